"""A plane's airspeed in the flight log, the log report and the CLI (issue 23): the trainer flies `box` with the sim
board's pitot (JSBSim's airspeed with a little seeded noise), the log's PX4 airspeed topic agrees with the airspeed
`hoverfly fly --json` judged, and `hoverfly log report` plots it; a quad has no pitot and its log no airspeed."""

import numpy as np
import pytest

from hoverfly.core.links.cliserver import CliServer
from hoverfly.logs.data import load
from hoverfly.logs.report import write_report
from hoverfly.sim.runner import SimRun
from hoverfly.sim.scenario import load_scenario

pytest.importorskip("jsbsim")


@pytest.fixture(scope="module")
def box_flight(tmp_path_factory):
    d = tmp_path_factory.mktemp("airspeed")
    path = str(d / "box.ulg")
    run = SimRun("trainer", "box", seed=3, log_path=path)
    result = run.run()
    return run, result, load(path), d


def test_trainer_box_logs_airspeed_whose_mean_is_the_flights_airspeed(box_flight):
    run, result, log, _ = box_flight
    a = log.topic("airspeed")
    assert a is not None
    t = a["t_s"]
    ias = a["indicated_airspeed_m_s"]
    # at most 20 Hz, and all the flight long
    assert np.min(np.diff(t)) >= 0.049
    assert len(t) >= 0.9 * 20 * run.duration_s
    # the judge averages while the plane is off the ground: from the throw on
    throw_s = [e["t"] for e in load_scenario("box")["events"] if e.get("throw")][0]
    flown = ias[t >= throw_s]
    judged = result["airspeed_m_s"]
    assert abs(float(np.mean(flown)) - judged["mean"]) <= 1.0
    assert judged["min"] - 1.5 <= float(np.min(flown)) and float(np.max(flown)) <= judged["max"] + 1.5
    # no static pressure or temperature: true airspeed is the indicated one, at full confidence
    assert np.array_equal(a["true_airspeed_m_s"], ias)
    assert np.all(a["confidence"] == 1.0)
    # on the ground before the throw the pitot reads about nothing
    assert float(np.max(ias[t < 1.0])) < 2.0


def test_cli_status_shows_the_planes_airspeed_at_the_end_of_the_box(box_flight):
    run, _, _, _ = box_flight
    plane_m_s = run.vehicle.airspeed_m_s
    line = [x for x in CliServer(run.flight).cmd_status() if x.startswith("Sensors:")][0]
    shown = float(line.split("; airspeed ")[1].split(" m/s")[0])
    assert abs(shown - plane_m_s) < 1.5  # one 50 Hz sample of noise (0.3 m/s) and of flight ago


def test_log_report_plots_the_airspeed_for_a_plane(box_flight):
    _, _, log, d = box_flight
    out = write_report(log, str(d / "report"))
    assert any(p.endswith("airspeed.png") for p in out["plots"])
    assert (d / "report" / "airspeed.png").stat().st_size > 10000
    assert "Airspeed against pitch and throttle" in (d / "report" / "index.html").read_text()


def test_a_quad_has_no_pitot_so_its_log_has_no_airspeed_and_no_plot(tmp_path):
    path = str(tmp_path / "hover.ulg")
    run = SimRun("5inch", "hover", seed=1, duration_s=2.0, log_path=path)
    run.run()
    assert not run.flight.signals.airspeed_valid
    log = load(path)
    a = log.topic("airspeed")
    assert a is None or len(a["t_s"]) == 0
    out = write_report(log, str(tmp_path / "report"))
    assert not any(p.endswith("airspeed.png") for p in out["plots"])
    assert "airspeed" not in "\n".join(CliServer(run.flight).cmd_status())


def _crsf_frames(data, frame_type):
    """Payloads of the CRSF frames of `frame_type` in the bytes the flight controller sent its receiver."""
    out = []
    i = 0
    while i + 2 < len(data):
        n = data[i + 1]
        if data[i] == 0xC8 and 2 <= n <= 62 and i + 2 + n <= len(data):
            if data[i + 2] == frame_type:
                out.append(bytes(data[i + 3:i + 1 + n]))
            i += 2 + n
        else:
            i += 1
    return out


def test_crsf_telemetry_sends_the_planes_airspeed_in_tenths_of_km_h(box_flight):
    run, _, _, _ = box_flight
    frames = _crsf_frames(run.board.telemetry_out, 0x0A)
    assert len(frames) >= 20  # the last 64 KiB of telemetry: a few seconds of the cruise
    last_m_s = [int.from_bytes(p[:2], "big") / 36.0 for p in frames[-20:]]
    # the box's last leg cruises at 23-25 m/s (the log's plot); the pitot's noise is 0.3 m/s
    assert all(20.0 < v < 28.0 for v in last_m_s)
    assert abs(last_m_s[-1] - run.vehicle.airspeed_m_s) < 2.0
