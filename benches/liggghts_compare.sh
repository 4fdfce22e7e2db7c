#!/usr/bin/env bash
# Side-by-side speed of am-sim and LIGGGHTS 3.8 on the benchmark beds of shared/bench/liggghts
# (19,200 or 97,200 settled spheres, Hertz-Mindlin, μ = 0.5, e = 0.5, periodic x/y, dt = 1e-7 s,
# skin 9 µm): the two programs alternate, several repetitions, medians and ratios of
# particle-steps per second per core, at each thread count, and the median and range of the
# ratios within a repetition (the two programs back to back: on a host whose speed drifts from
# minute to minute, the steadier reading). The speed-up of the most threads over the fewest and
# heat's cost are printed both from the medians and repetition by repetition (the variants of
# one repetition run minutes apart, where the medians may pair a fast minute with a slow one).
# LIGGGHTS times 5000 steps (2000 on the 97.2k bed) after a 500-step warm-up (its second "Loop
# time"); am-sim is timed over the same steps, 501-5500 (501-2500), by the wall times of its
# series rows at steps 500 and 5500 (2500),
# which include its checks at the outputs in that window. Until the forty-eighth round am-sim was
# timed over its whole run loop of 500 + 5000 steps, warm-up included (its bed holds fewer
# contacts then than at the window's end): 0.98-1.05 times the window's figure, printed at the
# end (docs/performance-log.md, forty-eighth round).
#
# am-sim checks its state (energy balance, stability limit, overlaps, every value finite) every
# 500 steps here, at its series rows: in.bench prints LIGGGHTS' thermo only at its runs' ends
# (`thermo 0`). A scene without an [output] table checks 100 times per run, which cost 3.7 % of
# the speed on the 19.2k bed and 4.8 % on the 97.2k bed on the Intel 207 (alternating runs,
# docs/performance-log.md, sixty-fifth round); the readings before that round were taken so. The
# guards that run every step (the forces' finite test, the largest overlap) run here too.
#
# The order of the two programs alternates from repetition to repetition.
#
# usage: benches/liggghts_compare.sh [LIGGGHTS_BENCH_DIR] [REPS] [THREADS...]
#   defaults: ../shared/bench/liggghts, 3 repetitions, threads 1 2; HEATS="0 1" (environment)
#   chooses the variants: 0 mechanics only, 1 with heat conduction (in.bench -var heat 1 against
#   scenes/liggghts_bed_20k_heat.toml); SIZES="20k" (environment) chooses the beds: 20k, 100k
#   (97,200 spheres, scenes/liggghts_bed_100k*.toml) or both, "20k 100k". Both programs start from
#   the same state: LIGGGHTS from its settled restart, am-sim from that restart as
#   benches/liggghts_export.sh wrote it (positions, velocities, spins and tangential springs), so
#   they do the same contact work (coordination 1.57 at the end of the window in both).
#   CHECK_EVERY=N (environment): steps between am-sim's checks of its state, 500 by default;
#   CHECK_EVERY=default for the scene's own cadence (100 checks per run), as before the
#   sixty-fifth round.
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
# How far apart the host has put the cores (benches/core_latency.rs), read right before each run of
# two threads or more, of either program: on the 2-vCPU guests it switches every few minutes
# between about 60-80 ns (cores sharing a third-level cache) and about 330 ns (cores far apart),
# and the 2-thread speeds with it, am-sim's more than LIGGGHTS' (docs/performance-log.md,
# fifty-third round). A reading taken before the pair instead missed switches in the 20 s of
# LIGGGHTS' run.
LATENCY=$(cargo bench --bench core_latency --no-run --message-format=json 2>/dev/null |
  python3 -c 'import json, sys
for m in map(json.loads, sys.stdin):
    if m.get("reason") == "compiler-artifact" and m["target"]["name"] == "core_latency" and m.get("executable"):
        print(m["executable"])')
[ -x "$LATENCY" ] || { echo "cargo bench --bench core_latency --no-run built no executable" >&2; exit 1; }
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT
# The host first: the ratio moves with it (on a Zen 3 without AVX-512 am-sim's contact laws run
# in AVX2, 1.6 times their AVX-512 time: docs/performance-log.md, thirty-fifth round), so a reading
# names the processor and its caches; each am-sim line below names the laws' build it ran.
cpu() { awk -F': ' -v key="$1" '$1 ~ "^"key"[[:space:]]*$" {print $2; exit}' /proc/cpuinfo; }
cache() { lscpu 2>/dev/null | awk -F': *' -v key="$1" '$1 == key {print $2; exit}'; }
echo "host: $(cpu "model name"), family $(cpu "cpu family") model $(cpu model), $(nproc) cores," \
  "L2 $(cache "L2 cache"), L3 $(cache "L3 cache")"
cp "$BENCH"/in.bench "$WORK"/
read -r -a HEATS <<< "${HEATS:-0 1}"
read -r -a SIZES <<< "${SIZES:-20k}"
for size in "${SIZES[@]}"; do
  case $size in
    20k | 100k) ;;
    *) echo "SIZES: unknown bed '$size' (20k or 100k)" >&2; exit 1 ;;
  esac
  gunzip -c "$BENCH/settled_$size.restart.gz" > "$WORK/settled_$size.restart"
  # A series row and a check every 500 steps: the row's wall time at step 500 starts LIGGGHTS'
  # timed window. CHECK_EVERY=default (environment) keeps the scene's 100 checks per run.
  checks=""
  [ "${CHECK_EVERY:-500}" = default ] || checks="every_steps = ${CHECK_EVERY:-500}\n"
  series="\n[output]\nseries_csv = \"am_series.csv\"\n${checks}series_every_steps = 500\n"
  for variant in 0:"" 1:_heat; do
    { sed "s|file = \"data/|file = \"$PWD/scenes/data/|" "scenes/liggghts_bed_$size${variant#*:}.toml"
      printf "$series"; } > "$WORK/am_sim_${size}_heat${variant%%:*}.toml"
  done
