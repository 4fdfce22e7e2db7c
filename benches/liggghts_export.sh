#!/usr/bin/env bash
# Writes the LIGGGHTS benchmark beds (shared/bench/liggghts, their settled restarts) as am-sim
# imports them, with everything a restart carries besides positions and velocities:
#   scenes/data/liggghts_start_{20k,100k}.dump.gz        `dump custom id x y z vx vy vz omegax omegay
#       omegaz radius f_history_zwall[1..3]`: the spins and the plate's tangential springs per atom;
#   scenes/data/liggghts_start_{20k,100k}_pairs.dump.gz  `dump local` of `compute pair/gran/local id
#       history`: one line per contact, the two ids, a periodic flag and the spring ξ [m].
# With --references it also writes what tests/liggghts_parity.rs compares am-sim with, from the 19.2k
# bed's restart (LIGGGHTS 3.8, 1 MPI rank):
#   tests/reference/liggghts_one_step.txt.gz       velocities and spins after one step (every
#       particle whose id is a multiple of 4);
#   tests/reference/liggghts_contacts_2000_steps.txt   coord.py on the bed after 500 + 1500 steps;
#   tests/reference/liggghts_heat_2000_steps.txt.gz    every temperature after 500 + 1500 steps of
#       in.bench -var heat 1.
#
# usage: benches/liggghts_export.sh [LIGGGHTS_BENCH_DIR] [--references]   (default ../shared/bench/liggghts)
# needs: apt-get install liggghts openmpi-bin; coord.py needs numpy and scipy.
set -euo pipefail
cd "$(dirname "$0")/.."
BENCH=$(realpath "${1:-../shared/bench/liggghts}")
REFERENCES=${2:-}
command -v liggghts >/dev/null || { echo "liggghts not found: apt-get install -y liggghts openmpi-bin" >&2; exit 1; }
# Checked before LIGGGHTS runs, not after: coord.py needs them for the references.
if [ "$REFERENCES" = "--references" ]; then
  python3 -c 'import numpy, scipy' 2>/dev/null || { echo "python3 lacks one of numpy scipy: pip install numpy scipy" >&2; exit 1; }
fi
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT
OUT=$PWD

# in.bench's set-up (material, contact laws, plate, gravity, integrator) up to its first `run`.
sed -n '1,/^fix integr/p' "$BENCH"/in.bench > "$WORK"/setup.in
grep -q "^fix zwall all wall/gran" "$WORK"/setup.in || { echo "in.bench: no 'fix zwall' line" >&2; exit 1; }

# `run 0` computes the forces without advancing the springs (LIGGGHTS' set-up), so the dumps hold
# the restart's state.
{ cat "$WORK"/setup.in; cat <<'EOF'
compute pairs all pair/gran/local id history
dump atoms all custom 1 start_${tag}.dump id x y z vx vy vz omegax omegay omegaz radius f_history_zwall[1] f_history_zwall[2] f_history_zwall[3]
dump_modify atoms sort id format "%d %.12e %.12e %.12e %.12e %.12e %.12e %.12e %.12e %.12e %.6e %.12e %.12e %.12e"
dump pairs all local 1 start_${tag}_pairs.dump c_pairs[1] c_pairs[2] c_pairs[3] c_pairs[4] c_pairs[5] c_pairs[6]
dump_modify pairs format "%.0f %.0f %.0f %.12e %.12e %.12e"
run 0
EOF
} > "$WORK"/export.in
for tag in 20k 100k; do
  gunzip -c "$BENCH/settled_$tag.restart.gz" > "$WORK/settled_$tag.restart"
  (cd "$WORK" && mpirun --allow-run-as-root -np 1 liggghts -in export.in -var tag $tag -screen none -log export.log)
  gzip -9 -c "$WORK/start_$tag.dump" > "scenes/data/liggghts_start_$tag.dump.gz"
  gzip -9 -c "$WORK/start_${tag}_pairs.dump" > "scenes/data/liggghts_start_${tag}_pairs.dump.gz"
  echo "scenes/data/liggghts_start_$tag.dump.gz and _pairs.dump.gz: $(grep -c . "$WORK/start_${tag}_pairs.dump") lines of springs"
done
[ "$REFERENCES" = "--references" ] || exit 0

# One step from the restart: velocities and spins.
{ cat "$WORK"/setup.in; cat <<'EOF'
run 1
write_dump all custom one_step.dump id vx vy vz omegax omegay omegaz modify sort id format "%d %.15e %.15e %.15e %.15e %.15e %.15e"
EOF
} > "$WORK"/one_step.in
(cd "$WORK" && mpirun --allow-run-as-root -np 1 liggghts -in one_step.in -var tag 20k -screen none -log one_step.log)
{ echo "# LIGGGHTS 3.8, shared/bench/liggghts/in.bench's set-up from settled_20k.restart, one step (run 1), 1 MPI rank,"
  echo "# written by benches/liggghts_export.sh --references. Columns: LIGGGHTS id, v [m/s] (3), omega [rad/s] (3);"
  echo "# the particles whose id is a multiple of 4."
  awk 'f && $1 % 4 == 0 {print} /^ITEM: ATOMS/ {f = 1}' "$WORK"/one_step.dump; } \
  | gzip -9 > tests/reference/liggghts_one_step.txt.gz

# 500 + 1500 steps of in.bench from its restart: the contacts, and with heat every temperature.
cp "$BENCH"/in.bench "$WORK"/
(cd "$WORK" && mpirun --allow-run-as-root -np 1 liggghts -in in.bench -var tag 20k -var heat 0 \
    -var nsteps 1500 -var dumpx 1 -screen none -log contacts.log)
{ echo "# LIGGGHTS 3.8, shared/bench/liggghts/in.bench -var heat 0 from its settled restart, 500 + 1500 steps, 1 MPI rank"
  echo "# (benches/liggghts_export.sh --references); shared/bench/liggghts/coord.py on the end dump:"
  python3 "$BENCH"/coord.py "$WORK"/end_20k_heat0.dump | sed 's|^[^:]*: ||'; } > tests/reference/liggghts_contacts_2000_steps.txt
{ cat "$WORK"/in.bench; echo "write_dump all custom end_T_\${tag}.dump id f_Temp modify sort id format '%d %.12e'"; } > "$WORK"/heat.in
(cd "$WORK" && mpirun --allow-run-as-root -np 1 liggghts -in heat.in -var tag 20k -var heat 1 \
    -var nsteps 1500 -screen none -log heat.log)
{ echo "# LIGGGHTS 3.8, shared/bench/liggghts/in.bench -var heat 1 from its settled restart, 500 + 1500 steps, 1 MPI rank"
  echo "# (benches/liggghts_export.sh --references): every particle's temperature [K] at the end."
  echo "# Columns: LIGGGHTS id, temperature_k. Initially 1000 K for z >= 1.8e-4 m, else 300 K."
  awk 'f {print} /^ITEM: ATOMS/ {f = 1}' "$WORK"/end_T_20k.dump; } | gzip -9 > tests/reference/liggghts_heat_2000_steps.txt.gz
cat tests/reference/liggghts_contacts_2000_steps.txt
echo "written to $OUT/tests/reference"
