"""`hoverfly rx`: decode captured receiver byte streams, encode single receiver frames.

    hoverfly rx decode --protocol crsf|sbus|ibus FILE|-  [--json]
    hoverfly rx encode --protocol crsf|sbus|ibus --channels 1500,1500,... [--out FILE] [--hex]

`decode` feeds the capture through the same codec the flight core uses and prints one line
per frame (RC frames, and for CRSF link statistics and every other valid frame), then a
summary of the counters; with `--json` each is one JSON object per line (`type` "rc",
"link_statistics", ..., then "summary"). `encode` writes one RC frame: binary to stdout or
`--out`, or hex text with `--hex`. Host tool (CPython), sits outside the flight core.
"""

import json
import sys

from hoverfly.errors import UserError
from hoverfly.protocols import crsf, ibus, sbus
from hoverfly.protocols.rxcodec import MAX_PULSE_US, MIN_PULSE_US

SERIAL_PROTOCOLS = ("crsf", "sbus", "ibus")
_PROTOCOL_HELP = ("the receiver's serial protocol: crsf (TBS Crossfire / ExpressLRS, 416 666 or 420 000 baud), "
                  "sbus (FrSky/Futaba, 100 kbaud inverted 8E2) or ibus (FlySky, 115200 baud)")


def register(subparsers):
    p = subparsers.add_parser("rx", help="receiver protocols: decode captures, encode frames",
                              description="Decode captured CRSF/SBUS/iBUS byte streams or encode one frame.")
    sub = p.add_subparsers(dest="rx_command")

    d = sub.add_parser("decode", help="decode a captured receiver byte stream, one line per frame")
    d.add_argument("--protocol", required=True, choices=SERIAL_PROTOCOLS, help=_PROTOCOL_HELP)
    d.add_argument("file", help="capture file, or - for stdin")
    d.add_argument("--json", action="store_true", help="one JSON object per line")
    d.set_defaults(func=run_decode)

    e = sub.add_parser("encode", help="encode one RC frame")
    e.add_argument("--protocol", required=True, choices=SERIAL_PROTOCOLS, help=_PROTOCOL_HELP)
    e.add_argument("--channels", default="", help="comma-separated µs values, missing ones are 1500")
    e.add_argument("--out", help="write the frame to this file instead of stdout")
    e.add_argument("--hex", action="store_true", help="hex text instead of binary")
    e.add_argument("--failsafe", action="store_true", help="SBUS: set the failsafe flag")
    e.add_argument("--frame-lost", action="store_true", help="SBUS: set the frame-lost flag")
    e.add_argument("--ch17", action="store_true", help="SBUS: digital channel 17 on")
    e.add_argument("--ch18", action="store_true", help="SBUS: digital channel 18 on")
    e.set_defaults(func=run_encode)

    def _help(args):
        p.print_help()
        return 2

    p.set_defaults(func=_help)


# -- decode ----------------------------------------------------------------------------


def _read_input(path):
    if path == "-":
        return sys.stdin.buffer.read()
    try:
        with open(path, "rb") as f:
            return f.read()
    except FileNotFoundError:
        raise UserError("no such file: %s" % path) from None
    except IsADirectoryError:
        raise UserError("%s is a directory, not a capture file" % path) from None
    except OSError as exc:
        raise UserError("cannot read %s: %s" % (path, exc.strerror or exc)) from None


def _decoder(protocol):
    if protocol == "crsf":
        return crsf.CrsfDecoder()
    if protocol == "sbus":
        return sbus.SbusDecoder()
    return ibus.IbusDecoder()


def _rc_record(protocol, d):
    rec = {"type": "rc", "channels_us": list(d.channels_us), "channels_raw": list(d.channels_raw)}
    if protocol == "sbus":
        rec.update(failsafe=d.failsafe, frame_lost=d.frame_lost, ch17=d.ch17, ch18=d.ch18)
    return rec


def _link_record(d):
    return {
        "type": "link_statistics",
        "rssi_dbm": d.rssi_dbm, "rssi1_dbm": d.rssi1_dbm, "rssi2_dbm": d.rssi2_dbm,
        "link_quality_pct": d.link_quality_pct, "snr_db": d.snr_db, "active_antenna": d.active_antenna,
        "rf_mode": d.rf_mode, "tx_power": d.tx_power, "tx_power_mw": d.tx_power_mw,
        "downlink_rssi_dbm": d.downlink_rssi_dbm, "downlink_link_quality_pct": d.downlink_link_quality_pct,
        "downlink_snr_db": d.downlink_snr_db,
    }


