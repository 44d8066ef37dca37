"""`hoverfly sim --log`: the real-time simulator writes a ULog that pyulog reads, and closes it on exit."""

import subprocess
import sys
from pathlib import Path

import pytest

pyulog = pytest.importorskip("pyulog")

HOVERFLY = str(Path(sys.executable).with_name("hoverfly"))


def test_sim_writes_a_log_that_pyulog_reads(tmp_path):
    path = tmp_path / "sim.ulg"
    res = subprocess.run([HOVERFLY, "sim", "--msp-port", "0", "--maint-port", "0", "--duration", "1.5",
                          "--log", str(path)], capture_output=True, text=True, timeout=60)
    assert res.returncode == 0, res.stderr
    log = pyulog.ULog(str(path))
    assert not log.file_corruption
    names = {d.name for d in log.data_list}
    assert {"vehicle_attitude", "sensor_combined", "actuator_outputs", "input_rc"} <= names
    att = next(d for d in log.data_list if d.name == "vehicle_attitude")
    t = att.data["timestamp"]
    assert (t[-1] - t[0]) / 1e6 > 1.0  # a second and more of the flight, at the logging rate
    assert len(t) > 900


def test_sim_log_in_a_missing_directory_is_a_one_line_error(tmp_path):
    res = subprocess.run([HOVERFLY, "sim", "--msp-port", "0", "--maint-port", "0", "--duration", "1",
                          "--log", str(tmp_path / "no" / "such" / "dir" / "x.ulg")],
                         capture_output=True, text=True, timeout=60)
    assert res.returncode == 2
    assert res.stderr.startswith("hoverfly: error:")
    assert "Traceback" not in res.stderr
