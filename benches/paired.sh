#!/usr/bin/env bash
# Paired runs of two am-sim builds (or two scenes) at 1 thread: A and B at once, one per core,
# then swapped, so that both see the same minute of a shared host. Prints, per pair, the four
# speeds (particle-steps per second) and B's speed over A's summed over both placements, and at
# the end the median of those ratios. On the noisy 2-core hosts of docs/performance.md this is
# how every change since the thirtieth round was timed: single runs move by 10-30 % from minute
# to minute, a pair by a few per cent.
#
# It also says whether the two runs' summaries agree apart from their timings: a change meant to
# be bitwise the same must print "summaries: the same" for every pair.
#
# usage: benches/paired.sh A_BINARY A_SCENE B_BINARY B_SCENE [PAIRS]
#   e.g. a throw-away build against the tree's, on the LIGGGHTS bed (scene paths relative to the
#   repository root; the scene's data files are found beside it):
#     benches/paired.sh target/release/am-sim scenes/liggghts_bed_20k.toml \
#       /tmp/tgt-x/release/am-sim scenes/liggghts_bed_20k.toml 3
#   or one build on two scenes (heat's cost): ... A scenes/liggghts_bed_100k.toml A
#   scenes/liggghts_bed_100k_heat.toml
# Needs 2 cores (taskset from util-linux).
set -euo pipefail
usage="usage: benches/paired.sh A_BINARY A_SCENE B_BINARY B_SCENE [PAIRS]"
A=$(realpath "${1:?$usage}")
SCENE_A=$(realpath "${2:?$usage}")
B=$(realpath "${3:?$usage}")
SCENE_B=$(realpath "${4:?$usage}")
PAIRS=${5:-3}
for binary in "$A" "$B"; do
  [ -x "$binary" ] || { echo "paired.sh: $binary is not an executable" >&2; exit 1; }
done
if [ "$(nproc)" -lt 2 ]; then
  echo "paired.sh: needs 2 cores, this machine has $(nproc)" >&2
  exit 1
fi
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT
# Each run in a folder of its own: a scene's output files are named relative to the working
# directory, and two runs writing the same file at once would refuse to start or clash.
mkdir "$WORK/a" "$WORK/b"

speed() { grep -o "speed: [0-9.e+-]*" "$1" | awk '{print $2}'; }
# The summary without the lines that carry timings.
summary() { grep -v "speed:\|wall time" "$1"; }

ratios=()
for pair in $(seq "$PAIRS"); do
  speeds=()
  same=yes
  for placement in "0 1" "1 0"; do
    read -r core_a core_b <<< "$placement"
    (cd "$WORK/a" && taskset -c "$core_a" "$A" "$SCENE_A" --threads 1 --overwrite) \
      > "$WORK/a.log" 2>&1 &
    run_a=$!
    (cd "$WORK/b" && taskset -c "$core_b" "$B" "$SCENE_B" --threads 1 --overwrite) \
      > "$WORK/b.log" 2>&1 || {
      kill "$run_a" 2> /dev/null || true
      echo "paired.sh: B failed:" >&2; tail -5 "$WORK/b.log" >&2; exit 1; }
    wait "$run_a" || { echo "paired.sh: A failed:" >&2; tail -5 "$WORK/a.log" >&2; exit 1; }
    speeds+=("$(speed "$WORK/a.log")" "$(speed "$WORK/b.log")")
    cmp -s <(summary "$WORK/a.log") <(summary "$WORK/b.log") || same=no
  done
  ratio=$(python3 -c "a1, b1, a2, b2 = map(float, '${speeds[*]}'.split()); print(f'{(b1 + b2) / (a1 + a2):.3f}')")
  ratios+=("$ratio")
  [ "$same" = yes ] && agree="the same" || agree="differ"
  echo "pair $pair: A ${speeds[0]} ${speeds[2]}, B ${speeds[1]} ${speeds[3]}: B/A $ratio; summaries: $agree"
done
python3 -c "import statistics; r = [float(x) for x in '${ratios[*]}'.split()]; print(f'B/A median {statistics.median(r):.3f} of {len(r)} pairs ({min(r):.3f}-{max(r):.3f})')"
