#!/usr/bin/env bash
# Side-by-side speed of am-sim and LIGGGHTS 3.8 on the benchmark bed of shared/bench/liggghts
# (19,200 settled spheres, Hertz-Mindlin, μ = 0.5, e = 0.5, periodic x/y, dt = 1e-7 s, skin 9 µm):
# the two programs alternate, several repetitions, medians and ratios of particle-steps per second
# per core, at each thread count. LIGGGHTS times 5000 steps after a 500-step warm-up (its second
# "Loop time"); am-sim times its whole run loop of 500 + 5000 steps (set-up excluded).
#
# usage: benches/liggghts_compare.sh [LIGGGHTS_BENCH_DIR] [REPS] [THREADS...]
#   defaults: ../shared/bench/liggghts, 3 repetitions, threads 1 2
# needs: apt-get install liggghts openmpi-bin (Debian's LIGGGHTS 3.8, generic -O2 build); am-sim is
# built here for generic x86-64 (no target-cpu=native), so the ratio is about the code.
set -euo pipefail
cd "$(dirname "$0")/.."
BENCH=$(realpath "${1:-../shared/bench/liggghts}")
REPS=${2:-3}
shift $(( $# > 2 ? 2 : $# )) || true
THREADS=("${@:-1 2}")
[ ${#THREADS[@]} -eq 1 ] && read -r -a THREADS <<< "${THREADS[0]}"
command -v liggghts >/dev/null || { echo "liggghts not found: apt-get install -y liggghts openmpi-bin" >&2; exit 1; }

cargo build --release --quiet
AM_SIM=$(realpath target/release/am-sim)
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT
cp "$BENCH"/in.bench "$WORK"/
gunzip -c "$BENCH"/settled_20k.restart.gz > "$WORK"/settled_20k.restart
sed "s|file = \"data/|file = \"$PWD/scenes/data/|" scenes/liggghts_bed_20k.toml > "$WORK"/am_sim_20k.toml

N=19200
results="$WORK/results.txt"
for rep in $(seq 1 "$REPS"); do
  for t in "${THREADS[@]}"; do
    (cd "$WORK" && mpirun --allow-run-as-root -np "$t" liggghts -in in.bench -var tag 20k -var heat 0 \
        -var nsteps 5000 -screen none -log lig.log)
    loop=$(grep "Loop time" "$WORK"/lig.log | tail -1 | awk '{print $4}')
    echo "liggghts $t $(python3 -c "print($N*5000/$loop/$t)")" >> "$results"
    speed=$(cd "$WORK" && "$AM_SIM" am_sim_20k.toml --threads "$t" --quiet | awk '/particle-steps\/s/{print $2}')
    echo "am-sim $t $(python3 -c "print($speed/$t)")" >> "$results"
    echo "rep $rep, $t thread(s): $(tail -2 "$results" | tr '\n' ' ')"
  done
done
python3 - "$results" <<'PY'
import statistics, sys, collections
runs = collections.defaultdict(list)
for line in open(sys.argv[1]):
    prog, threads, per_core = line.split()
    runs[(prog, int(threads))].append(float(per_core))
print("\nparticle-steps per second per core (median of %d)" % len(next(iter(runs.values()))))
print("threads | LIGGGHTS | am-sim | am-sim / LIGGGHTS")
for t in sorted({t for _, t in runs}):
    lig, am = statistics.median(runs[("liggghts", t)]), statistics.median(runs[("am-sim", t)])
    print(f"{t:7d} | {lig:8.3e} | {am:8.3e} | {am / lig:.2f}")
PY
