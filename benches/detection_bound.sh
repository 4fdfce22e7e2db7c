#!/usr/bin/env bash
# What any contact detection could save on a bed: runs SCENE for STEPS steps with a frame every
# EVERY steps, then counts with benches/detection_bound.py the pair tests per particle-step of
# the touching pairs alone (the floor), of am-sim's near lists at several near skins, of
# per-entry thresholds on each pair's own displacement bound (docs/performance-log.md, forty-first
# round) and of near entries skipped until the bed's budget reaches their gap at the refresh
# (forty-sixth round). Needs h5py and numpy (scripts/setup --checks installs them).
#
# usage: benches/detection_bound.sh [SCENE] [STEPS] [EVERY] [-- detection_bound.py options]
#   defaults: scenes/liggghts_bed_20k.toml, 1500 steps, a frame every 5 steps (1.6 GB of frames
#   in a temporary folder for the 19.2k bed; about two minutes in all)
# AM_SIM=path/to/am-sim selects the binary (default: target/release/am-sim, built if missing).
set -euo pipefail
cd "$(dirname "$0")/.."
SCENE=scenes/liggghts_bed_20k.toml STEPS=1500 EVERY=5
for value in SCENE STEPS EVERY; do
  if [ $# -gt 0 ] && [ "$1" != -- ]; then printf -v "$value" '%s' "$1"; shift; fi
done
[ "${1:-}" = -- ] && shift
if [ -z "${AM_SIM:-}" ]; then
  [ -x target/release/am-sim ] || cargo build --release --quiet
  AM_SIM=$(realpath target/release/am-sim)
fi
# shellcheck source=benches/valgrind_scene.sh
. benches/valgrind_scene.sh
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT

scene_for_steps "$SCENE" "$STEPS" "$WORK/scene.toml"
# The scene's own [output] table (if any) gives way to frames every EVERY steps.
python3 - "$WORK/scene.toml" "$EVERY" <<'PY'
import re, sys
path, every = sys.argv[1:]
s = open(path).read()
blocks = re.split(r'(?m)^(?=\[)', s)
s = ''.join(b for b in blocks if not b.startswith('[output]'))
open(path, 'w').write(s + f'\n[output]\nfile = "frames.h5"\nevery_steps = {every}\n')
PY
(cd "$WORK" && "$AM_SIM" scene.toml --quiet --threads 2) > "$WORK/run.txt"
sed -n '/^done:/,/^  contacts:/p' "$WORK/run.txt"
builds=$(sed -n 's/.*neighbour-list builds: \([0-9]*\).*/\1/p' "$WORK/run.txt")
if [ "${builds:-1}" -gt 1 ]; then
  echo "note: the list was built $builds times in the window; the counts take the first frame's candidates for all of it (an approximation)"
fi
python3 benches/detection_bound.py "$WORK/frames.h5" "$WORK/scene.toml" "$@"
