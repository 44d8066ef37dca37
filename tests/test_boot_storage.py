"""Boot always comes up (issue 30): a stored record with a valid CRC whose entries fail the parameter
check (inf for an integer, NaN, out of range, an unknown name, a choice that does not exist, mixer_type =
hexx saved on a quad) loses only that entry: it is skipped and reported (Storage.skipped_names and
skip_reasons, the built-in test's params flag, CLI status, the `hoverfly sim` start line), the rest of
the set loads, and a bad reboot parameter keeps the craft's value."""

import json
import math
import struct

import pytest
from configfakes import make_flight

from hoverfly.core.config.params import Params
from hoverfly.core.config.storage import FORMAT, HEADER_BYTES, LOADED, MAGIC, MemoryStorageBoard, Storage, crc32
from hoverfly.core.links.cliserver import CliServer
from hoverfly.core.safety.bit import BIT_PARAMS
from hoverfly.sim.server import SimServer
from test_micropython import MICROPYTHON, run_micropython


def record(entries, seq=1):
    """A record in storage's byte format (core/config/storage.py) holding exactly `entries`, typed by the
    Python value ('i' int, 'f' float, 's' text), with a good CRC: what a checked save never writes."""
    parts = []
    for name, v in entries:
        nb = name.encode()
        if isinstance(v, str):
            tb = v.encode()
            parts.append(struct.pack("<B", len(nb)) + nb + b"s" + struct.pack("<B", len(tb)) + tb)
        elif isinstance(v, float):
            parts.append(struct.pack("<B", len(nb)) + nb + b"f" + struct.pack("<d", v))
        else:
            parts.append(struct.pack("<B", len(nb)) + nb + b"i" + struct.pack("<i", v))
    payload = b"".join(parts)
    head = bytearray(HEADER_BYTES)
    head[0:4] = MAGIC
    struct.pack_into("<BBHII", head, 4, FORMAT, 0, len(entries), seq, len(payload))
    body = bytes(head) + payload
    return body + struct.pack("<I", crc32(body))


# (entry, the parameter it targets): each alone makes the record hostile
HOSTILE = [
    (("p_roll", math.inf), "p_roll"),  # inf for an integer parameter
    (("d_roll", math.nan), "d_roll"),
    (("loop_hz", 1e308), "loop_hz"),  # a reboot parameter: falls back
    (("motor_idle_pct", -math.inf), "motor_idle_pct"),
    (("p_roll", 400), "p_roll"),  # out of range
    (("loop_hz", 2 ** 31 - 1), "loop_hz"),
    (("mixer_type", "hexx"), "mixer_type"),  # in the table, but 6 motors on a 4-motor board
    (("mixer_type", "octo_nope"), "mixer_type"),
    (("fs_procedure", "x" * 200), "fs_procedure"),
    (("rx_provider", 99), "rx_provider"),
    (("rc_map", 11111111), "rc_map"),
    (("no_such_param", 5), "no_such_param"),  # unknown name (a retired row)
]
GOOD = [("p_pitch", 77), ("motor_idle_pct", 7.5), ("fs_procedure", "drop")]


class QuadStore(MemoryStorageBoard):
    motor_count = 4  # the board's motor outputs (SimBoard and Rp2Board say so too)


@pytest.mark.parametrize("bad,target", HOSTILE, ids=[h[0][0] + "=" + repr(h[0][1])[:12] for h in HOSTILE])
def test_a_hostile_entry_is_skipped_and_the_rest_of_the_set_loads(bad, target):
    entries = [e for e in GOOD if e[0] != bad[0]] + [bad]
    p = Params()
    st = Storage(QuadStore(record(entries)))
    assert st.load(p) == LOADED and not st.failed
    assert st.skipped == 1 and st.skipped_names == [target]
    assert len(st.skip_reasons) == 1 and "\n" not in st.skip_reasons[0] and target in st.skip_reasons[0]
    assert p.load_skipped == [target]
    defaults = Params()
    if target in defaults.values:
        assert p.get(target) == defaults.get(target)  # the skipped one keeps the value it had
    for name, v in entries[:-1]:
        assert p.get(name) == v  # the rest loads
    assert "1 stored value skipped" in st.summary()


