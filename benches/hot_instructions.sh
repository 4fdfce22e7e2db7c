#!/usr/bin/env bash
# Instruction by instruction: the disassembly of the functions matching PATTERN, each instruction
# with how many times it ran per particle-step on a scene (callgrind, 1 thread). Where
# `benches/instructions.sh` says which part of the step takes the instructions, this says which
# instructions they are: the loads of a lane, a pointer reloaded from the stack, a bounds check,
# the spring ring's bookkeeping. The step waits on instructions (docs/performance-log.md, eighteenth
# round), so this is where a change to the fill, the write-back or the sift is planned and
# checked (fortieth round).
#
# Builds the release binary with line tables and v0 symbol names (each build of a generic
# function under its own name) in a target folder of its own, runs the scene for STEPS steps
# under `valgrind --tool=callgrind --dump-instr=yes`, and prints `hot_instructions.py`'s reading.
# The counts include the set-up, which the step's functions do not run; valgrind does not run
# AVX-512, so the kernels run their AVX2 builds (`--simd avx2`).
#
# usage: benches/hot_instructions.sh PATTERN [SCENE] [STEPS] [-- hot_instructions.py options]
#   e.g. benches/hot_instructions.sh 'pair_pass::handle_kept::<false, true, false>'
#        benches/hot_instructions.sh 'pair_pass::write_lanes' scenes/liggghts_bed_20k.toml 500 -- --lines
#   PATTERN is a regular expression on the demangled names (`nm -C`); defaults: the 19.2k
#   LIGGGHTS bed, 1000 steps (about a minute under valgrind).
# needs: apt-get install valgrind binutils
set -euo pipefail
cd "$(dirname "$0")/.."
[ $# -ge 1 ] || { sed -n '2,/^set -euo/p' "$0" | sed '$d; s/^# \{0,1\}//' >&2; exit 2; }
PATTERN=$1
shift
SCENE=scenes/liggghts_bed_20k.toml
STEPS=1000
[ $# -ge 1 ] && [ "$1" != "--" ] && { SCENE=$1; shift; }
[ $# -ge 1 ] && [ "$1" != "--" ] && { STEPS=$1; shift; }
[ $# -ge 1 ] && [ "$1" = "--" ] && shift
command -v valgrind >/dev/null || { echo "valgrind not found: apt-get install -y valgrind" >&2; exit 1; }
command -v objdump >/dev/null || { echo "objdump not found: apt-get install -y binutils" >&2; exit 1; }

CARGO_PROFILE_RELEASE_DEBUG=line-tables-only RUSTFLAGS="-C symbol-mangling-version=v0" \
  cargo build --release --quiet --target-dir target/hot
AM_SIM=$(realpath target/hot/release/am-sim)
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT
# REP_OFF (glibc's string instructions out of valgrind's way), scene_for_steps, particles_of.
source benches/valgrind_scene.sh
scene_for_steps "$SCENE" "$STEPS" "$WORK/scene.toml"
(cd "$WORK" && GLIBC_TUNABLES=$REP_OFF valgrind --tool=callgrind --dump-instr=yes \
    --callgrind-out-file="$WORK/callgrind.out" "$AM_SIM" scene.toml --threads 1 --quiet \
    --simd avx2 > "$WORK/run.txt" 2> "$WORK/valgrind.txt")
particles=$(particles_of "$WORK/run.txt")
echo "$SCENE, $STEPS steps of $particles particles: counts per particle-step"
python3 benches/hot_instructions.py "$WORK/callgrind.out" "$AM_SIM" "$PATTERN" \
  --unit "$((STEPS * particles))" "$@"
