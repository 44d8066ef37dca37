"""The simulator's shortcuts change no flight: the same seed flown with them on and off gives the same result."""

import pytest

from hoverfly.sim import esc
from hoverfly.sim.runner import fly


def _flight(scenario, seed, **kw):
    r = fly(scenario, "5inch", seed=seed, duration_s=5.0, **kw)
    for k in ("wall_time_s", "realtime_factor", "loop"):
        r.pop(k)
    return r


@pytest.mark.parametrize("scenario,seed,kw", [
    ("hover", 1, {}),
    ("flip", 2, {"esc": "dshot300"}),
    ("rx-loss", 3, {}),
    ("hover", 4, {"overrides": [("dshot_bidir", 1)]}),
])
def test_the_esc_word_cache_changes_no_flight(monkeypatch, scenario, seed, kw):
    monkeypatch.setattr(esc, "WORD_CACHE", False)
    decoded = _flight(scenario, seed, **kw)
    monkeypatch.setattr(esc, "WORD_CACHE", True)
    esc._THROTTLE_FRAMES.clear()
    cached = _flight(scenario, seed, **kw)
    assert esc._THROTTLE_FRAMES  # the cache was used
    assert cached == decoded


def test_a_cached_word_is_decoded_as_the_esc_decodes_it():
    """Every throttle word, both CRC kinds: what the cache hands back is what the decode gives."""
    from hoverfly.protocols.dshot import THROTTLE_MIN

    def word(value, bidir):
        w = value << 1
        c = w ^ (w >> 4) ^ (w >> 8)
        if bidir:
            c = ~c
        return (w << 4) | (c & 0xF)

    for bidir in (False, True):
        for value in range(THROTTLE_MIN, 2048, 7):
            w = word(value, bidir)
            plain = esc.SimEsc()
            esc.WORD_CACHE, saved = False, esc.WORD_CACHE
            try:
                t_plain = plain.receive_word(w)
            finally:
                esc.WORD_CACHE = saved
            first = esc.SimEsc()
            first.receive_word(w)  # fills the cache
            again = esc.SimEsc()
            assert again.receive_word(w) == t_plain
            assert (again.bidir, again.frames, again.errors) == (plain.bidir, plain.frames, plain.errors)
