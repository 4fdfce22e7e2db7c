#!/usr/bin/env bash
# Instructions per particle-step of the run loop, by part of the step, on the LIGGGHTS benchmark
# bed: a measure of the step that does not move with the hour. On the shared 2-core host the
# clock scatters by up to a quarter from run to run (docs/performance-log.md, twenty-fifth round),
# so a change of a few per cent cannot be timed there; its instruction count can, exactly. The
# step waits on instructions rather than on memory (eighteenth round), so fewer instructions in
# the fill, the write-back or the sift is what a faster step needs. Time still decides: confirm
# a change with alternating runs on a quiet hour (benches/liggghts_compare.sh).
#
# Runs the bed under cachegrind for N and 2N steps at 1 thread and takes the difference, so the
# import and set-up drop out; divides by N × particles. Valgrind does not run AVX-512, so the
# contact kernel runs its AVX2 build here (`--simd avx2`); its count is that build's.
#
# usage: benches/instructions.sh [SCENE] [N]
#   defaults: scenes/liggghts_bed_20k.toml, 1000 steps (about a minute and a half in all);
#   scenes/liggghts_bed_20k_heat.toml gives the heat variant.
# needs: apt-get install valgrind (cachegrind and cg_annotate)
set -euo pipefail
cd "$(dirname "$0")/.."
SCENE=${1:-scenes/liggghts_bed_20k.toml}
STEPS=${2:-1000}
command -v valgrind >/dev/null || { echo "valgrind not found: apt-get install -y valgrind" >&2; exit 1; }
command -v cg_annotate >/dev/null || { echo "cg_annotate not found: apt-get install -y valgrind" >&2; exit 1; }

# Symbols mangled the v0 way keep their generic arguments, so that the builds of a vector kernel
# (`simd::loop_avx2::<integrate::KickDrift>`, `::<forces::lanes::PairKernel<..>>`) count in
# their own parts instead of under one name. A target folder of its own: the flag would
# otherwise rebuild the release binary each time. It changes the names, not the code.
RUSTFLAGS="-C symbol-mangling-version=v0" cargo build --release --quiet --target-dir target/instructions
AM_SIM=$(realpath target/instructions/release/am-sim)
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT
# REP_OFF (glibc's string instructions out of valgrind's way), scene_for_steps, particles_of.
source benches/valgrind_scene.sh
for n in "$STEPS" $((2 * STEPS)); do
  scene_for_steps "$SCENE" "$n" "$WORK/scene_$n.toml"
  (cd "$WORK" && GLIBC_TUNABLES=$REP_OFF valgrind --tool=cachegrind --cache-sim=no --cachegrind-out-file="$WORK/cg_$n" \
      "$AM_SIM" "scene_$n.toml" --threads 1 --quiet --simd avx2 > "$WORK/run_$n.txt" 2> "$WORK/valgrind_$n.txt")
  # Every function listed (`--threshold=0`): by default a function below 0.1 % of its run's total
  # is left out, and one listed in a single run of the two made the parts' differences miss 3.5
  # of the 19.2k bed's 358.1 per particle-step (its "rest" read -1.6 where it is +1.3; sixtieth
  # round).
  cg_annotate --auto=no --threshold=0 "$WORK/cg_$n" > "$WORK/annotated_$n.txt"
done
particles=$(particles_of "$WORK/run_$STEPS.txt")

python3 - "$WORK/annotated_$STEPS.txt" "$WORK/annotated_$((2 * STEPS)).txt" "$STEPS" "$particles" "$SCENE" <<'EOF'
import re, sys
short, long_, steps, particles, scene = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4]), sys.argv[5]
# The parts of a step, by the functions that carry them in a release build (inlined callees count
# in their caller; v0 names write a method `<Type>::method`). The first pattern that matches a
# function names its part.
PARTS = [
    ("sift of the near lists", r"NeighborList>?::visit_slabs"),
    ("fill of the lanes", r"pair_pass::handle_kept"),
    ("write-back", r"pair_pass::Batch>?::flush|pair_pass::write_lanes"),
    ("contact kernel", r"forces::lanes::"),
    ("drift and kicks", r"integrate::"),
    ("particle pass (walls)", r"particle_pass::|scatter::for_each_chunk|wall_lanes::"),
    ("temperatures", r"thermal::"),
    ("diagnostics (at the output cadence)", r"diagnostics|stability_limit_of|pair_geometry|periodic::"),
    ("memset, memcpy", r"memset|memmove|memcpy"),
]
line = re.compile(r"^\s*([\d,]+)\s+\(\s*[\d.]+%\)\s+(.*)$")

def counts(path):
    totals, functions = {}, {}
    for text in open(path, encoding="utf-8", errors="replace"):
        m = line.match(text)
        if not m:
            continue
        value, name = int(m.group(1).replace(",", "")), m.group(2)
        if "PROGRAM TOTALS" in name:
            totals["all"] = value
            continue
        functions[name] = functions.get(name, 0) + value
    return totals["all"], functions

total_short, short_functions = counts(short)
total_long, long_functions = counts(long_)
per_step = steps * particles
by_part = {name: 0 for name, _ in PARTS}
by_part["the rest"] = 0
for function in set(short_functions) | set(long_functions):
    difference = long_functions.get(function, 0) - short_functions.get(function, 0)
    part = next((name for name, pattern in PARTS if re.search(pattern, function)), "the rest")
    by_part[part] += difference
loop = total_long - total_short
print(f"{scene}: instructions per particle-step of the run loop ({steps} steps of {particles} particles,")
print(f"the difference of runs of {steps} and {2 * steps} steps; the contact kernel's AVX2 build)")
print()
print(f"| part | instructions per particle-step | share |")
print(f"|---|---|---|")
for name, value in sorted(by_part.items(), key=lambda kv: -kv[1]):
    if value:
        print(f"| {name} | {value / per_step:.1f} | {100 * value / loop:.1f} % |")
print(f"| **all** | **{loop / per_step:.1f}** | |")
# What the difference cancels: the checks made at each output (diagnostics, the contact walk),
# as many in either run (100 outputs per run, and the start's). The timed benchmark pays them
# (5500 steps, 100 outputs); LIGGGHTS' prints only at its ends.
outputs = 101
checks_pattern = dict(PARTS)["diagnostics (at the output cadence)"]
checks = sum(value for function, value in short_functions.items()
             if re.search(checks_pattern, function))
print()
print(f"The checks at each output, which the difference leaves out: {checks / (outputs * particles):.0f} "
      f"instructions per particle per output ({checks / per_step:.1f} per particle-step of this "
      f"{steps}-step run, {checks / (5500 * particles):.1f} of a 5500-step one).")
EOF
