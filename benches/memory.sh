#!/usr/bin/env bash
# Peak memory per particle (issue 5: at most 400 bytes per particle, and a 1M-particle bed within a
# 24 GiB machine): peak resident set size (/usr/bin/time -v) divided by the particle count, for the
# two LIGGGHTS benchmark beds (the larger also with its heat conduction, which the goal does not
# bound), for a bed of one million spheres inserted at random (the benchmark's material and
# contact model, 200 steps: loose, with few contacts) and for a packed
# bed of 1,166,400 spheres (the 97.2k start configuration tiled 4 x 3 over its periodic box, so
# that the copies meet as the periodic images did: the 97.2k bed's contacts, springs and near
# lists, run 2500 steps as that bed is, so that the list is rebuilt and the springs carried over
# as there). The large beds are written to a temporary folder, so that the test that builds every
# shipped scene does not build a million spheres.
#
# usage: benches/memory.sh [THREADS]     (default 2; needs /usr/bin/time: apt-get install time)
#   NO_HDF5=1 benches/memory.sh   measures a build without the HDF5 output (--no-default-features,
#   in target/no-hdf5): these scenes write no file, so the difference is the resident pages of
#   the statically linked HDF5 code.
set -euo pipefail
cd "$(dirname "$0")/.."
THREADS=${1:-2}
command -v /usr/bin/time >/dev/null || { echo "/usr/bin/time not found: apt-get install -y time" >&2; exit 1; }
if [[ "${NO_HDF5:-0}" == 1 ]]; then
  export CARGO_TARGET_DIR=target/no-hdf5
  cargo build --release --quiet --no-default-features
else
  export CARGO_TARGET_DIR=target
  cargo build --release --quiet
fi
BINARY="$CARGO_TARGET_DIR/release/am-sim"
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT
cat > "$WORK/bed_1m.toml" <<'TOML'
[scene]
version = 1
title = "One million spheres: memory per particle"
[simulation]
dt_s = 1e-7
duration_s = 2e-5
gravity_m_s2 = [0.0, 0.0, -9.81]
skin_m = 9e-6
[materials.steel]
density_kg_m3 = 7800
youngs_modulus_pa = 2e8
poisson_ratio = 0.3
[contact]
model = "hertz"
restitution = 0.5
friction_coefficient = 0.5
[[insert]]
min_corner_m = [0.0, 0.0, 0.0]
max_corner_m = [1.07e-2, 1.07e-2, 5.0e-4]
solid_fraction = 0.246
seed = 1
material = "steel"
[insert.size]
distribution = "constant"
diameter_m = 3e-5
[[walls]]
point_m = [0.0, 0.0, 0.0]
normal = [0.0, 0.0, 1.0]
material = "steel"
[periodic]
x_m = [0.0, 1.07e-2]
y_m = [0.0, 1.07e-2]
TOML
# The packed bed: the 97.2k bed's dump tiled 4 x 3 over its 2.97 mm box, ids offset per copy
# (positions, velocities and radii only: the copies start without spins and springs).
python3 - scenes/data/liggghts_start_100k.dump.gz "$WORK/bed_1m_packed.dump" <<'PYTHON'
import gzip, sys
BOX, TILES = 2.97e-3, (4, 3)
with gzip.open(sys.argv[1], "rt") as dump:
    lines = dump.read().splitlines()
header = next(i for i, line in enumerate(lines) if line.startswith("ITEM: ATOMS"))
names = lines[header].split()[2:]
column = {name: names.index(name) for name in ("id", "x", "y", "z", "vx", "vy", "vz", "radius")}
atoms = [line.split() for line in lines[header + 1:] if line.strip()]
with open(sys.argv[2], "w") as out:
    out.write(f"ITEM: TIMESTEP\n0\nITEM: NUMBER OF ATOMS\n{len(atoms) * TILES[0] * TILES[1]}\n")
    out.write(f"ITEM: BOX BOUNDS pp pp ff\n0 {BOX * TILES[0]!r}\n0 {BOX * TILES[1]!r}\n0 0.001\n")
    out.write("ITEM: ATOMS id x y z vx vy vz radius\n")
    for i in range(TILES[0]):
        for j in range(TILES[1]):
            offset = (i * TILES[1] + j) * len(atoms)
            for a in atoms:
                x, y = float(a[column["x"]]) + i * BOX, float(a[column["y"]]) + j * BOX
                rest = " ".join(a[column[name]] for name in ("z", "vx", "vy", "vz", "radius"))
                out.write(f"{int(a[column['id']]) + offset} {x!r} {y!r} {rest}\n")
PYTHON
sed -e 's|^file = .*|file = "bed_1m_packed.dump"|' -e 's|^x_m = .*|x_m = [0.0, 1.188e-2]|' \
    -e 's|^y_m = .*|y_m = [0.0, 8.91e-3]|' -e '/^pair_history_file/d' -e '/^wall_history_columns/d' \
    -e 's|^title = .*|title = "1,166,400 packed spheres: memory per particle"|' \
    scenes/liggghts_bed_100k.toml > "$WORK/bed_1m_packed.toml"
for scene in scenes/liggghts_bed_20k.toml scenes/liggghts_bed_100k.toml \
    scenes/liggghts_bed_100k_heat.toml "$WORK/bed_1m.toml" "$WORK/bed_1m_packed.toml"; do
  /usr/bin/time -v "$BINARY" "$scene" --threads "$THREADS" --overwrite > "$WORK/out.txt" 2> "$WORK/time.txt"
  n=$(grep -oE '— [0-9]+ particles' "$WORK/out.txt" | grep -oE '[0-9]+' | head -1)
  kb=$(awk '/Maximum resident set size/{print $6}' "$WORK/time.txt")
  speed=$(awk '/particle-steps\/s/{print $2}' "$WORK/out.txt")
  echo "$(basename "$scene"): $n particles, peak RSS $((kb / 1024)) MiB, $(( kb * 1024 / n )) B per particle, $speed particle-steps/s"
done
