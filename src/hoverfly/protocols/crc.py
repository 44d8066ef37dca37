"""Checksums shared by the wire codecs: CRC-8/DVB-S2 (CRSF, MSP v2), CRC-8 poly 0xBA, XOR-8.

Table-driven; the tables are built once at import into bytes objects so a lookup
allocates nothing. Check values over b"123456789": DVB-S2 0xBC, 0xBA-poly 0x20, XOR 0x31
(reference/protocols.md section 0).
"""


def _table(poly):
    t = bytearray(256)
    for i in range(256):
        c = i
        for _ in range(8):
            c = ((c << 1) ^ poly) & 0xFF if c & 0x80 else (c << 1) & 0xFF
        t[i] = c
    return bytes(t)


CRC8_DVB_S2_TABLE = _table(0xD5)
CRC8_BA_TABLE = _table(0xBA)


def crc8_dvb_s2(data, start=0, end=-1, crc=0):
    """CRC-8/DVB-S2 of data[start:end] (end -1 = to the end), continuing from `crc`."""
    if end < 0:
        end = len(data)
    t = CRC8_DVB_S2_TABLE
    for i in range(start, end):
        crc = t[crc ^ data[i]]
    return crc


# fastpass: crc8_dvb_s2_span data:B
def crc8_dvb_s2_span(data, start, end):
    """CRC-8/DVB-S2 of data[start:end] from 0, end given (>= start, within data): what a codec checks a frame
    with. Its viper twin (accel/crc.py, generated from it) reads data without bounds checks."""
    t = CRC8_DVB_S2_TABLE
    crc = 0
    for i in range(start, end):
        crc = t[crc ^ data[i]]
    return crc


def crc8_dvb_s2_byte(crc, b):
    return CRC8_DVB_S2_TABLE[crc ^ b]


def crc8_ba(data, start=0, end=-1, crc=0):
    """CRC-8 poly 0xBA (CRSF 0x32 command frames' inner CRC)."""
    if end < 0:
        end = len(data)
    t = CRC8_BA_TABLE
    for i in range(start, end):
        crc = t[crc ^ data[i]]
    return crc


def xor8(data, start=0, end=-1, x=0):
    """XOR of data[start:end] (MSP v1, the seed-001 maintenance protocol)."""
    if end < 0:
        end = len(data)
    for i in range(start, end):
        x ^= data[i]
    return x
