#!/usr/bin/env bash
# Side-by-side speed of am-sim and LIGGGHTS 3.8 on the benchmark bed of shared/bench/liggghts
# (19,200 settled spheres, Hertz-Mindlin, μ = 0.5, e = 0.5, periodic x/y, dt = 1e-7 s, skin 9 µm):
# the two programs alternate, several repetitions, medians and ratios of particle-steps per second
# per core, at each thread count. LIGGGHTS times 5000 steps after a 500-step warm-up (its second
# "Loop time"); am-sim times its whole run loop of 500 + 5000 steps (set-up excluded).
#
# usage: benches/liggghts_compare.sh [LIGGGHTS_BENCH_DIR] [REPS] [THREADS...]
#   defaults: ../shared/bench/liggghts, 3 repetitions, threads 1 2; HEATS="0 1" (environment)
#   chooses the variants: 0 mechanics only, 1 with heat conduction (in.bench -var heat 1 against
#   scenes/liggghts_bed_20k_heat.toml).
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
sed "s|file = \"data/|file = \"$PWD/scenes/data/|" scenes/liggghts_bed_20k.toml > "$WORK"/am_sim_20k_heat0.toml
sed "s|file = \"data/|file = \"$PWD/scenes/data/|" scenes/liggghts_bed_20k_heat.toml > "$WORK"/am_sim_20k_heat1.toml
read -r -a HEATS <<< "${HEATS:-0 1}"

N=19200
results="$WORK/results.txt"
for rep in $(seq 1 "$REPS"); do
  for heat in "${HEATS[@]}"; do
    for t in "${THREADS[@]}"; do
      (cd "$WORK" && mpirun --allow-run-as-root -np "$t" liggghts -in in.bench -var tag 20k \
          -var heat "$heat" -var nsteps 5000 -screen none -log lig.log)
      loop=$(grep "Loop time" "$WORK"/lig.log | tail -1 | awk '{print $4}')
      echo "liggghts $heat $t $(python3 -c "print($N*5000/$loop/$t)")" >> "$results"
      speed=$(cd "$WORK" && "$AM_SIM" "am_sim_20k_heat$heat.toml" --threads "$t" --quiet --overwrite \
          | awk '/particle-steps\/s/{print $2}')
      echo "am-sim $heat $t $(python3 -c "print($speed/$t)")" >> "$results"
      echo "rep $rep, heat $heat, $t thread(s): $(tail -2 "$results" | tr '\n' ' ')"
    done
  done
done
python3 - "$results" <<'PY'
import statistics, sys, collections
runs = collections.defaultdict(list)
for line in open(sys.argv[1]):
    prog, heat, threads, per_core = line.split()
    runs[(prog, int(heat), int(threads))].append(float(per_core))
median = lambda key: statistics.median(runs[key])
print("\nparticle-steps per second per core (medians of %d runs)" % len(next(iter(runs.values()))))
print("heat | threads | LIGGGHTS | am-sim | am-sim / LIGGGHTS")
keys = sorted({(h, t) for _, h, t in runs})
for h, t in keys:
    lig, am = median(("liggghts", h, t)), median(("am-sim", h, t))
    print(f"{h:4d} | {t:7d} | {lig:8.3e} | {am:8.3e} | {am / lig:.2f}")
threads = sorted({t for _, t in keys})
for h in sorted({h for h, _ in keys}):
    if len(threads) > 1:
        t0, t1 = threads[0], threads[-1]
        for prog in ("liggghts", "am-sim"):
            speedup = median((prog, h, t1)) * t1 / (median((prog, h, t0)) * t0)
            print(f"heat {h}: {prog} {t1} threads vs {t0}: {speedup:.2f}x")
for t in threads:
    if (0, t) in keys and (1, t) in keys:
        for prog in ("liggghts", "am-sim"):
            cost = median((prog, 0, t)) / median((prog, 1, t)) - 1.0
            print(f"{t} thread(s): heat conduction adds {100 * cost:.0f} % to {prog}'s step time")
PY
