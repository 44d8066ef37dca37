"""The flight-log reader always ends: any bytes give a result or one LogReadError, in bounded work.

Given a short log written by the simulator, when it is mutated (bits flipped, bytes inserted,
deleted, overwritten with 0xFF 0xFF sizes, NaN/inf floats, cut) or replaced by hostile
structures (garbage runs, nested formats that flatten exponentially, thousands of wide
subscriptions, a corrupt header at the end of the definitions that claims more than is left),
then the reader gives a summary or a LogReadError, the reads and seeks pyulog makes stay within
a small multiple of the file's size, and where pyulog alone ends it reads the same as ours.
pyulog 1.3 alone hung on 46 of 37 505 mutated logs (issue 30).
"""

import os
import signal
import struct

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from pyulog import ULog

import hoverfly.logs.ulogread as ulogread
from hoverfly.cli import main
from hoverfly.logs.data import load
from hoverfly.logs.ulogread import LogReadError, open_ulog, read_summary
from hoverfly.sim.runner import fly

# The reads and seeks pyulog may make per byte of a damaged file before the reader stops it
# (a byte-by-byte walk through damage takes about 3; the reader's own cut-off is 16).
WALK_CALLS_PER_BYTE = 4
HANG_S = 60  # a hang detector on a busy machine, not a timing


class _Hang(BaseException):
    """Raised by the alarm: a BaseException, so no `except Exception` in a reader swallows it."""


def _alarm(*_):
    raise _Hang()


@pytest.fixture(scope="module")
def sim_log(tmp_path_factory):
    path = tmp_path_factory.mktemp("fuzzlog") / "hover.ulg"
    fly("hover", "5inch", seed=3, duration_s=0.3, log_path=str(path))
    return path.read_bytes()


@pytest.fixture
def calls(monkeypatch):
    """The _BoundedFile of each read, to see how much work pyulog did."""
    made = []
    real = ulogread._BoundedFile

    def counting(data, budget):
        f = real(data, budget)
        made.append(f)
        return f

    monkeypatch.setattr(ulogread, "_BoundedFile", counting)
    return made


def _read_within_bounds(path, made, size):
    old = signal.signal(signal.SIGALRM, _alarm)
    signal.alarm(HANG_S)
    try:
        try:
            s = read_summary(str(path))
        except LogReadError as exc:
            s = None
            assert "\n" not in str(exc)
    except _Hang:
        pytest.fail("the reader did not end within %d s on a %d-byte file" % (HANG_S, size))
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)
    if made:
        assert made[-1].calls <= WALK_CALLS_PER_BYTE * size + 64, (made[-1].calls, size)
    return s


def _msg(kind, payload):
    return struct.pack("<HB", len(payload), ord(kind)) + payload


@st.composite
def _mutated(draw, data):
    d = bytearray(data)
    for _ in range(draw(st.integers(1, 10))):
        op = draw(st.sampled_from(("flip", "insert", "delete", "size", "bytes", "float")))
        p = draw(st.integers(0, len(d) - 1)) if d else 0
        if op == "flip" and d:
            d[p] ^= 1 << draw(st.integers(0, 7))
        elif op == "insert":
            d[p:p] = draw(st.binary(min_size=1, max_size=6))
        elif op == "delete":
            del d[p : p + draw(st.integers(1, 6))]
        elif op == "size" and len(d) > p + 1:  # a header claiming a huge message
            d[p : p + 2] = draw(st.sampled_from((b"\xff\xff", b"\x00\x00", b"\x10\x27", b"\x11\x27")))
        elif op == "bytes":
            d[p : p + 8] = draw(st.binary(min_size=8, max_size=8))
        elif op == "float" and len(d) > p + 4:
            d[p : p + 4] = draw(st.sampled_from((struct.pack("<f", float("nan")), struct.pack("<f", float("inf")),
                                                 struct.pack("<f", -3.4e38))))
    if draw(st.booleans()):
        d = d[: draw(st.integers(0, len(d)))]
    return bytes(d)


@settings(max_examples=120, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture,
                                                                   HealthCheck.too_slow])
