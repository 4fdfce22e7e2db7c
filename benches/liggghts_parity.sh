#!/usr/bin/env bash
# Physics parity with LIGGGHTS 3.8 on the 19.2k benchmark bed: both programs start from the same
# state (LIGGGHTS from its settled restart, am-sim from scenes/data/liggghts_start_20k*.dump.gz,
# which benches/liggghts_export.sh wrote from that restart: positions, velocities, spins and the
# tangential springs of pairs and plate), run 500 + 5000 steps, and the script prints, for each,
# the particle-particle coordination with overlap > 0, the wall contacts per particle and the
# largest overlap at the end (LIGGGHTS' numbers by shared/bench/liggghts/coord.py, which needs
# numpy and scipy). Then the heat variant (in.bench -var heat 1 against
# scenes/liggghts_bed_20k_heat.toml: the top of the bed, z >= 180 um, at 1000 K, the rest at 300 K,
# conduction only): the heat that reached the initially cold particles, how many of them warmed
# and of the hot ones cooled, and how far each particle's final temperature is from LIGGGHTS' (h5py).
#
# usage: benches/liggghts_parity.sh [LIGGGHTS_BENCH_DIR]   (default ../shared/bench/liggghts)
set -euo pipefail
cd "$(dirname "$0")/.."
BENCH=$(realpath "${1:-../shared/bench/liggghts}")
command -v liggghts >/dev/null || { echo "liggghts not found: apt-get install -y liggghts openmpi-bin" >&2; exit 1; }
# Checked before LIGGGHTS runs, not after: coord.py and the heat comparison need them.
python3 -c 'import numpy, scipy, h5py' 2>/dev/null || { echo "python3 lacks one of numpy scipy h5py: pip install numpy scipy h5py" >&2; exit 1; }
cargo build --release --quiet
AM_SIM=$(realpath target/release/am-sim)
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT

gunzip -c "$BENCH"/settled_20k.restart.gz > "$WORK"/settled_20k.restart
cp "$BENCH"/in.bench "$WORK"/in.parity
(cd "$WORK" && mpirun --allow-run-as-root -np 2 liggghts -in in.parity -var tag 20k -var heat 0 \
    -var nsteps 5000 -var dumpx 1 -screen none -log parity.log)
echo "LIGGGHTS, from its restart:"
python3 "$BENCH"/coord.py "$WORK"/end_20k_heat0.dump

sed "s|file = \"data/|file = \"$PWD/scenes/data/|" scenes/liggghts_bed_20k.toml > "$WORK"/am_sim.toml
echo "am-sim, from the same state:"
(cd "$WORK" && "$AM_SIM" am_sim.toml --quiet) | awk '
    /contacts:/ { pp = $2; wall = $4 }
    /now: largest overlap/ { overlap = $4 }
    END { printf "contacts(overlap>0)=%d Z=%.3f | wall contacts=%d (%.3f/particle) | max overlap=%s m\n",
          pp, 2 * pp / 19200, wall, wall / 19200, overlap }'

# The heat variant: LIGGGHTS writes every particle's temperature at the end, am-sim its last frame.
{ cat "$WORK"/in.parity; echo "write_dump all custom end_T_\${tag}.dump id z f_Temp modify format '%d %.12e %.12e'"; } > "$WORK"/in.heat
(cd "$WORK" && mpirun --allow-run-as-root -np 2 liggghts -in in.heat -var tag 20k -var heat 1 \
    -var nsteps 5000 -screen none -log heat.log)
{ sed "s|file = \"data/|file = \"$PWD/scenes/data/|" scenes/liggghts_bed_20k_heat.toml
  printf '\n[output]\nfile = "heat.h5"\nevery_steps = 5500\n'; } > "$WORK"/am_sim_heat.toml
(cd "$WORK" && "$AM_SIM" am_sim_heat.toml --quiet > /dev/null)
python3 - "$PWD/scenes/data/liggghts_start_20k.dump.gz" "$WORK/end_T_20k.dump" "$WORK/heat.h5" <<'PY'
import gzip, sys
import h5py, numpy as np
start = gzip.open(sys.argv[1], "rt").read().split("\n")
k = next(i for i, l in enumerate(start) if l.startswith("ITEM: ATOMS"))
rows = sorted((int(r[0]), float(r[3])) for r in (l.split() for l in start[k + 1:]) if r)
hot = np.array([z >= 1.8e-4 for _, z in rows])          # in.bench: region hot ... 1.8e-4 INF
end = open(sys.argv[2]).read().split("\n")
k = next(i for i, l in enumerate(end) if l.startswith("ITEM: ATOMS"))
lig = dict((int(r[0]), float(r[2])) for r in (l.split() for l in end[k + 1:]) if r)
lig = np.array([lig[i] for i, _ in rows])
frames = h5py.File(sys.argv[3])["frames"]
last = frames[sorted(frames)[-1]]
# am-sim numbers the imported particles 0.. in the order of their file ids.
am = np.empty(len(rows)); am[last["id"][()]] = last["temperature"][()]
for name, t in (("LIGGGHTS", lig), ("am-sim", am)):
    print(f"{name}: heat into the cold part {(t[~hot] - 300).sum():.4e} K (sum over particles), "
          f"{(t[~hot] > 300 + 1e-6).sum()} of {(~hot).sum()} warmed, "
          f"{(t[hot] < 1000 - 1e-6).sum()} of {hot.sum()} cooled, mean T {t.mean():.4f} K")
d = am - lig
print(f"am-sim - LIGGGHTS per particle: rms {np.sqrt((d * d).mean()):.3f} K, max {abs(d).max():.2f} K")
PY