def _other_record(d):
    rec = {"type": crsf.TYPE_NAMES.get(d.last_type, "unknown"), "frame_type": d.last_type}
    if d.last_type >= crsf.TYPE_EXTENDED_FIRST:
        rec.update(dest=d.last_dest, origin=d.last_origin)
    return rec


def _summary(protocol, d):
    rec = {"type": "summary", "frames": d.frames, "crc_errors": d.crc_errors, "resyncs": d.resyncs,
           "bytes": d.bytes, "length_errors": d.length_errors}
    if protocol == "crsf":
        rec.update(link_stats_frames=d.link_stats_frames, other_frames=d.other_frames)
    return rec


def _human(rec):
    kind = rec["type"]
    if kind == "rc":
        line = "rc  " + " ".join("%4d" % v for v in rec["channels_us"])
        for flag in ("failsafe", "frame_lost", "ch17", "ch18"):
            if rec.get(flag):
                line += "  " + flag
        return line
    if kind == "link_statistics":
        return ("link_statistics  rssi %d dBm (ant %d)  lq %d%%  snr %d dB  rf_mode %d  power %d mW  "
                "down: rssi %d dBm lq %d%% snr %d dB" % (
                    rec["rssi_dbm"], rec["active_antenna"] + 1, rec["link_quality_pct"], rec["snr_db"],
                    rec["rf_mode"], rec["tx_power_mw"], rec["downlink_rssi_dbm"],
                    rec["downlink_link_quality_pct"], rec["downlink_snr_db"]))
    if kind == "summary":
        return "  ".join("%s %d" % (k, v) for k, v in rec.items() if k != "type")
    line = "%s  type 0x%02X" % (kind, rec["frame_type"])
    if "dest" in rec:
        line += "  dest 0x%02X origin 0x%02X" % (rec["dest"], rec["origin"])
    return line


def run_decode(args):
    data = _read_input(args.file)
    d = _decoder(args.protocol)
    emit = (lambda rec: print(json.dumps(rec))) if args.json else (lambda rec: print(_human(rec)))
    is_crsf = args.protocol == "crsf"
    one = bytearray(1)
    for b in data:
        one[0] = b
        link = d.link_stats_frames if is_crsf else 0
        other = d.other_frames if is_crsf else 0
        if d.feed(one):
            emit(_rc_record(args.protocol, d))
        elif is_crsf and d.link_stats_frames != link:
            emit(_link_record(d))
        elif is_crsf and d.other_frames != other:
            emit(_other_record(d))
    emit(_summary(args.protocol, d))
    return 0


# -- encode ----------------------------------------------------------------------------


def _parse_channels(text, protocol):
    values = []
    if text.strip():
        for k, item in enumerate(text.split(","), start=1):
            item = item.strip()
            try:
                v = float(item)
            except ValueError:
                raise UserError("channel %d: %r is not a number (µs)" % (k, item)) from None
            if v != v or v < MIN_PULSE_US or v > MAX_PULSE_US:
                raise UserError("channel %d: %s µs is outside %d..%d" % (k, item, MIN_PULSE_US, MAX_PULSE_US))
            values.append(int(round(v)))
    limit = ibus.IBUS_CHANNELS if protocol == "ibus" else 16
    if len(values) > limit:
        raise UserError("%s carries %d channels, got %d" % (protocol, limit, len(values)))
    return values + [1500] * (limit - len(values))


def run_encode(args):
    chans = _parse_channels(args.channels, args.protocol)
    if args.protocol != "sbus" and (args.failsafe or args.frame_lost or args.ch17 or args.ch18):
        raise UserError("--failsafe/--frame-lost/--ch17/--ch18 are SBUS flags")
    if args.protocol == "crsf":
        frame = crsf.encode_rc_frame(chans)
    elif args.protocol == "sbus":
        frame = sbus.encode_rc_frame(chans, None, args.ch17, args.ch18, args.frame_lost, args.failsafe)
    else:
        frame = ibus.encode_rc_frame(chans)
    frame = bytes(frame)
    if args.hex:
        text = " ".join("%02X" % b for b in frame) + "\n"
        if args.out:
            _write(args.out, text.encode())
        else:
            sys.stdout.write(text)
        return 0
    if args.out:
        _write(args.out, frame)
    else:
        sys.stdout.flush()
        sys.stdout.buffer.write(frame)
        sys.stdout.buffer.flush()
    return 0


def _write(path, data):
    try:
        with open(path, "wb") as f:
            f.write(data)
    except OSError as exc:
        raise UserError("cannot write %s: %s" % (path, exc.strerror or exc)) from None
