#!/usr/bin/env bash
# One scene over several seeds of its random insertion: what a single run's bond count, melted
# and evaporating particles are worth. A packed bed is chaotic: a change at the rounding level, or
# another seed, gives another packing and another bond count (README, "The main job"), so a
# figure to compare across code versions or against a paper is a mean over seeds, with its spread.
#
# Runs the scene once per seed, each with every `seed = ...` line of the scene (its [[insert]]
# blocks) set to that seed, in a temporary folder (the frames are written there and removed), and
# prints a table of the runs' spheres, bonds, melted and evaporating particles and energy balance
# residuals, then the mean and the sample standard deviation of each column.
#
# usage: scripts/seeds.sh [SCENE] [SEEDS...]
#   defaults: scenes/bed.toml, seeds 316 (the committed one) to 320; about two to four minutes per
#   seed at 2 threads. THREADS (environment) sets the thread count (default: all cores).
# AM_SIM=path/to/am-sim selects the binary (default: target/release/am-sim, built if missing).
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
scene=$(realpath "${1:-$root/scenes/bed.toml}")
shift || true
seeds=("$@")
((${#seeds[@]})) || seeds=(316 317 318 319 320)
grep -q '^seed *=' "$scene" || { echo "$scene: no 'seed = ...' line to vary" >&2; exit 1; }
AM_SIM=${AM_SIM:-$root/target/release/am-sim}
if [[ ! -x "$AM_SIM" ]]; then
    (cd "$root" && cargo build --release --quiet)
fi
threads=()
[[ -n "${THREADS:-}" ]] && threads=(--threads "$THREADS")

work=$(mktemp -d)
# The varied scene sits beside the original, so that the files it names are found as they are.
varied="$(dirname "$scene")/.seeds-$$-$(basename "$scene")"
trap 'rm -rf "$work" "$varied"' EXIT

table="$work/table"
for seed in "${seeds[@]}"; do
    [[ "$seed" =~ ^[0-9]+$ ]] || { echo "seed '$seed': not a non-negative integer" >&2; exit 1; }
    sed -E "s/^seed *= *[0-9]+/seed = $seed/" "$scene" > "$varied"
    mkdir -p "$work/$seed"
    echo "seed $seed: running $(basename "$scene") ..." >&2
    (cd "$work/$seed" && "$AM_SIM" -q "${threads[@]}" "$varied" > run.log 2>&1) || {
        echo "seed $seed: am-sim failed; its output:" >&2
        cat "$work/$seed/run.log" >&2
        exit 1
    }
    # The summary's lines: the header's particle count, the contacts' bonds, the thermal results'
    # melted particles, the evaporation's particles, the run's energy balance residual (the last
    # one printed: the deposition prints its own before it).
    awk -v seed="$seed" '
        /particles, [0-9]+ steps/ { for (i = 1; i <= NF; i++) if ($(i + 1) == "particles,") spheres = $i }
        /bonds: [0-9]+/ { match($0, /bonds: [0-9]+/); bonds = substr($0, RSTART + 7, RLENGTH - 7) }
        / particles melted/ { for (i = 1; i <= NF; i++) if ($(i + 1) == "particles" && $(i + 2) ~ /^melted/) melted = $i }
        /vapour from [0-9]+ particles/ { for (i = 1; i <= NF; i++) if ($i == "from") evaporating = $(i + 1) }
        /energy balance residual/ { for (i = 1; i <= NF; i++) if ($i == "residual") residual = $(i + 1) }
        END {
            if (bonds == "") bonds = "-"; if (melted == "") melted = "-";
            if (evaporating == "") evaporating = "-"; if (residual == "") residual = "-";
            print seed, spheres, bonds, melted, evaporating, residual
        }' "$work/$seed/run.log" >> "$table"
done

plural=s
((${#seeds[@]} == 1)) && plural=""
echo "$(basename "$scene") over ${#seeds[@]} seed$plural"
echo
echo "| seed | spheres | bonds | melted | evaporating | energy residual |"
echo "|---|---|---|---|---|---|"
awk '{ printf "| %s | %s | %s | %s | %s | %s |\n", $1, $2, $3, $4, $5, $6 }' "$table"
awk '
    { for (c = 2; c <= 6; c++) if ($c != "-") { n[c]++; s[c] += $c; q[c] += $c * $c } }
    END {
        split("spheres bonds melted evaporating residual", name, " ")
        line = "mean (sample standard deviation):"
        for (c = 2; c <= 6; c++) {
            if (n[c] == 0) continue
            mean = s[c] / n[c]
            var = n[c] > 1 ? (q[c] - n[c] * mean * mean) / (n[c] - 1) : 0
            sd = var > 0 ? sqrt(var) : 0
            fmt = c == 6 ? " %s %.3g (%.2g)" : " %s %.1f (%.1f)"
            line = line sprintf(fmt, name[c - 1], mean, sd)
        }
        print ""
        print line
    }' "$table"