done

results="$WORK/results.txt"
for rep in $(seq 1 "$REPS"); do
  for size in "${SIZES[@]}"; do
    if [ "$size" = 20k ]; then N=19200 STEPS=5000; else N=97200 STEPS=2000; fi
    for heat in "${HEATS[@]}"; do
      for t in "${THREADS[@]}"; do
        # The cores' distance in ns now, before a run of two threads or more (recorded for the
        # summary); nothing at 1 thread.
        apart_now() {
          (( t > 1 )) || return 0
          local ns
          ns=$("$LATENCY" | awk '{print $4}')
          echo "$1 $size $heat $t $ns" >> "$WORK/apart.txt"
          echo "$ns"
        }
        run_liggghts() {
          lig_apart=$(apart_now liggghts)
          (cd "$WORK" && mpirun --allow-run-as-root -np "$t" liggghts -in in.bench -var tag "$size" \
              -var heat "$heat" -var nsteps "$STEPS" -screen none -log lig.log > lig.out)
          loop=$(grep "Loop time" "$WORK"/lig.log | tail -1 | awk '{print $4}')
          echo "liggghts $size $heat $t $(python3 -c "print($N*$STEPS/$loop/$t)")" >> "$results"
        }
        run_am_sim() {
          am_apart=$(apart_now am-sim)
          (cd "$WORK" && "$AM_SIM" "am_sim_${size}_heat$heat.toml" --threads "$t" --quiet \
              --overwrite > am.log)
          # Particle-steps per second over the steps after the 500-step warm-up, as LIGGGHTS'
          # second "Loop time" times them.
          speed=$(python3 - "$WORK"/am_series.csv "$N" <<'PY'
import csv, sys
wall = {int(r["step"]): float(r["wall_time_s"]) for r in csv.DictReader(open(sys.argv[1]))}
last = max(wall)
print(int(sys.argv[2]) * (last - 500) / (wall[last] - wall[500]))
PY
)
          kernel=$(grep -m1 -o "contact kernel [a-z0-9]*" "$WORK"/am.log | cut -d' ' -f3)
          whole=$(awk '/particle-steps\/s/{print $2}' "$WORK"/am.log)   # its whole run loop
          echo "am-sim $size $heat $t $(python3 -c "print($speed/$t)") $kernel" \
            "(whole loop $(python3 -c "print(f'{$whole/$t:.4g}')"))" >> "$results"
        }
        # Who goes first alternates from repetition to repetition, so that neither program
        # always runs right after the other (on this shared host 2-thread speeds move with the
        # cores' placement, read above, from one minute to the next: take medians of several
        # repetitions, and compare like placements).
        if (( rep % 2 )); then run_liggghts; run_am_sim; else run_am_sim; run_liggghts; fi
        echo "rep $rep, bed $size, heat $heat, $t thread(s): $(tail -2 "$results" | tr '\n' ' ')"
        if (( t > 1 )); then
          echo "  the cores $lig_apart ns apart before LIGGGHTS' run, $am_apart ns before am-sim's"
        fi
      done
    done
  done
