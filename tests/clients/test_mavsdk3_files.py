"""MAVLink FTP and log download with MAVSDK 3's own plugins (FTP, LogFiles,
Param) against the rotorpilot binary, through the scripts in
mavsdk_examples/ modelled on MAVSDK-Python's ftp_list_dir.py,
ftp_download_file.py and logfile_download.py, plus PX4's packed parameter
file (@PARAM/param.pck) downloaded, decoded, compared and uploaded.

A first run with --log-dir writes a ULog and stops (the log is complete);
each later run of the same instance with the same --log-dir serves every
run's log, its own included, and the scripts download the first and compare it byte for byte with
the file on disk. Run in the mavsdk<4 venv (with pyulog):
`python -m pytest tests/clients/test_mavsdk3_files.py`.
"""

import glob
import os
import shutil
import sys
import tempfile
import time
from pathlib import Path

import pytest

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from harness import Vehicle  # noqa: E402
from test_mavsdk3 import run_script  # noqa: E402

SPEED = 5.0


@pytest.fixture(scope="module")
def two_runs():
    """(instance, log dir, the first run's finished ULog)."""
    logs = tempfile.mkdtemp(prefix="rotorpilot-ftp-logs-")
    with Vehicle(speed=SPEED, extra=["--log-dir", logs]) as v:
        instance = v.instance
        time.sleep(2.0)
    first = glob.glob(os.path.join(logs, f"*-i{instance}", "flight.ulg"))
    assert len(first) == 1, first
    # the next run starts in a later second: its own directory
    time.sleep(1.1)
    yield instance, logs, first[0]
    shutil.rmtree(logs, ignore_errors=True)


@pytest.mark.parametrize("script", ["ftp_list_dir.py", "ftp_download_file.py", "logfile_download.py"])
def test_files_and_logs(two_runs, script, monkeypatch):
    instance, logs, first = two_runs
    monkeypatch.setenv("ROTORPILOT_LOG_FILE", first)
    with Vehicle(instance=instance, speed=SPEED, extra=["--log-dir", logs]) as v:
        # every run so far, this one's log (being written) included
        runs = glob.glob(os.path.join(logs, f"*-i{instance}"))
        assert len(runs) >= 2, runs
        monkeypatch.setenv("ROTORPILOT_EXPECT_LOGS", str(len(runs)))
        run_script(script, v)


def test_param_pck_download_matches_the_list_and_upload_sets_a_parameter():
    with Vehicle(speed=SPEED) as v:
        run_script("param_pck.py", v)
        params = open(os.path.join(v.state_dir, "params.toml")).read()
    assert "MIS_TAKEOFF_ALT" in params, "the uploaded value is saved as any set is"


def test_no_log_dir_lists_the_root_with_an_empty_log_directory(monkeypatch):
    monkeypatch.setenv("ROTORPILOT_EXPECT_LOGS", "0")
    with Vehicle(speed=SPEED) as v:
        run_script("ftp_list_dir.py", v)
