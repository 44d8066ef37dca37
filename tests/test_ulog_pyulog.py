"""ULog writer read back by pyulog (an independent reader); the reader wrapper on cut and corrupted files."""

import random
import struct

import numpy as np
import pytest

from hoverfly.logs.ulogread import LogReadError, open_ulog, read_summary
from hoverfly.protocols.ulog import UlogWriter

START_US = 1_000_000
STEP_US = 1000


class RecordingSink:
    """The whole file in memory, plus where each message ends (the writer writes one message per call)."""

    def __init__(self):
        self.data = bytearray()
        self.messages = []  # (end offset, message bytes)

    def write(self, data):
        self.data += data
        self.messages.append((len(self.data), bytes(data)))
        return len(data)


FORMATS = {
    "vehicle_attitude": (
        ("uint64_t", "timestamp"),
        ("float[4]", "q"),
        ("float[4]", "delta_q_reset"),
        ("uint8_t", "quat_reset_counter"),
        ("uint8_t[7]", "_padding0"),
    ),
    "vehicle_angular_velocity": (
        ("uint64_t", "timestamp"),
        ("uint64_t", "timestamp_sample"),
        ("float[3]", "xyz"),
    ),
    "actuator_outputs": (("uint64_t", "timestamp"), ("uint32_t", "noutputs"), ("float[16]", "output")),
    "hoverfly_loop": (
        ("uint64_t", "timestamp"),
        ("uint16_t", "loop_us"),
        ("uint32_t", "overruns"),
        ("float", "cpu_pct"),
        ("bool", "armed"),
        ("int8_t", "mode"),
    ),
}


def _att(i):
    return (1.0, (i % 97) * 0.125, -(i % 13) * 0.5, 0.25, 0.0, 0.0, 0.0, 1.0, i % 256)


def _rate(i, t):
    return (t - 250, (i % 31) * 0.25, -(i % 7) * 0.5, 2.0)


def _act(i, inst):
    return (4,) + tuple(((i + k + inst) % 64) * 0.015625 for k in range(16))