done
touch "$WORK/apart.txt"
python3 - "$results" "$WORK/apart.txt" <<'PY'
import statistics, sys, collections
runs = collections.defaultdict(list)
whole = collections.defaultdict(list)  # am-sim's whole run loop over its timed window
for line in open(sys.argv[1]):
    fields = line.split()
    prog, size, heat, threads, per_core = fields[:5]  # am-sim's lines add its laws' build and whole loop
    runs[(prog, size, int(heat), int(threads))].append(float(per_core))
    if prog == "am-sim":
        whole[(size, int(heat), int(threads))].append(float(fields[8].rstrip(")")) / float(per_core))
median = lambda key: statistics.median(runs[key])


def per_repetition(a, b, ratio, form=".2f"):
    """The ratio of two variants' runs of the same repetition (minutes apart, where the ratio of
    the medians may pair a fast minute with a slow one): the median, then each repetition's in
    order (the cores' distances below are in the same order)."""
    values = [ratio(x, y) for x, y in zip(runs[a], runs[b])]
    return (f"by repetition {statistics.median(values):{form}}"
            f" ({', '.join(f'{v:{form}}' for v in values)})")
print("\nparticle-steps per second per core (medians of %d runs)" % len(next(iter(runs.values()))))
# Each repetition runs the two programs back to back, so the ratio within a repetition is less
# touched by the host's drift from minute to minute than the ratio of the two medians, which
# may take LIGGGHTS' median from a fast minute and am-sim's from a slow one: both are printed.
print("bed | heat | threads | LIGGGHTS | am-sim | am-sim / LIGGGHTS | per repetition: median (range)")
keys = sorted({(s, h, t) for _, s, h, t in runs}, key=lambda k: (len(k[0]), k))
for s, h, t in keys:
    lig, am = median(("liggghts", s, h, t)), median(("am-sim", s, h, t))
    pairs = [a / l for l, a in zip(runs[("liggghts", s, h, t)], runs[("am-sim", s, h, t)])]
    print(f"{s:>4} | {h:4d} | {t:7d} | {lig:8.3e} | {am:8.3e} | {am / lig:.2f} | "
          f"{statistics.median(pairs):.2f} ({min(pairs):.2f}-{max(pairs):.2f})")
for (s, h, t), ratios in sorted(whole.items(), key=lambda k: (len(k[0][0]), k[0])):
    print(f"bed {s}, heat {h}, {t} thread(s): am-sim's whole loop reads {statistics.median(ratios):.3f}"
          f" × its timed window ({min(ratios):.3f}-{max(ratios):.3f})")
threads = sorted({t for _, _, t in keys})
for s, h in sorted({(s, h) for s, h, _ in keys}, key=lambda k: (len(k[0]), k)):
    if len(threads) > 1:
        t0, t1 = threads[0], threads[-1]
        for prog in ("liggghts", "am-sim"):
            speedup = median((prog, s, h, t1)) * t1 / (median((prog, s, h, t0)) * t0)
            each = per_repetition((prog, s, h, t1), (prog, s, h, t0), lambda a, b: a * t1 / (b * t0))
            print(f"bed {s}, heat {h}: {prog} {t1} threads vs {t0}: {speedup:.2f}x; {each}x")
apart = collections.defaultdict(list)
for line in open(sys.argv[2]):
    prog, s, h, t, ns = line.split()
    apart[(s, int(h), int(t), prog)].append(ns)
for (s, h, t, prog), readings in sorted(apart.items(), key=lambda k: (len(k[0][0]), k[0])):
    print(f"bed {s}, heat {h}, {t} threads: cores {', '.join(readings)} ns apart before {prog}'s runs"
          " (about 60-80: sharing a cache; about 330: far apart, where both lose, am-sim more)")
for s, t in sorted({(s, t) for s, _, t in keys}, key=lambda k: (len(k[0]), k)):
    if (s, 0, t) in keys and (s, 1, t) in keys:
        for prog in ("liggghts", "am-sim"):
            cost = median((prog, s, 0, t)) / median((prog, s, 1, t)) - 1.0
            each = per_repetition((prog, s, 0, t), (prog, s, 1, t), lambda a, b: 100 * (a / b - 1.0), "+.0f")
            print(f"bed {s}, {t} thread(s): heat conduction adds {100 * cost:.0f} % to {prog}'s step time;"
                  f" {each} %")
PY
