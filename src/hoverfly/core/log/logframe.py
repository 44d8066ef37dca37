"""The flight log's fast frame: its byte layout, and the pass record the signals can live in.

Takes nothing at run time; gives the layout of one logged pass (the D messages of the six fast
topics back to back, see core/log/logger.py) and `PassRecord`, one preallocated block of that
layout. Signals builds its logged arrays through `PassRecord.floats()`: where the runtime can
view a bytearray as floats (CPython's memoryview.cast) each array is a view into the block, so
the stages write their results straight into the frame and logging a pass is a few scalar
stores and one copy, as PX4's logger copies its uORB structs. Elsewhere (MicroPython has no
cast) `floats()` gives plain arrays and the logger packs the frame instead.
"""

import struct
from array import array

from hoverfly.core.stages.mixer import MAX_MOTORS

MAX_OUTPUTS = 16  # PX4 actuator_outputs.output[16]

# The packing of each fast topic's D payload after its 5-byte header, in FAST_TOPICS order
# (core/log/logger.py). An array signal goes in whole as its raw bytes ('Ns'): array('f') holds IEEE
# float32 in the host's order, little-endian on every target (x86, ARM, RP2040) as ULog is.
# Constant zero fields are 'x'.
FAST_PACK = (
    "Q16s17x",  # timestamp, q[4]; delta_q_reset and quat_reset_counter stay 0
    "QQ12s12x",  # timestamp, timestamp_sample, xyz[3]; xyz_derivative stays 0
    "QI%ds%dx" % (4 * MAX_MOTORS, 4 * (MAX_OUTPUTS - MAX_MOTORS)),  # timestamp, noutputs, output[]; rest 0
    "Q12sI4x12sI4x",  # timestamp, gyro_rad, gyro_integral_dt, accelerometer_m_s2, accelerometer_integral_dt
    "Q12s8xfB",  # timestamp, roll, pitch, yaw, thrust_body = (0, 0, -throttle), reset_integral
    "QfBBBB12s48s",  # timestamp, tpa, i_active, airmode, saturated, mode, sum[3] = torque_norm,
    # p[3] i[3] d[3] f[3] = pid_terms
)
# The rate setpoint's scalars end its message and hoverfly_pid's start the next one, so the scalars
# that change pass to pass are one run of the frame (with hoverfly_pid's header and timestamp
# between them): core/log/logger.py stores them with one pack a pass.
# The frame is a whole number of 8-byte words (344 bytes; hoverfly_pid's mode byte makes it so), so
# the staged frames' timestamps are one strided column per field: core/log/logger.py fills them once
# a batch instead of seven stores a pass. (Trailing `_padding` bytes would do the same, but pyulog
# 1.3 counts a message longer than its fields as corrupt.)
# The array fields ('s' above) in frame order: the signal each one logs, and its float count.
ARRAY_FIELDS = (("q", 4), ("gyro_rad_s", 3), ("motor_out", MAX_MOTORS), ("gyro_raw_rad_s", 3),
                ("accel_raw_m_s2", 3), ("rate_rad_s", 3), ("torque_norm", 3), ("pid_terms", 12))
HEADER_BYTES = 5  # ULog message header: uint16 size, uint8 'D', uint16 msg_id


def frame_format(gaps=False):
    """The whole frame's struct format (headers as '5s'); with gaps the arrays' bytes are
    skipped ('Nx') for a separate copy."""
    fmt = "<"
    for p in FAST_PACK:
        fmt += "5s" + (p.replace("s", "x") if gaps else p)
    return fmt


def _items():
    """(offset in the frame, code, count) of every field of the frame, pads included, in order;
    the headers as (offset, 'hdr', 5)."""
    items = []
    off = 0
    for p in FAST_PACK:
        items.append((off, "hdr", HEADER_BYTES))
        off += HEADER_BYTES
        count = ""
        for c in p:
            if "0" <= c <= "9":
                count += c
                continue
            n = int(count) if count else 1
            items.append((off, c, n))
            off += struct.calcsize("<%d%s" % (n, c))
            count = ""
    return items


def array_table():
    """(offset in the frame, byte count) of each array field, in frame order, as array('H')."""
    table = array("H")
    for off, c, n in _items():
        if c == "s":
            table.append(off)
            table.append(n)
    return table


def field_offsets(code):
    """(offset, count) of the fields packed with struct code `code` ('Q', 'f', ...), in frame
    order."""
    return [(off, n) for off, c, n in _items() if c == code]


def header_offsets():
    return [off for off, c, n in _items() if c == "hdr"]


FRAME_BYTES = struct.calcsize(frame_format())


def _can_view():
    try:
        memoryview(bytearray(8)).cast("f")
    except (AttributeError, TypeError, ValueError, NotImplementedError):
        return False
    return True


CAN_VIEW = _can_view()


class PassRecord:
    """One fast frame's bytes (`buf`), with the pass's logged arrays inside it where the runtime
    can view them (`backed`). `floats(name, init)` gives the array for ARRAY_FIELDS' `name`:
    a float view into `buf` when backed, else a plain array('f') of init's values."""

    def __init__(self):
        self.buf = bytearray(FRAME_BYTES)
        self.backed = CAN_VIEW
        table = array_table()
        self._offsets = {}
        for k in range(len(ARRAY_FIELDS)):
            self._offsets[ARRAY_FIELDS[k][0]] = (table[2 * k], ARRAY_FIELDS[k][1])
        self.views = {}

    def floats(self, name, init):
        off, n = self._offsets[name]
        if not self.backed:
            return array("f", init)
        v = memoryview(self.buf)[off : off + 4 * n].cast("f")
        for i in range(n):
            v[i] = init[i] if i < len(init) else 0.0
        self.views[name] = v
        return v

    def holds(self, name, arr):
        """True if `arr` is the view of `name` in this record (still the one the signals use)."""
        return self.backed and self.views.get(name) is arr

    def view(self, offset, code, count=1):
        """A `count`-element view of `code` at `offset` (CPython only: scalars the logger stores)."""
        size = struct.calcsize("<%d%s" % (count, code))
        return memoryview(self.buf)[offset : offset + size].cast(code)