@given(data=st.data())
def test_any_mutation_of_a_log_reads_or_fails_in_one_line_within_bounded_work(sim_log, tmp_path, calls, data):
    m = data.draw(_mutated(sim_log))
    path = tmp_path / "m.ulg"
    path.write_bytes(m)
    s = _read_within_bounds(path, calls, len(m))
    if s is not None:
        assert isinstance(s["topics"], list) and isinstance(s["warnings"], list)
        assert len(s["warnings"]) <= ulogread.MAX_WARNINGS + 3
    # Where pyulog alone ends (it hangs on some) and the reader never used a position past the end (where a
    # plain file stops at the end: the hang's fix), it read exactly what the bounded reader read.
    if s is not None and calls and calls[-1].stopped_at < 0 and not calls[-1].past_end_used:
        old = signal.signal(signal.SIGALRM, _alarm)
        signal.alarm(5)
        try:
            import contextlib
            import io

            with contextlib.redirect_stdout(io.StringIO()):
                plain = ULog(str(path), None, disable_str_exceptions=True)
        except _Hang:
            return
        except Exception:  # noqa: BLE001 - pyulog alone raising is not what this compares
            return
        finally:
            signal.alarm(0)
            signal.signal(signal.SIGALRM, old)
        ours, _ = open_ulog(path)
        assert ours == plain


def _definitions(sim_log):
    """The header, flag bits and every definition message of the log (up to the first 'A')."""
    off = 16
    while True:
        size = sim_log[off] | (sim_log[off + 1] << 8)
        if sim_log[off + 2] == ord("A"):
            return sim_log[:off]
        off += 3 + size


def _claims_past_the_end(defs):
    """The definitions, then a corrupt header (type 0) claiming more than the 100 bytes left: as
    big that pyulog's seek back from the short read lands on the last definition, then walks
    forward to the same header again."""
    off = 16
    last = off
    while off < len(defs):
        last = off
        off += 3 + (defs[off] | (defs[off + 1] << 8))
    size = len(defs) + 101 - last
    return defs + struct.pack("<HB", size, 0) + bytes(range(100))


def _hostile(sim_log):
    defs = _definitions(sim_log)
    head = sim_log[: 16 + 43]
    data = sim_log[len(defs):]
    nest = _msg("F", b"a:uint64_t timestamp;float[65535] x;") + _msg("F", b"b:uint64_t timestamp;a[65535] y;")
    deep = b"".join(_msg("F", b"f%d:uint64_t timestamp;f%d x;" % (i, i + 1)) for i in range(600))
    return {
        # pyulog's hang: a corrupt header (type 0) at the end of the definitions claims more
        # than is left; its seek back from the short read landed before the header, forever
        "corrupt_header_claims_past_the_end": _claims_past_the_end(defs),
        "ff_run_inside_the_data": defs + data[:3000] + b"\xff" * 200000 + data[3000:],
        "zeros_after_the_flag_bits": head + bytes(300000),
        "formats_nested_to_4e9_values": head + nest + b"".join(
            _msg("A", struct.pack("<BH", 0, i) + b"b") for i in range(300)),
        "thousands_of_wide_subscriptions": head + _msg("F", b"a:uint64_t timestamp;float[16383] x;") + b"".join(
            _msg("A", struct.pack("<BH", i % 256, i) + b"a") for i in range(3000)),
        "format_inside_itself": head + _msg("F", b"a:uint64_t timestamp;a x;") + _msg("A", b"\x00\x00\x00a"),
        "formats_nested_600_deep": head + deep + _msg("F", b"f600:uint64_t timestamp;") + _msg("A", b"\x00\x00\x00f0"),
        "only_the_magic": sim_log[:7],
        "empty": b"",
    }


@pytest.mark.parametrize("case", ["corrupt_header_claims_past_the_end", "ff_run_inside_the_data",
                                  "zeros_after_the_flag_bits", "formats_nested_to_4e9_values",
                                  "thousands_of_wide_subscriptions", "format_inside_itself",
                                  "formats_nested_600_deep", "only_the_magic", "empty"])
def test_hostile_logs_end_with_a_result_or_one_error_line(sim_log, tmp_path, calls, case):
    m = _hostile(sim_log)[case]
    path = tmp_path / (case + ".ulg")
    path.write_bytes(m)
    s = _read_within_bounds(path, calls, len(m))
    if case == "ff_run_inside_the_data":
        # what came before the damage is kept, and the damage is said (how much of what follows
        # pyulog's recovery finds again is its own: a false header can skip up to 64 KB)
        before = read_summary(_write(tmp_path, _definitions(sim_log) + sim_log[len(_definitions(sim_log)):][:3000]))
        want = {t["name"]: t["samples"] for t in before["topics"]}
        got = {t["name"]: t["samples"] for t in s["topics"]}
        assert want and all(got.get(k, 0) >= n for k, n in want.items()), (got, want)
        assert s["file_corruption"]
    elif case in ("only_the_magic", "empty"):
        assert s is None


