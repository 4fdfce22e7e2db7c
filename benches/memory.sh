#!/usr/bin/env bash
# Peak memory per particle (issue 5: at most 400 bytes per particle, and a 1M-particle bed within a
# 24 GiB machine): peak resident set size (/usr/bin/time -v) divided by the particle count, for the
# two LIGGGHTS benchmark beds and for a bed of one million spheres inserted at random (the
# benchmark's material and contact model, 200 steps; written to a temporary scene so that the
# test that builds every shipped scene does not insert a million spheres).
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
for scene in scenes/liggghts_bed_20k.toml scenes/liggghts_bed_100k.toml "$WORK/bed_1m.toml"; do
  /usr/bin/time -v "$BINARY" "$scene" --threads "$THREADS" --overwrite > "$WORK/out.txt" 2> "$WORK/time.txt"
  n=$(grep -oE '— [0-9]+ particles' "$WORK/out.txt" | grep -oE '[0-9]+' | head -1)
  kb=$(awk '/Maximum resident set size/{print $6}' "$WORK/time.txt")
  speed=$(awk '/particle-steps\/s/{print $2}' "$WORK/out.txt")
  echo "$(basename "$scene"): $n particles, peak RSS $((kb / 1024)) MiB, $(( kb * 1024 / n )) B per particle, $speed particle-steps/s"
done
