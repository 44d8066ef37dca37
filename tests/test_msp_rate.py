"""MSP at the companion's rate (seed 004, issue 25), the 2-second version of bench/msp_rate.py: 400 Hz
SET_RAW_RC plus MSP_ATTITUDE and MSP_RAW_IMU polled at 400 Hz each, over TCP on 127.0.0.1 to an
in-process `hoverfly sim`; every RC frame reaches the controller in order (a sequence number in AUX4)
and is taken by the enabled autopilot, every poll is answered, in order, none dropped."""

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bench"))
import msp_rate  # noqa: E402


@pytest.mark.parametrize("serial_hz", [2000, 100])
def test_400_hz_rc_and_400_hz_polling_lose_nothing(serial_hz):
    r = msp_rate.measure(seconds=2.0, rc_hz=400, poll_hz=400, serial_hz=serial_hz, settle_s=0.3)
    assert r["autopilot_enabled"]
    assert r["rc_sent"] == 800 and r["rc_taken"] == r["rc_sent"] and r["rc_in_order"]
    assert r["rc_accepted"] == r["rc_sent"]
    assert r["polls_sent"] == 1600 and r["polls_answered"] == r["polls_sent"]
    assert r["replies_in_order"] and r["error_replies"] == 0
    assert r["frames_dropped"] == 0 and r["reply_bytes_dropped"] == 0
    # the links task answers within a run or two (10 ms at Betaflight's 100 Hz); a loaded machine's
    # scheduling comes on top (the figures are bench/msp_rate.py's)
    assert r["latency_ms_p50"] < (10.0 if serial_hz >= 1000 else 25.0), r
