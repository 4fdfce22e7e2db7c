#!/usr/bin/env bash
# The flagship's scan on its own: the settled bed of a finished `scenes/bed.toml` run (frame 0 of
# its bed.h5, written right after the deposition) imported into the same scene without the
# deposition and without output, so that the scan's step (laser, boundary heat, conduction,
# bonds) can be timed or counted without the two minutes of deposition before it
# (docs/performance-log.md, thirty-first round).
#
# PHASE=rest measures the same bed at rest instead: the deposition's packed end, where the
# flagship spends most of its deposition (docs/performance-log.md, thirty-third round). Its scene
# drops the laser, the heat and the bonds as well ([laser], [thermal], [bond], the plate's
# temperature), so what is left is the mechanics of the flagship's bed: friction, rolling
# resistance and the plate, with twice the pair contacts and seven times the wall contacts per
# particle of the LIGGGHTS bed.
#
# usage: benches/flagship_scan.sh BED_H5 [DURATION_S] [THREADS]
#   defaults: 6e-4 s (the laser from 1e-4 s, as in the flagship), 1 thread; prints am-sim's summary
# INSTRUCTIONS=1 benches/flagship_scan.sh BED_H5
#   instructions per particle-step with cachegrind (needs valgrind): the difference of runs of 100
#   and 200 steps at 1 thread with the laser on from the first step, so the set-up drops out
#   (valgrind runs the AVX2 builds).
# PHASE=rest benches/flagship_scan.sh BED_H5 [DURATION_S] [THREADS]
#   the bed at rest, timed (default 2e-4 s, 2000 steps)
# PHASE=rest INSTRUCTIONS=1 benches/flagship_scan.sh BED_H5 [STEPS]
#   its instructions per particle-step by part of the step (benches/instructions.sh; default 500
#   steps, about three minutes)
# AM_SIM=path/to/am-sim selects the binary (default: target/release/am-sim, built if missing).
set -euo pipefail
cd "$(dirname "$0")/.."
BED=$(realpath "${1:?usage: benches/flagship_scan.sh BED_H5 [DURATION_S] [THREADS]}")
PHASE=${PHASE:-scan}
case $PHASE in
  scan | rest) ;;
  *) echo "PHASE: unknown phase '$PHASE' (scan or rest)" >&2; exit 1 ;;
esac
if [ "$PHASE" = rest ]; then DURATION=${2:-2e-4}; else DURATION=${2:-6e-4}; fi
THREADS=${3:-1}
if [ -z "${AM_SIM:-}" ]; then
  [ -x target/release/am-sim ] || cargo build --release --quiet
  AM_SIM=$(realpath target/release/am-sim)
fi
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT

# scenes/bed.toml with [[import]] of the settled bed in place of [[insert]], its size and
# [deposition]; no output file. For the bed at rest, without [bond], [thermal], [laser] (and
# their sub-tables) and the plate's temperature either.
scene() { # duration_s laser_start_s out
  python3 - "$BED" "$1" "$2" "$3" "$PHASE" <<'PY'
import re, sys
bed, duration, laser_start, out, phase = sys.argv[1:]
s = open('scenes/bed.toml').read()
start, end = s.index('[[insert]]'), s.index('[[walls]]')
s = s[:start] + f'[[import]]\nfile = "{bed}"\nformat = "am_sim_h5"\nframe = 0\nmaterial = "ss316l"\n\n' + s[end:]
s = re.sub(r'(?m)^duration_s *=.*$', f'duration_s = {duration}', s)
s = re.sub(r'(?m)^start_time_s *=.*$', f'start_time_s = {laser_start}', s)
s = re.sub(r'(?m)^file = "bed.h5".*$', '', s)
if phase == 'rest':
    # A table runs from its header to the next one; the comments just above a header stay with
    # the table before it, which is harmless.
    blocks = re.split(r'(?m)^(?=\[)', s)
    s = ''.join(b for b in blocks if not b.startswith(('[bond]', '[thermal', '[laser')))
    s = re.sub(r'(?m)^temperature_k *=.*$', '', s)
    for key in ('[bond]', '[thermal', '[laser', 'temperature_k'):
        assert key not in s, f'{key} left in the scene at rest'
open(out, 'w').write(s)
PY
}

if [ "$PHASE" = rest ]; then
  if [ "${INSTRUCTIONS:-0}" = 1 ]; then
    # benches/instructions.sh sets the duration of its two runs itself.
    scene 1e-7 0 "$WORK/rest.toml"
    benches/instructions.sh "$WORK/rest.toml" "${2:-500}"
  else
    scene "$DURATION" 0 "$WORK/rest.toml"
    "$AM_SIM" "$WORK/rest.toml" --threads "$THREADS"
  fi
elif [ "${INSTRUCTIONS:-0}" = 1 ]; then
  command -v valgrind >/dev/null || { echo "valgrind not found: apt-get install -y valgrind" >&2; exit 1; }
  REP_OFF=glibc.cpu.x86_rep_stosb_threshold=1000000000000:glibc.cpu.x86_rep_movsb_threshold=1000000000000
  for n in 100 200; do
    scene "${n}e-7" 0 "$WORK/scan_$n.toml"
    GLIBC_TUNABLES=$REP_OFF valgrind --tool=cachegrind --cache-sim=no --cachegrind-out-file="$WORK/cg_$n" \
      "$AM_SIM" "$WORK/scan_$n.toml" --threads 1 --quiet > "$WORK/run_$n.txt" 2> "$WORK/valgrind_$n.txt"
  done
  particles=$(sed -n 's/.* — \([0-9]*\) particles,.*/\1/p' "$WORK/run_100.txt" | head -1)
  python3 - "$WORK" "$particles" <<'PY'
import re, subprocess, sys
work, particles = sys.argv[1], int(sys.argv[2])
def total(f):
    out = subprocess.run(['cg_annotate', '--auto=no', f], capture_output=True, text=True).stdout
    return int(re.search(r'([\d,]+) \(100.0%\)\s+PROGRAM TOTALS', out).group(1).replace(',', ''))
per = (total(f'{work}/cg_200') - total(f'{work}/cg_100')) / (100 * particles)
print(f'flagship scan: {per:.1f} instructions per particle-step ({particles} particles, laser on, 1 thread)')
PY
else
  scene "$DURATION" 1e-4 "$WORK/scan.toml"
  "$AM_SIM" "$WORK/scan.toml" --threads "$THREADS"
fi
