"""`hoverfly esc`: encode an ESC command, decode a bidirectional DShot reply (host tool).

  hoverfly esc encode --protocol dshot600 --value 1046 [--telemetry] [--bidir] [--json]
      DShot: --value is the 11-bit value 0..2047 (0 stop, 1..47 commands, 48..2047 throttle);
      prints the frame (hex, bits) and the bit timings and PIO constants.
  hoverfly esc encode --protocol oneshot125 --value 234 [--rate-hz N] [--timer-hz N] [--json]
      pwm/oneshot125/oneshot42/multishot: --value is throttle 0..1000 (Betaflight's motor value
      minus 1000, so 234 = 1234) -> pulse width, and the timer counts at --timer-hz (default
      125 MHz, the rp2 system clock) and --rate-hz (default 480 Hz PWM, 1000 Hz one-shot family).
      servo: --value is −1000..1000 (stick −1..1) -> 1000..1500..2000 µs at 50 Hz by default.
  hoverfly esc decode-erpm 5F41 [--poles 14] [--gcr] [--no-edt] [--json]
      WORD is the reply's 16-bit word in hex (--gcr: the 21-bit line code, start bit included).
      Exit 0 for a valid reply, 1 when its GCR or CRC is bad.
"""

import json

from hoverfly.errors import UserError
from hoverfly.protocols import analog, dshot

DSHOT_PROTOCOLS = {"dshot150": 150, "dshot300": 300, "dshot600": 600, "dshot1200": 1200}
ANALOG_PROTOCOLS = ("pwm", "oneshot125", "oneshot42", "multishot", "servo")
DEFAULT_RATE_HZ = {"pwm": 480, "oneshot125": 1000, "oneshot42": 1000, "multishot": 1000, "servo": 50}
RP2_SYS_CLOCK_HZ = 125000000
EDT_UNITS = {"temperature": "degC", "voltage": "V", "current": "A"}


def register(subparsers):
    p = subparsers.add_parser("esc", help="encode ESC commands, decode bidirectional DShot replies")
    sub = p.add_subparsers(dest="esc_command")
    e = sub.add_parser("encode", help="one ESC command -> DShot frame or pulse width, with timings")
    e.add_argument("--protocol", required=True, choices=tuple(DSHOT_PROTOCOLS) + ANALOG_PROTOCOLS,
                   help="the ESC protocol: dshot150/300/600/1200 (digital frames, the number is kbit/s), pwm "
                        "(1000-2000 us), oneshot125 (125-250 us), oneshot42 (42-84 us), multishot (5-25 us) or "
                        "servo (1000-2000 us at 50 Hz)")
    e.add_argument("--value", required=True, help="dshot 0..2047; analog throttle 0..1000; servo -1000..1000")
    e.add_argument("--telemetry", action="store_true", help="dshot: set the telemetry request bit")
    e.add_argument("--bidir", action="store_true", help="dshot: bidirectional (inverted CRC)")
    e.add_argument("--rate-hz", type=float, help="analog: update rate (480 pwm, 1000 one-shot, 50 servo)")
    e.add_argument("--timer-hz", type=int, default=RP2_SYS_CLOCK_HZ, help="analog: timer clock for counts")
    e.add_argument("--json", action="store_true", help="one JSON object")
    e.set_defaults(func=run_encode)
    d = sub.add_parser("decode-erpm", help="bidirectional DShot reply -> eRPM/RPM or EDT value")
    d.add_argument("word", help="16-bit reply word in hex (with --gcr: 21-bit line code)")
    d.add_argument("--poles", type=int, default=14, help="motor magnet poles (default 14)")
    d.add_argument("--gcr", action="store_true", help="WORD is the 21-bit GCR line code")
    d.add_argument("--no-edt", action="store_true", help="read every frame as eRPM (ESC without EDT)")
    d.add_argument("--json", action="store_true", help="one JSON object")
    d.set_defaults(func=run_decode)
    p.set_defaults(func=_help(p))


def _help(parser):
    def run(args):
        parser.print_help()
        return 2

    return run


def _int(text, what):
    try:
        return int(text, 0)
    except ValueError:
        raise UserError("%s %r is not an integer" % (what, text)) from None


