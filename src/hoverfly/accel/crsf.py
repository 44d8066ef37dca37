"""Viper twins of CRSF's per-frame byte loops (MicroPython only; chosen at import by protocols/crsf.py).

Takes the same arguments and gives the same results, byte for byte, as the pure-Python twins
it stands in for, which stay the reference and the fallback wherever viper is missing
(CPython, the wasm port) or fails to compile:

- `check_unpack11(src, p, raw, us, us_of_raw, crc_table)`: rxcodec.check_unpack11, the whole
  RC frame check: CRC-8 over src[p] (type) + 22 channel bytes against src[p + 23], then the
  16 × 11-bit channels into raw[0..15] and us_of_raw[value] into us[0..15]. 0 on a CRC
  mismatch (nothing written), 1 after unpacking.
- `unpack11(src, p, raw, us, us_of_raw)`: rxcodec.unpack11, the channels from src[p:p+22].
- `crc8_dvb_s2(src, start, end)`: protocols/crc.py's CRC-8/DVB-S2 of src[start:end] from 0
  (end given, >= start), for CRSF's other frames and the telemetry encoders.

It sits in the receiver task: CrsfDecoder.feed/_take call it once per frame.
Viper reads raw memory without bounds checks, so the callers' contracts matter: src holds the
whole frame (the framer only calls with complete frames), raw/us/us_of_raw are array('H')
(ptr16) and crc_table is 256 bytes. tests/portable/test_viper_twins.py runs both twins on
random and edge-case frames and asserts they agree.
Viper ints are machine words (32-bit on the RP2040/RP2350): every intermediate here is a byte,
an 11-bit value, a table index or an index below 64, so nothing comes near 2**31.
"""

# ptr8/ptr16/int are viper's built-in casts: they exist only inside @micropython.viper code.
# ruff: noqa: F821

import micropython

from hoverfly.protocols.crc import CRC8_DVB_S2_TABLE


@micropython.viper
def crc8_dvb_s2(src, start: int, end: int) -> int:
    s = ptr8(src)
    t = ptr8(CRC8_DVB_S2_TABLE)
    c = 0
    k = start
    while k < end:
        c = t[c ^ s[k]]  # c and s[k] are bytes: the index stays in 0..255
        k += 1
    return c


@micropython.viper
def unpack11(src, p: int, raw, us, us_of_raw):
    s = ptr8(src)
    r = ptr16(raw)
    u = ptr16(us)
    m = ptr16(us_of_raw)
    c = 0
    while c < 16:
        # Eight channels in 11 bytes, LSB first; the widest term is a byte << 10 (< 2**18).
        b0 = s[p]
        b1 = s[p + 1]
        b2 = s[p + 2]
        b3 = s[p + 3]
        b4 = s[p + 4]
        b5 = s[p + 5]
        b6 = s[p + 6]
        b7 = s[p + 7]
        b8 = s[p + 8]
        b9 = s[p + 9]
        b10 = s[p + 10]
        v = (b0 | b1 << 8) & 0x7FF
        r[c] = v
        u[c] = m[v]
        v = (b1 >> 3 | b2 << 5) & 0x7FF
        r[c + 1] = v
        u[c + 1] = m[v]
        v = (b2 >> 6 | b3 << 2 | b4 << 10) & 0x7FF
        r[c + 2] = v
        u[c + 2] = m[v]
        v = (b4 >> 1 | b5 << 7) & 0x7FF
        r[c + 3] = v
        u[c + 3] = m[v]
        v = (b5 >> 4 | b6 << 4) & 0x7FF
        r[c + 4] = v
        u[c + 4] = m[v]
        v = (b6 >> 7 | b7 << 1 | b8 << 9) & 0x7FF
        r[c + 5] = v
        u[c + 5] = m[v]
        v = (b8 >> 2 | b9 << 6) & 0x7FF
        r[c + 6] = v
        u[c + 6] = m[v]
        v = (b9 >> 5 | b10 << 3) & 0x7FF
        r[c + 7] = v
        u[c + 7] = m[v]
        c += 8
        p += 11


@micropython.viper
def check_unpack11(src, p: int, raw, us, us_of_raw, crc_table) -> int:
    s = ptr8(src)
    t = ptr8(crc_table)
    c = 0
    k = p
    end = p + 23  # type byte + 22 channel bytes; the CRC byte follows
    while k < end:
        c = t[c ^ s[k]]
        k += 1
    if c != s[end]:
        return 0
    unpack11(src, p + 1, raw, us, us_of_raw)
    return 1