def test_a_hostile_record_in_a_flight_boot_sets_the_params_flag_and_status_shows_it():
    f, board = make_flight(seams=False)  # a booted flight; now reboot it on a hostile store
    board.store.image = record(GOOD + [("p_roll", math.inf), ("mixer_type", "hexx")])
    board.motor_count = 4
    p = Params()
    st = Storage(board)
    st.load(p)
    f2 = type(f)(board, p)
    f2.start(board.now_us())
    t = board.now_us()
    for _ in range(50):
        t += 1000
        board.t_us = t
        f2.step(t)
    assert f2.bit.flags & (1 << BIT_PARAMS) and "params" in f2.bit.names()
    assert any("skipped at boot" in s for s in f2.bit.sentences())
    cli = CliServer(f2, st)
    cli.enter(lambda b: None)
    out = []
    cli.feed(b"status\r", 7, out.append)
    text = b"".join(out).decode()
    assert "Parameters: 2 stored value(s) skipped at boot" in text and "mixer_type = hexx drives 6 motors" in text
    assert "params" in text  # the built-in test line names the check
    assert p.get("mixer_type") == "quadx" and p.get("p_pitch") == 77


def test_a_clean_boot_leaves_the_params_flag_clear():
    f, board = make_flight(seams=False)
    t = board.now_us()
    for _ in range(50):
        t += 1000
        board.t_us = t
        f.step(t)
    assert not f.bit.flags & (1 << BIT_PARAMS)


@pytest.mark.parametrize("bad,target", HOSTILE, ids=[h[0][0] + "=" + repr(h[0][1])[:12] for h in HOSTILE])
def test_hoverfly_sim_boots_from_a_hostile_store_and_says_what_it_skipped(tmp_path, bad, target):
    path = tmp_path / "params.bin"
    path.write_bytes(record(GOOD + [bad]))
    sim = SimServer("5inch", msp_port=0, maint_port=0, storage_path=str(path), duration_s=0.05)
    try:
        line = sim.describe()
        assert "1 stored value skipped" in line and target in line and "\n" not in line
        assert sim.storage.skipped_names == [target]
        assert sim.run.params.get("p_pitch") == 77
        assert sim.run.params.get("mixer_type") == "quadx"
        sim.run.realtime = False
        result = sim.serve()  # and it flies its passes
    finally:
        sim.ports.close()
    assert result is not None and not result["crashed"]


@pytest.mark.skipif(MICROPYTHON is None, reason="micropython not installed")
def test_portable_storage_load_skips_hostile_entries_under_micropython():
    images = [list(record(GOOD + [bad])) for bad, _ in HOSTILE]
    code = """
import json
from hoverfly.core.config.params import Params
from hoverfly.core.config.storage import Storage, MemoryStorageBoard
class B(MemoryStorageBoard):
    motor_count = 4
out = []
for img in %s:
    p = Params()
    st = Storage(B(bytes(img)))
    status = st.load(p)
    out.append([status, st.skipped, st.skipped_names, p.get("p_pitch"), p.get("mixer_type"), p.get("loop_hz")])
print(json.dumps(out))
""" % json.dumps(images)
    res = run_micropython(code, heap="2m")
    assert res.returncode == 0, res.stdout[-2000:] + res.stderr[-2000:]
    got = json.loads(res.stdout.strip().splitlines()[-1])
    for (bad, target), (status, skipped, names, p_pitch, mixer, loop_hz) in zip(HOSTILE, got, strict=True):
        assert (status, skipped, names) == (LOADED, 1, [target]), bad
        assert (p_pitch, mixer, loop_hz) == (77, "quadx", 1000), bad