def _hex(text, what):
    t = text.strip().lower()
    if t.startswith("0x"):
        t = t[2:]
    try:
        return int(t, 16)
    except ValueError:
        raise UserError("%s %r is not hexadecimal" % (what, text)) from None


def encode(protocol, value_text, telemetry=False, bidir=False, rate_hz=None, timer_hz=RP2_SYS_CLOCK_HZ):
    """The report `hoverfly esc encode` prints, as a dict."""
    if protocol in DSHOT_PROTOCOLS:
        speed = DSHOT_PROTOCOLS[protocol]
        value = _int(value_text, "--value")
        if not 0 <= value <= dshot.VALUE_MAX:
            raise UserError("dshot --value %d outside 0..2047" % value)
        frame = dshot.dshot_frame(value, 1 if telemetry else 0, bidir)
        bit_ns, t0h_ns, t1h_ns, frame_ns, sm_freq_hz, reply_bit_ns = dshot.dshot_timing(speed)
        if value == 0:
            meaning = "stop"
        elif value <= dshot.COMMAND_MAX:
            meaning = "command " + dshot.COMMAND_NAMES[value]
        else:
            meaning = "throttle %.2f%%" % ((value - dshot.THROTTLE_MIN) * 100.0 / dshot.THROTTLE_RANGE)
        out = {
            "protocol": protocol, "value": value, "telemetry": bool(telemetry), "bidir": bool(bidir),
            "meaning": meaning, "frame": frame, "hex": "0x%04X" % frame, "bits": _bits(frame, 16),
            "pio_word": "0x%08X" % dshot.pio_word(frame),
            "bit_ns": bit_ns, "t0h_ns": t0h_ns, "t1h_ns": t1h_ns, "frame_ns": frame_ns,
            "sm_freq_hz": sm_freq_hz, "pio_cycles_per_bit": dshot.PIO_CYCLES_PER_BIT,
            "pio_cycles_high_0": dshot.PIO_CYCLES_HIGH_0, "pio_cycles_high_1": dshot.PIO_CYCLES_HIGH_1,
        }
        if bidir:
            out["reply_bit_ns"] = reply_bit_ns
            out["reply_delay_us"] = dshot.REPLY_DELAY_US
        if 1 <= value <= dshot.COMMAND_MAX:
            out["command_repeats"] = dshot.command_repeats(value)
            out["command_delay_us"] = dshot.command_delay_us(value)
        return out
    if protocol not in ANALOG_PROTOCOLS:
        raise UserError("unknown protocol %r" % protocol)
    if telemetry or bidir:
        raise UserError("--telemetry and --bidir apply to dshot only")
    pid = analog.protocol_id(protocol)
    rate = DEFAULT_RATE_HZ[protocol] if rate_hz is None else rate_hz
    err = analog.validate_rate(pid, rate)
    if err:
        raise UserError(err)
    if timer_hz <= 0:
        raise UserError("--timer-hz must be positive")
    value = _int(value_text, "--value")
    if pid == analog.SERVO:
        if not -1000 <= value <= 1000:
            raise UserError("servo --value %d outside -1000..1000" % value)
        width_us = analog.servo_pulse_us(value / 1000.0)
    else:
        if not 0 <= value <= 1000:
            raise UserError("analog --value %d outside 0..1000 (throttle)" % value)
        width_us = analog.pulse_us(pid, value / 1000.0)
    lo_us, hi_us = analog.pulse_range_us(pid)
    if pid == analog.SERVO:
        lo_us, hi_us = 1000.0, 2000.0
    rmin, rmax = analog.rate_limits_hz(pid)
    return {
        "protocol": protocol, "value": value, "pulse_us": round(width_us, 6),
        "pulse_ns": int(width_us * 1000 + 0.5), "min_us": lo_us, "max_us": hi_us,
        "rate_hz": rate, "period_us": round(1e6 / rate, 3), "rate_min_hz": rmin, "rate_max_hz": rmax,
        "timer_hz": timer_hz, "period_counts": analog.period_counts(timer_hz, rate),
        "compare_counts": analog.counts_of_us(width_us, timer_hz),
    }


def _bits(v, n):
    return "".join("1" if (v >> i) & 1 else "0" for i in range(n - 1, -1, -1))