def _write(tmp_path, data, name="good.ulg"):
    p = tmp_path / name
    p.write_bytes(data)
    return p


def test_a_good_log_reads_exactly_as_pyulog_reads_it(sim_log, tmp_path, calls):
    path = _write(tmp_path, sim_log)
    ours, warnings = open_ulog(path)
    assert ours == ULog(str(path))
    assert warnings == [] and calls[-1].stopped_at < 0
    assert calls[-1].calls <= len(sim_log)  # a clean log: a read per header and one per payload


def test_a_good_log_cut_anywhere_reads_as_pyulog_reads_it(sim_log, tmp_path):
    for cut in (17, 60, 500, len(_definitions(sim_log)) + 1, len(sim_log) // 2 + 3, len(sim_log) - 1):
        path = _write(tmp_path, sim_log[:cut], "cut.ulg")
        try:
            ours, _ = open_ulog(path)
        except LogReadError:
            with pytest.raises(Exception):  # noqa: B017 - pyulog's own error on a cut header
                ULog(str(path))
            continue
        assert ours == ULog(str(path)), cut


def test_every_log_command_ends_on_hostile_and_mutated_logs_without_a_traceback(sim_log, tmp_path, capsys):
    import random

    rng = random.Random(30)
    files = [_hostile(sim_log)[c] for c in ("corrupt_header_claims_past_the_end", "format_inside_itself")]
    for _ in range(3):
        d = bytearray(sim_log)
        for _ in range(8):
            d[rng.randrange(16, len(d))] = rng.randrange(256)
        files.append(bytes(d[: rng.randrange(len(d) // 2, len(d))]))
    path = tmp_path / "h.ulg"
    old = signal.signal(signal.SIGALRM, _alarm)
    try:
        for m in files:
            path.write_bytes(m)
            for cmd in ("info", "params", "csv", "report", "replay"):
                extra = ["--out", str(tmp_path / cmd)] if cmd in ("csv", "report", "replay") else []
                signal.alarm(HANG_S)
                try:
                    code = main(["log", cmd, str(path)] + extra)
                except _Hang:
                    pytest.fail("hoverfly log %s did not end" % cmd)
                finally:
                    signal.alarm(0)
                err = capsys.readouterr().err
                assert code in (0, 2), (cmd, err)
                assert "Traceback" not in err
                if code == 2:
                    assert err.count("error:") == 1
    finally:
        signal.signal(signal.SIGALRM, old)


def test_a_log_load_of_a_damaged_file_keeps_what_it_could_read(sim_log, tmp_path):
    d = _hostile(sim_log)["ff_run_inside_the_data"]
    log = load(_write(tmp_path, d, "ff.ulg"))
    assert log.is_hoverfly and log.topic("sensor_combined") is not None
    assert any("corruption" in w for w in log.warnings)


def test_topic_names_with_path_characters_stay_inside_the_csv_directory(sim_log, tmp_path, capsys):
    # the format name is the file's own text: '/' and '..' in it must not steer where files go
    evil = sim_log.replace(b"input_rc", b"in/../rc").replace(b"battery_status", b"../../../../up")
    path = _write(tmp_path, evil, "evil.ulg")
    out = tmp_path / "deep" / "csv"
    assert main(["log", "csv", str(path), "--out", str(out)]) == 0
    written = capsys.readouterr().out.split()
    assert written and all(os.path.dirname(p) == str(out) for p in written)
    assert sorted(os.listdir(tmp_path)) == ["deep", "evil.ulg"] and os.listdir(tmp_path / "deep") == ["csv"]
    assert any(p.endswith("_in____rc.csv") for p in written)


def test_an_output_directory_that_cannot_be_written_is_one_error_line(sim_log, tmp_path, capsys):
    path = _write(tmp_path, sim_log)
    blocker = tmp_path / "file"
    blocker.write_text("not a directory")
    for cmd in ("csv", "report"):
        assert main(["log", cmd, str(path), "--out", str(blocker / "out")]) == 2
        err = capsys.readouterr().err
        assert "cannot write to" in err and "Traceback" not in err and err.count("\n") == 1
