#!/usr/bin/env bash
# bench_steps.sh [--check]: instructions per simulated step, counted by
# valgrind's callgrind (a count does not move with the machine's load, a
# wall time does), for four workloads:
#   bare     one lockstep step of the quad flying the figure-eight at 2 m with
#            the geometric law and the estimate fed back (examples/steps.rs):
#            (I(12000 steps) - I(2000 steps)) / 10000, start-up cancelled out;
#   mission  `rotorpilot simulate tools/scenarios/mission-square.toml`, the
#            whole flight stack headless: all instructions of the run over its
#            steps (start-up included, under 0.5 % of it);
#   filter   the same mission on the navigation filter, as the daemon flies
#            by default (the file with `[navigation] source = "filter"`): the
#            raw sensors, the filter and its output predictor on top;
#   fleet    one vehicle-step of a headless fleet (`rotorpilot simulate
#            tools/fleets/fleet-16.toml --json --threads 1`: fleet-1024.toml's
#            figure-eight quads, 16 of them, on one stepping thread), the
#            fleet flown for 12 s and for 2 s (copies of the file with its
#            [fleet] duration_s changed): (I(12 s) - I(2 s)) / the
#            vehicle-steps between them, start-up cancelled out as for bare.
# --check (tools/test-all.sh): shorter bare runs (6000 and 1000 steps) and
# fleet runs (6 s and 1 s), and a failure when any figure is above its
# ceiling below, a little above what the step costs today, so that a change
# that makes every step dearer shows up as a number. docs/performance.md
# gives the figures and their history.
set -euo pipefail
cd "$(dirname "$0")/.."

# Ceilings [instructions per step] for --check, 5 % above the figures of
# docs/performance.md, with room for the small shifts of code generation.
# The plant step, the control law, allocation, the shaper and the estimator
# run AVX2 code where the CPU has it (the same bits, fewer instructions), so
# the ceilings depend on the CPU: on an AVX2 machine 5 % above 4,911, 6,484,
# 9,355 and 5,271 (bare, mission, filter, fleet); without AVX2, 5 % above
# the x86-64 baseline's 5,847, 7,359, 10,166 and 6,178 plus about 190 for
# the estimator's baseline code.
if grep -qw avx2 /proc/cpuinfo 2>/dev/null; then
    BARE_CEILING=5160 MISSION_CEILING=6810 FILTER_CEILING=9830 FLEET_CEILING=5540
else
    BARE_CEILING=6340 MISSION_CEILING=7930 FILTER_CEILING=10880 FLEET_CEILING=6690
fi

check=false
case "${1:-}" in
    --check) check=true ;;
    "") ;;
    *) echo "usage: tools/bench_steps.sh [--check]" >&2; exit 2 ;;
esac
command -v valgrind >/dev/null || { echo "bench_steps.sh: valgrind is not installed (apt-get install valgrind)" >&2; exit 2; }

cargo build --release --quiet --example steps --bin rotorpilot
bin="${CARGO_TARGET_DIR:-$PWD/target}/release"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

# instructions N of one run under callgrind ("I refs: N" on stderr); the
# program's own output goes to $tmp/out
refs() {
    valgrind --tool=callgrind --callgrind-out-file="$tmp/callgrind.out" "$@" >"$tmp/out" 2>"$tmp/err" \
        || { cat "$tmp/err" >&2; exit 1; }
    sed -n 's/.*I *refs: *//p' "$tmp/err" | tr -d ,
}

if $check; then long=6000 short=1000; else long=12000 short=2000; fi
bare_long=$(refs "$bin/examples/steps" quad geometric "$long")
bare_short=$(refs "$bin/examples/steps" quad geometric "$short")
bare=$(( (bare_long - bare_short) / (long - short) ))

mission_total=$(refs "$bin/rotorpilot" simulate tools/scenarios/mission-square.toml --json)
# the scenario's 1 kHz step: sim_time_s / 0.001 steps
steps=$(python3 -c 'import json,sys; print(round(json.load(open(sys.argv[1]))["sim_time_s"] * 1000))' "$tmp/out")
mission=$(( mission_total / steps ))

{ cat tools/scenarios/mission-square.toml; printf '\n[navigation]\nsource = "filter"\n'; } >"$tmp/filter.toml"
filter_total=$(refs "$bin/rotorpilot" simulate "$tmp/filter.toml" --json)
filter_steps=$(python3 -c 'import json,sys; print(round(json.load(open(sys.argv[1]))["sim_time_s"] * 1000))' "$tmp/out")
filter=$(( filter_total / filter_steps ))

# the fleet flown for $1 seconds: a copy of the file with that duration_s,
# its vehicles' scenario path (relative to the file) made absolute
fleet_file=tools/fleets/fleet-16.toml
fleet_copy() {
    sed -e "s|^duration_s = .*|duration_s = $1|" \
        -e "s|^scenario = \"|scenario = \"$PWD/tools/fleets/|" "$fleet_file" >"$tmp/fleet-$1.toml"
    echo "$tmp/fleet-$1.toml"
}
vehicle_steps() { python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["vehicle_steps"])' "$tmp/out"; }
fleet_long_s="$(( long / 1000 )).0" fleet_short_s="$(( short / 1000 )).0"
fleet_long=$(refs "$bin/rotorpilot" simulate "$(fleet_copy "$fleet_long_s")" --json --threads 1)
fleet_long_vsteps=$(vehicle_steps)
fleet_short=$(refs "$bin/rotorpilot" simulate "$(fleet_copy "$fleet_short_s")" --json --threads 1)
fleet_short_vsteps=$(vehicle_steps)
fleet_vsteps=$(( fleet_long_vsteps - fleet_short_vsteps ))
fleet=$(( (fleet_long - fleet_short) / fleet_vsteps ))

printf 'bare step (quad, geometric, estimator on): %d instructions/step ((%d - %d) / %d)\n' \
    "$bare" "$bare_long" "$bare_short" "$(( long - short ))"
printf 'mission-square step (whole flight stack):   %d instructions/step (%d / %d steps)\n' \
    "$mission" "$mission_total" "$steps"
printf 'mission-square step on the filter:          %d instructions/step (%d / %d steps)\n' \
    "$filter" "$filter_total" "$filter_steps"
printf 'fleet vehicle-step (fleet-16, 1 thread):    %d instructions/vehicle-step ((%d - %d) / %d vehicle-steps)\n' \
    "$fleet" "$fleet_long" "$fleet_short" "$fleet_vsteps"

if $check; then
    fail=0
    if (( bare > BARE_CEILING )); then
        echo "bare step costs $bare instructions, above its ceiling $BARE_CEILING" >&2
        fail=1
    fi
    if (( mission > MISSION_CEILING )); then
        echo "mission-square step costs $mission instructions, above its ceiling $MISSION_CEILING" >&2
        fail=1
    fi
    if (( filter > FILTER_CEILING )); then
        echo "mission-square step on the filter costs $filter instructions, above its ceiling $FILTER_CEILING" >&2
        fail=1
    fi
    if (( fleet > FLEET_CEILING )); then
        echo "fleet vehicle-step costs $fleet instructions, above its ceiling $FLEET_CEILING" >&2
        fail=1
    fi
    (( fail == 0 )) && echo "all under their ceilings ($BARE_CEILING, $MISSION_CEILING, $FILTER_CEILING, $FLEET_CEILING)"
    exit "$fail"
fi
