"""The fixed-point stick shaping (core/stages/rc.py `rc_pass`) stays inside 32-bit words, whatever it holds.

On the RP2040/RP2350 the viper twin (accel/rc.py, generated from `rc_pass`) computes in 32-bit machine
words that wrap silently; the twin test also runs on a 32-bit VM, but only on the values it draws. The
viper does the Python's split products step for step; here the Python runs on the extremes of every
coefficient and state (full-scale gains, rates at the clamp, sticks at opposite ends) with every
integer it computes checked: any intermediate at 2**31 or beyond raises.
"""

import itertools

from hoverfly.core.stages import rc
from hoverfly.core.stages.rc import CO_C, CO_E, CO_K, CO_SIZE, CO_T, S_S1, S_X, S_Y, ST_SIZE
from test_fixedrate_bounds import I32

_ONE20 = 1 << 20


def test_rc_pass_stays_in_32_bits_at_every_extreme():
    runs = 0
    for k, rate, expo in itertools.product((1, 9000, 32767, 32768), (0, 1, 0x3FFFFF), (0, 1, 32768, 65535, 65536)):
        for x, s1, y in itertools.product((-_ONE20, 0, _ONE20), repeat=3):
            co = [I32(0)] * CO_SIZE
            co[CO_K] = I32(k)
            for i in range(3):
                co[CO_C + i] = I32(rate)
                co[CO_T + i] = I32(rate)
                co[CO_E + i] = I32(expo)
            st = [I32(0)] * ST_SIZE
            for i in range(4):
                lo = 0 if i == 3 else -_ONE20
                st[S_X + i] = I32(max(lo, x))
                st[S_S1 + i] = I32(max(lo, s1))
                st[S_Y + i] = I32(max(lo, y))
            stick = [0.0] * 3
            out = [0.0] * 3
            for _ in range(3):
                rc.rc_pass(co, st, stick, out)
                for i in range(4):
                    assert -_ONE20 <= st[S_S1 + i] <= _ONE20 and -_ONE20 <= st[S_Y + i] <= _ONE20
                for i in range(3):
                    assert abs(out[i]) <= 2.0 * rate / 65536.0 + 1e-9
            runs += 1
    assert runs == 4 * 3 * 5 * 27


def test_the_split_products_equal_the_plain_ones():
    for a in (0, 1, 255, 256, 4097, 65535, 65536):
        for b in (0, 1, 255, 256, 30000, 65535, 65536):
            assert rc._mul16(a, b) == (a * b) >> 16
        for c in (0, 1, 2047, 2048, 123456, 0x3FFFFF):
            assert rc._mul_rate(a, c) == (a * c) >> 16
    for kk in (1, 9000, 32768):
        for x in (-_ONE20, -3, 0, 5, _ONE20):
            for y in (-_ONE20, -1, 0, 7, _ONE20):
                d = x - y
                want = y + ((kk * d + 16384) >> 15) if d else y
                if d and want == y:
                    want = y + (1 if d > 0 else -1)
                assert rc._step(kk, x, y) == want


def test_rc_frame_stays_in_32_bits_for_every_us_and_deadband():
    # rc_frame's one product (_stick_q: a * 2**21, a below the span 500 - deadband) on every µs an "H" channel
    # holds and every deadband the parameters allow (yaw_deadband up to 100)
    for db in range(0, 101):
        prev = -_ONE20
        for us in range(0, 65536, 7):
            q = rc._stick_q(I32(us), I32(db))
            assert prev <= q <= _ONE20  # and never turning back
            prev = q
