#!/usr/bin/env bash
# Physics parity with LIGGGHTS 3.8 on the 19.2k benchmark bed: both programs start from the same
# dump (scenes/data/liggghts_start_20k.dump.gz, so neither has tangential histories: a LIGGGHTS
# restart would carry them, a dump cannot), run 500 + 5000 steps, and the script prints, for each,
# the particle-particle coordination with overlap > 0, the wall contacts per particle and the
# largest overlap at the end (LIGGGHTS' numbers by shared/bench/liggghts/coord.py, which needs
# numpy and scipy).
#
# usage: benches/liggghts_parity.sh [LIGGGHTS_BENCH_DIR]   (default ../shared/bench/liggghts)
set -euo pipefail
cd "$(dirname "$0")/.."
BENCH=$(realpath "${1:-../shared/bench/liggghts}")
command -v liggghts >/dev/null || { echo "liggghts not found: apt-get install -y liggghts openmpi-bin" >&2; exit 1; }
cargo build --release --quiet
AM_SIM=$(realpath target/release/am-sim)
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT

# The dump as a LAMMPS data file (atom_style granular: id type diameter density x y z).
python3 - "$PWD/scenes/data/liggghts_start_20k.dump.gz" "$WORK/start_20k.data" <<'PY'
import gzip, sys
lines = gzip.open(sys.argv[1], "rt").read().split("\n")
n = int(lines[lines.index("ITEM: NUMBER OF ATOMS") + 1])
k = next(i for i, l in enumerate(lines) if l.startswith("ITEM: ATOMS"))
rows = [l.split() for l in lines[k + 1:k + 1 + n]]
with open(sys.argv[2], "w") as f:
    f.write(f"dump of the settled bed\n\n{n} atoms\n1 atom types\n\n0 0.00132 xlo xhi\n"
            "0 0.00132 ylo yhi\n0 0.001 zlo zhi\n\nAtoms\n\n")
    for r in rows:
        f.write(f"{r[0]} 1 {2 * float(r[7]):.6e} 7800 {r[1]} {r[2]} {r[3]}\n")
    f.write("\nVelocities\n\n")
    for r in rows:
        f.write(f"{r[0]} {r[4]} {r[5]} {r[6]} 0 0 0\n")
PY
sed -e 's|read_restart   settled_${tag}.restart|read_data start_${tag}.data|' "$BENCH"/in.bench > "$WORK"/in.parity
(cd "$WORK" && mpirun --allow-run-as-root -np 2 liggghts -in in.parity -var tag 20k -var heat 0 \
    -var nsteps 5000 -var dumpx 1 -screen none -log parity.log)
echo "LIGGGHTS, from the dump:"
python3 "$BENCH"/coord.py "$WORK"/end_20k_heat0.dump

sed "s|file = \"data/|file = \"$PWD/scenes/data/|" scenes/liggghts_bed_20k.toml > "$WORK"/am_sim.toml
echo "am-sim, from the dump:"
(cd "$WORK" && "$AM_SIM" am_sim.toml --quiet) | awk '
    /contacts:/ { pp = $2; wall = $4 }
    /now: largest overlap/ { overlap = $4 }
    END { printf "contacts(overlap>0)=%d Z=%.3f | wall contacts=%d (%.3f/particle) | max overlap=%s m\n",
          pp, 2 * pp / 19200, wall, wall / 19200, overlap }'