def _loop(i):
    return (200 + i % 50, i // 100, (i % 100) * 0.5, i > 100, (i % 5) - 2)


def build_log(n_loops=2500):
    """n_loops x 4 samples: 10 000 samples for the default."""
    sink = RecordingSink()
    w = UlogWriter(sink, START_US)
    for name, fields in FORMATS.items():
        assert w.add_format(name, fields)
    assert w.add_info("char[8] sys_name", "hoverfly")
    assert w.add_info("char[5] ver_sw", "0.1.0")
    assert w.add_info("uint32_t ver_sw_release", 0x000100FF)
    assert w.add_param("p_roll", 45)
    assert w.add_param("gyro_lpf_hz", 100.5)
    ids = {
        "att": w.subscribe("vehicle_attitude"),
        "rate": w.subscribe("vehicle_angular_velocity"),
        "act0": w.subscribe("actuator_outputs", 0),
        "act1": w.subscribe("actuator_outputs", 1),
        "loop": w.subscribe("hoverfly_loop"),
    }
    expected = {k: [] for k in ids}
    logs = []
    syncs = 0
    for i in range(n_loops):
        t = START_US + i * STEP_US
        if w.maybe_sync(t):
            syncs += 1
        for key, values in (("att", _att(i)), ("rate", _rate(i, t)), ("loop", _loop(i))):
            assert w.write_data(ids[key], t, values)
            expected[key].append((t,) + values)
        inst = i & 1
        key = "act%d" % inst
        assert w.write_data(ids[key], t, _act(i, inst))
        expected[key].append((t,) + _act(i, inst))
        if i % 500 == 7:
            text = "loop %d" % i
            assert w.log_message(6, t, text)
            logs.append((t, text))
        if i == 1000:
            assert w.param_change("p_roll", 50, t)
    assert w.refused == 0 and w.clamped_timestamps == 0
    return bytes(sink.data), sink.messages, ids, expected, logs, syncs


@pytest.fixture(scope="module")
def full_log():
    return build_log()


def _write(tmp_path, data, name="log.ulg"):
    p = tmp_path / name
    p.write_bytes(data)
    return p


def _columns(d, fields):
    """pyulog's flattened columns for our field list (arrays expanded, padding dropped)."""
    cols = []
    for type_str, name in fields:
        if name.startswith("_padding"):
            continue
        if "[" in type_str:
            n = int(type_str[type_str.index("[") + 1 : -1])
            cols += [d.data["%s[%d]" % (name, k)] for k in range(n)]
        else:
            cols.append(d.data[name])
    return cols


def test_pyulog_reads_every_sample_exactly(full_log, tmp_path):
    data, _, ids, expected, logs, syncs = full_log
    ulog, warnings = open_ulog(_write(tmp_path, data))
    assert warnings == []
    assert ulog.file_corruption is False
    assert sum(len(v) for v in expected.values()) == 10_000
    topics = {(d.name, d.multi_id): d for d in ulog.data_list}
    where = {
        "att": ("vehicle_attitude", 0),
        "rate": ("vehicle_angular_velocity", 0),
        "act0": ("actuator_outputs", 0),
        "act1": ("actuator_outputs", 1),
        "loop": ("hoverfly_loop", 0),
    }
    assert set(topics) == set(where.values())
    for key, (name, multi_id) in where.items():
        d = topics[(name, multi_id)]
        assert d.msg_id == ids[key]
        cols = _columns(d, FORMATS[name])
        want = np.array(expected[key], dtype=np.float64)
        assert len(cols[0]) == len(want)
        for c in range(want.shape[1]):
            got = cols[c].astype(np.float64)
            assert np.array_equal(got, want[:, c]), (name, multi_id, c)
    assert ulog.start_timestamp == START_US
    assert ulog.msg_info_dict["sys_name"] == "hoverfly"
    assert ulog.msg_info_dict["ver_sw"] == "0.1.0"
    assert ulog.msg_info_dict["ver_sw_release"] == 0x000100FF
    assert ulog.initial_parameters == {"p_roll": 45, "gyro_lpf_hz": 100.5}
    assert ulog.changed_parameters == [(START_US + 1000 * STEP_US, "p_roll", 50)]
    assert [(m.timestamp, m.message, m.log_level) for m in ulog.logged_messages] == [
        (t, text, ord("6")) for t, text in logs
    ]
    assert ulog._sync_seq_cnt == syncs == 3


def test_summary_lists_topics_rates_params_and_duration(full_log, tmp_path):
    data = full_log[0]
    s = read_summary(_write(tmp_path, data))
    assert s["file_corruption"] is False and s["warnings"] == []
    by = {(t["name"], t["multi_id"]): t for t in s["topics"]}
    assert by[("vehicle_attitude", 0)]["samples"] == 2500
    assert by[("vehicle_attitude", 0)]["rate_hz"] == pytest.approx(1000.0)
    assert by[("actuator_outputs", 1)]["samples"] == 1250
    assert by[("actuator_outputs", 1)]["rate_hz"] == pytest.approx(500.0)
    assert "q[3]" in by[("vehicle_attitude", 0)]["fields"]
    assert s["duration_s"] == pytest.approx(2.499)
    assert s["params"]["p_roll"] == 45 and s["changed_params"][0][1:] == ("p_roll", 50)
    assert s["messages"][0] == {"timestamp_us": START_US + 7 * STEP_US, "level": "info", "text": "loop 7"}
    assert s["info"]["sys_name"] == "hoverfly"


def _expected_before(messages, cut):
    """What pyulog must show from the messages wholly before `cut`."""
    d_counts = {}
    n_log = 0
    n_changes = 0
    params = {}
    info = {}
    in_data = False
    for end, m in messages:
        if end > cut:
            break
        kind = m[2]
        if kind == ord("D"):
            mid = struct.unpack_from("<H", m, 3)[0]
            d_counts[mid] = d_counts.get(mid, 0) + 1
        elif kind in (ord("A"), ord("L")):
            in_data = True
            n_log += kind == ord("L")
        elif kind == ord("P"):
            klen = m[3]
            name = m[4 : 4 + klen].decode().split(" ")[1]
            if in_data:
                n_changes += 1
            else:
                params[name] = True
        elif kind == ord("I"):
            klen = m[3]
            info[m[4 : 4 + klen].decode().split(" ")[1]] = True
    return d_counts, n_log, n_changes, params, info


def _check_cut(path, messages, cut):
    if cut < 16:
        with pytest.raises(LogReadError):
            read_summary(path)
        return
    s = read_summary(path)
    ulog, _ = open_ulog(path)
    d_counts, n_log, n_changes, params, info = _expected_before(messages, cut)
    got = {d.msg_id: len(d.data["timestamp"]) for d in ulog.data_list}
    assert got == d_counts, cut
    assert len(s["messages"]) == n_log, cut
    assert len(s["changed_params"]) == n_changes, cut
    assert set(params) <= set(s["params"]), cut
    assert set(info) <= set(s["info"]), cut


def test_file_cut_at_every_offset_of_the_first_2kb_keeps_what_came_before(full_log, tmp_path):
    data, messages = full_log[0], full_log[1]
    p = tmp_path / "cut.ulg"
    for cut in range(0, 2048):
        p.write_bytes(data[:cut])
        _check_cut(p, messages, cut)


def test_file_cut_later_keeps_what_came_before(full_log, tmp_path):
    data, messages = full_log[0], full_log[1]
    rng = random.Random(8)
    p = tmp_path / "cut.ulg"
    cuts = sorted(rng.sample(range(2048, len(data)), 40)) + [len(data) - 1, len(data) - 17]
    for cut in cuts:
        p.write_bytes(data[:cut])
        _check_cut(p, messages, cut)


@pytest.fixture(scope="module")
def small_log():
    return build_log(150)[0]


def test_flipped_bytes_never_raise_anything_but_log_read_error(small_log, tmp_path):
    rng = random.Random(1234)
    p = tmp_path / "flip.ulg"
    outcomes = {"summary": 0, "error": 0}
    for trial in range(400):
        data = bytearray(small_log)
        # half the trials aim at the header and Definitions, where a flip does most harm
        span = 1200 if trial % 2 else len(data)
        for _ in range(rng.randint(1, 12)):
            data[rng.randrange(span)] = rng.randrange(256)
        if trial % 3 == 0:
            data = data[: rng.randrange(len(data))]
        p.write_bytes(bytes(data))
        try:
            s = read_summary(p)
            assert isinstance(s["topics"], list)
            outcomes["summary"] += 1
        except LogReadError as exc:
            assert "\n" not in str(exc)
            outcomes["error"] += 1
    assert outcomes["summary"] > 100


@pytest.mark.parametrize(
    "content",
    [
        b"",
        b"ULog\x01\x12",
        b"\x00" * 64,
        b"GIF89a" + bytes(100),
        b"ULog\x01\x12\x35\x01"
        + bytes(8)
        + b"\x28\x00\x42"
        + bytes(8)
        + b"\x02"
        + bytes(31),  # unknown incompat bit
    ],
    ids=["empty", "short", "zeros", "gif", "incompat"],
)
def test_non_ulog_files_raise_one_line_log_read_error(tmp_path, content):
    p = _write(tmp_path, content)
    with pytest.raises(LogReadError) as err:
        read_summary(p)
    assert str(p) in str(err.value) and "\n" not in str(err.value)


def test_missing_file_and_directory_raise_log_read_error(tmp_path):
    with pytest.raises(LogReadError, match="cannot open"):
        read_summary(tmp_path / "nope.ulg")
    with pytest.raises(LogReadError):
        read_summary(tmp_path)


def test_pyulog_warnings_are_captured_not_printed(tmp_path, capsys):
    data = bytearray(build_log(50)[0])
    # an unsubscribed msg_id in a D message: pyulog prints a warning and flags corruption
    data += struct.pack("<HBH", 6, ord("D"), 999) + bytes(4)
    s = read_summary(_write(tmp_path, bytes(data)))
    assert capsys.readouterr().out == ""
    assert s["file_corruption"] is True
    assert any("999" in w for w in s["warnings"])


def test_log_read_error_is_a_user_error():
    from hoverfly.errors import UserError

    assert issubclass(LogReadError, UserError)


def test_nested_char_and_mid_padding_fields_read_back(tmp_path):
    sink = RecordingSink()
    w = UlogWriter(sink, 0)
    assert w.add_format("vec3", (("uint64_t", "timestamp"), ("float[3]", "v")))
    assert w.add_format(
        "mixed",
        (
            ("uint8_t", "a"),
            ("uint8_t[3]", "_padding0"),
            ("uint64_t", "timestamp"),
            ("vec3[2]", "acc"),
            ("char[4]", "mode"),
            ("double", "d"),
        ),
    )
    m = w.subscribe("mixed")
    for i in range(5):
        assert w.write_data(m, 100 + i, (i, 7, 1.0, 2.0, 3.0, 8, -1.0, -2.0, -3.5, b"ACRO", i * 0.1))
    ulog, warnings = open_ulog(_write(tmp_path, bytes(sink.data)))
    assert warnings == [] and not ulog.file_corruption
    d = ulog.data_list[0].data
    assert list(d["timestamp"]) == [100, 101, 102, 103, 104]
    assert list(d["a"]) == [0, 1, 2, 3, 4]
    assert list(d["acc[1].v[2]"]) == [-3.5] * 5 and list(d["acc[0].timestamp"]) == [7] * 5
    assert bytes(int(d["mode[%d]" % k][0]) for k in range(4)) == b"ACRO"
    assert list(d["d"]) == [i * 0.1 for i in range(5)]
