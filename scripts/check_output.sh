#!/usr/bin/env bash
# End-to-end check of the HDF5/XDMF output as a user opens it: runs a shortened laser track
# (particles melt and bond), then checks the file with h5py and, if pvpython is installed, with
# all three XDMF readers of ParaView; then runs the worked example of docs/post-processing.md and
# checks that its snippets print what the page says (scripts/check_docs.py). Needs
# `scripts/setup --checks`.
# Usage: scripts/check_output.sh [OUT_DIR]
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
out="${1:-$(mktemp -d)}"
mkdir -p "$out"
cd "$here/.."
cargo build --release --quiet
sed -e 's/^duration_s = 3.5e-3.*/duration_s = 1.0e-3/' -e 's/^every_steps = 500.*/every_steps = 1000/' \
    scenes/laser_track.toml > "$out/track.toml"
(cd "$out" && "$OLDPWD/target/release/am-sim" track.toml --quiet --overwrite)
python3 "$here/check_h5py.py" "$out/laser_track.h5" --frames 11 --expected-json "$out/expected.json"
if command -v pvpython >/dev/null; then
    pvpython "$here/check_paraview.py" "$out/laser_track.xmf" "$out/expected.json"
else
    echo "check_output: pvpython not found (scripts/setup --checks installs ParaView): ParaView check skipped" >&2
    exit 1
fi
# The worked example of docs/post-processing.md: its snippets print what the page says.
python3 "$here/check_docs.py" "$out/docs"
echo "check_output: all passed ($out)"