def decode(word_text, poles=14, gcr=False, edt=True):
    """The report `hoverfly esc decode-erpm` prints, as a dict."""
    if poles < 2 or poles % 2:
        raise UserError("--poles %d must be an even number >= 2" % poles)
    raw = _hex(word_text, "WORD")
    out = {}
    if gcr:
        if not 0 <= raw <= 0x1FFFFF:
            raise UserError("GCR line code 0x%X is wider than 21 bits" % raw)
        out["gcr"] = "0x%06X" % raw
        word = dshot.gcr_decode(raw)
        out["gcr_ok"] = word >= 0
        if word < 0:
            out.update({"word": None, "crc_ok": False, "kind": "invalid"})
            return out
    else:
        if not 0 <= raw <= 0xFFFF:
            raise UserError("reply word 0x%X is wider than 16 bits" % raw)
        word = raw
    out["word"] = "0x%04X" % word
    kind, value = dshot.decode_reply(word, poles, edt)
    out["crc_ok"] = kind != dshot.KIND_INVALID
    if kind == dshot.KIND_INVALID:
        out["kind"] = "invalid"
        return out
    name = dshot.KIND_NAMES[kind]
    out["kind"] = name
    if kind == dshot.KIND_ERPM:
        period_us, erpm, rpm = value
        out.update({"stopped": period_us == 0, "period_us": period_us, "erpm": erpm, "rpm": rpm})
        out["poles"] = poles
    else:
        out["value"] = value
        if name in EDT_UNITS:
            out["unit"] = EDT_UNITS[name]
    return out


def run_encode(args):
    out = encode(args.protocol, args.value, args.telemetry, args.bidir, args.rate_hz, args.timer_hz)
    if args.json:
        print(json.dumps(out))
        return 0
    if "frame" in out:
        print("%s value %d (%s) telemetry %d %s" % (
            out["protocol"], out["value"], out["meaning"], out["telemetry"],
            "bidirectional" if out["bidir"] else "normal"))
        print("frame %s  bits %s  (PIO word %s)" % (out["hex"], out["bits"], out["pio_word"]))
        print("bit %d ns  T0H %d ns  T1H %d ns  frame %d ns" % (
            out["bit_ns"], out["t0h_ns"], out["t1h_ns"], out["frame_ns"]))
        print("PIO %d Hz, %d cycles/bit, high %d (0) / %d (1)" % (
            out["sm_freq_hz"], out["pio_cycles_per_bit"], out["pio_cycles_high_0"], out["pio_cycles_high_1"]))
        if "reply_bit_ns" in out:
            print("reply %d ns/bit, ~%d us after the frame" % (out["reply_bit_ns"], out["reply_delay_us"]))
        if "command_repeats" in out:
            print("command: send %d times, then wait %d us" % (
                out["command_repeats"], out["command_delay_us"]))
    else:
        print("%s value %d -> pulse %.3f us (%d ns), range %g..%g us" % (
            out["protocol"], out["value"], out["pulse_us"], out["pulse_ns"], out["min_us"], out["max_us"]))
        print("rate %g Hz (allowed %d..%d), period %.3f us; at %d Hz timer: period %d counts, compare %d" % (
            out["rate_hz"], out["rate_min_hz"], out["rate_max_hz"], out["period_us"], out["timer_hz"],
            out["period_counts"], out["compare_counts"]))
    return 0


def run_decode(args):
    out = decode(args.word, args.poles, args.gcr, not args.no_edt)
    ok = out["crc_ok"]
    if args.json:
        print(json.dumps(out))
        return 0 if ok else 1
    head = ("gcr %s -> " % out["gcr"]) if "gcr" in out else ""
    if not ok:
        why = "bad GCR" if out["word"] is None else "bad CRC"
        print("%sword %s: invalid (%s)" % (head, out["word"], why))
        return 1
    if out["kind"] == "erpm":
        if out["stopped"]:
            print("%sword %s: motor stopped" % (head, out["word"]))
        else:
            print("%sword %s: period %d us, %d eRPM, %d RPM (%d poles)" % (
                head, out["word"], out["period_us"], out["erpm"], out["rpm"], out["poles"]))
    else:
        print("%sword %s: %s %s %s" % (head, out["word"], out["kind"], out["value"], out.get("unit", "")))
    return 0
