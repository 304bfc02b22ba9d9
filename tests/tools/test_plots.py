"""The plotting tools turn real logs into PNG figures.

Run by tools/test-all.sh with the pinned matplotlib; ROTORPILOT_BIN points at
the release binary.
"""
import os
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
BIN = os.environ.get("ROTORPILOT_BIN", os.path.join(ROOT, "target", "release", "rotorpilot"))
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def run(*args, **kw):
    return subprocess.run(args, check=True, capture_output=True, text=True, timeout=120, **kw)


def assert_pngs(paths):
    assert paths, "no figure written"
    for p in paths:
        with open(p, "rb") as f:
            head = f.read(8)
        assert head == PNG_MAGIC, p
        assert os.path.getsize(p) > 10_000, f"{p} is suspiciously small"


def test_plot_flight_draws_the_reports_figures(tmp_path):
    log = tmp_path / "ex5.csv"
    run(BIN, "simulate", os.path.join(ROOT, "tools/scenarios/fsr-exercise5.toml"), "--csv", str(log))
    out = run(sys.executable, os.path.join(ROOT, "tools/plot_flight.py"), str(log), "--out", str(tmp_path / "fig"))
    written = out.stdout.split()
    names = {os.path.basename(p) for p in written}
    assert {"position_error.png", "velocity_error.png", "attitude.png", "angular_velocity.png",
            "inputs.png"} <= names
    # roll and pitch are plotted as flown (the log has no setpoint for them): not named an error
    assert "attitude_error.png" not in names
    assert_pngs(written)


def test_plot_estimates_draws_three_figures_per_order_and_a_comparison(tmp_path):
    log = tmp_path / "ex4.csv"
    run(BIN, "simulate", os.path.join(ROOT, "tools/scenarios/fsr-exercise4.toml"), "--csv", str(log))
    run(BIN, "estimate", str(log), "--order", "1,5,20", "--poly", "binomial")
    out = run(sys.executable, os.path.join(ROOT, "tools/plot_estimates.py"), str(log),
              str(tmp_path / "ex4-estimates.csv"), "--orders", "1,5,20", "--poly", "binomial",
              "--out", str(tmp_path / "fig"))
    written = out.stdout.split()
    assert len(written) == 3 * 3 + 1
    assert_pngs(written)


def test_plot_flight_refuses_a_log_without_the_columns(tmp_path):
    bad = tmp_path / "bad.csv"
    bad.write_text("time_s,x\n0,1\n0.001,2\n")
    r = subprocess.run([sys.executable, os.path.join(ROOT, "tools/plot_flight.py"), str(bad)],
                       capture_output=True, text=True, timeout=60)
    assert r.returncode != 0
    assert "bad.csv:1: missing column" in r.stderr


def test_plot_estimates_takes_the_nominal_mass_from_the_flights_sidecar(tmp_path, capsys):
    sys.path.insert(0, os.path.join(ROOT, "tools"))
    import plot_estimates

    log = tmp_path / "quad.csv"
    run(BIN, "simulate", os.path.join(ROOT, "tools/scenarios/quad-step-10m.toml"), "--csv", str(log))
    assert plot_estimates.nominal_mass(str(log), None) == 2.0  # the quad's, from quad.csv.meta.json
    assert plot_estimates.nominal_mass(str(log), 3.0) == 3.0  # --nominal-mass overrides
    assert "warning" not in capsys.readouterr().err
    os.remove(str(log) + ".meta.json")
    assert plot_estimates.nominal_mass(str(log), None) == 1.5
    err = capsys.readouterr().err
    assert "warning" in err and "quad.csv.meta.json" in err and "--nominal-mass" in err


def test_plot_flight_reads_a_flight_record_and_draws_the_path(tmp_path):
    """A kept flight has a flight.record and no CSV: plot_flight.py replays
    it (`rotorpilot replay --csv`) and draws its figures, the north/east
    path among them, as from the CSV of the same flight."""
    logs = tmp_path / "logs"
    env = dict(os.environ, ROTORPILOT_BIN=BIN)
    daemon = subprocess.Popen(
        [BIN, "--speed", "50", "--log-dir", str(logs), "--state-dir", str(tmp_path / "state"),
         "--gcs-bind", "127.0.0.1:0", "--api-bind", "127.0.0.1:0", "--gcs-remote", "none", "--api-remote", "none"],
        stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    try:
        for line in daemon.stdout:
            if line.startswith("rotorpilot: ready to arm"):
                break
        import time
        time.sleep(0.5)
    finally:
        daemon.terminate()
        daemon.wait(10)
    (run_dir,) = list(logs.iterdir())
    record = run_dir / "flight.record"
    assert record.is_file() and not (run_dir / "flight.csv").exists()
    out = run(sys.executable, os.path.join(ROOT, "tools/plot_flight.py"), str(record), "--out",
              str(tmp_path / "fig"), env=env)
    written = out.stdout.split()
    names = {os.path.basename(p) for p in written}
    assert {"path_ne.png", "position_error.png", "attitude.png", "inputs.png"} <= names, names
    assert_pngs(written)
    # a record that does not replay is named with replay's own error
    bad = tmp_path / "bad.record"
    bad.write_text(record.read_text().splitlines()[0] + "\nhello\n")
    r = subprocess.run([sys.executable, os.path.join(ROOT, "tools/plot_flight.py"), str(bad)],
                       capture_output=True, text=True, timeout=60, env=env)
    assert r.returncode != 0 and "rotorpilot replay failed" in r.stderr and "not a record line" in r.stderr, r.stderr
