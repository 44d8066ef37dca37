"""Simulated ESCs and servos: they read the real wire, as the hardware would, and drive the physics.

The sim board's output timer hands each output line what the flight core's output codec put
on it (`core.stages.output.OutputEncoder`): a 16-bit DShot frame, or an analog pulse width in µs.
`SimEsc` decodes it to the throttle 0..1 the motor model spins to:
- DShot: CRC checked (normal, or inverted for bidirectional: the ESC detects which, as
  BLHeli_32/AM32 do); a frame that fails is ignored (the last command holds) and counted.
  Value 0 = stop, 48..2047 = throttle (value - 48) / 1999, 1..47 = special commands: no
  thrust (the motor stops); a command acts after 6 identical frames in a row (AM32/BLHeli_32),
  and the ESC keeps what it understood (spin direction, 3D mode, extended telemetry). An ESC
  in 3D mode reads 1048..2047 as forward and below as reverse (no thrust in this model).
- Analog: the width mapped by the protocol's own range (PWM 1000..2000 µs, OneShot125
  125..250, OneShot42 42..84, Multishot 5..25); a width beyond the range by more than
  `tolerance_us` is ignored and counted.
`receive_line` / `receive_analog_line` take the wire as (level, duration) pulses from the
pulse-train model (`protocols.pulsetrain`) and decode them with timing tolerance, as an ESC
does: slower, so the sim board uses them only when asked (`line=True`).
Bidirectional DShot: `reply_code(omega_rad_s)` is the ESC's answer, the 21-bit GCR line code
of the eRPM of the simulated rotor (eRPM = RPM x poles / 2), or the stopped code.

`SimServo` maps a servo width back to a position -1..1 with the servo's own end points.
CPython only (simulator).
"""

import math

from hoverfly.core.stages.output import analog_protocol, dshot_speed_kbit
from hoverfly.protocols import analog
from hoverfly.protocols.dshot import (
    CMD_3D_MODE_OFF,
    CMD_3D_MODE_ON,
    CMD_EXTENDED_TELEMETRY_DISABLE,
    CMD_EXTENDED_TELEMETRY_ENABLE,
    CMD_SPIN_DIRECTION_1,
    CMD_SPIN_DIRECTION_2,
    CMD_SPIN_DIRECTION_NORMAL,
    CMD_SPIN_DIRECTION_REVERSED,
    THROTTLE_MIN,
    THROTTLE_RANGE,
    erpm_reply_word,
    frame_crc_ok,
    gcr_encode,
)
from hoverfly.protocols.pulsetrain import AnalogPulseDecoder, DshotPulseDecoder

ACT_AFTER_REPEATS = 6  # identical command frames before an ESC acts on a command
# Throttle frames already decoded: word -> (bidirectional, throttle 0..1 outside 3D mode). A word's CRC,
# kind and value are fixed by its 16 bits, so each throttle word is checked once a process (a hover sends a
# few hundred different ones, 40 000 frames). WORD_CACHE = False decodes every frame (the test that the
# cache changes no flight: tests/test_sim_speed.py).
WORD_CACHE = True
_THROTTLE_FRAMES = {}
_RPM_PER_RAD_S = 60.0 / (2.0 * math.pi)


class SimEsc:
    def __init__(self, protocol="dshot600", poles=14, tolerance_us=0.5, mode_3d=False):
        self.protocol = protocol
        self.speed_kbit = dshot_speed_kbit(protocol)
        self.dshot = self.speed_kbit > 0
        self.analog = analog_protocol(protocol)
        if not self.dshot and self.analog < 0:
            raise ValueError("unknown ESC protocol %r" % (protocol,))
        self.poles = poles
        self.throttle_norm = 0.0  # what the motor is asked for
        self.frames = 0  # good frames/pulses
        self.errors = 0  # CRC failures, pulses out of range or off timing
        self.commands = 0  # command frames received
        self.commands_done = 0  # commands acted on
        self.last_command = 0
        self.bidir = False  # seen inverted-CRC frames: answers each with eRPM
        self.spin_reversed = False
        self.mode_3d = mode_3d  # True: as left in 3D mode by another controller
        self.edt = False
        self._cmd_run = 0
        self._cmd_value = -1
        self._throttle_word = -1  # the last good throttle frame: the same word decodes the same way
        self._reply_word = -1  # the last bidirectional reply and its line code
        self._reply_code = 0
        if self.dshot:
            self._line_normal = DshotPulseDecoder(self.speed_kbit, bidir=False)
            self._line_bidir = DshotPulseDecoder(self.speed_kbit, bidir=True)
        else:
            lo, hi = analog.pulse_range_us(self.analog)
            self.min_us = lo
            self.len_us = hi - lo
            self.tolerance_us = tolerance_us
            self._line_analog = AnalogPulseDecoder(self.analog, tolerance_us)

    # ------------------------------------------------------------ DShot
    def receive_word(self, word):
        """One DShot frame off the wire; returns the throttle 0..1 the motor now runs to."""
        if word == self._throttle_word:
            # A throttle frame repeated (most of them, at a 1 kHz loop): its CRC, kind and value are
            # the last one's, and only a command frame, which clears this, can change the ESC's mode.
            self.frames += 1
            return self.throttle_norm
        if WORD_CACHE and not self.mode_3d:
            known = _THROTTLE_FRAMES.get(word)
            if known is not None:  # a throttle frame decoded before: as the branch below leaves it
                self.bidir = known[0]
                self.frames += 1
                self._throttle_word = word
                self._cmd_run = 0
                self.throttle_norm = known[1]
                return known[1]
        if frame_crc_ok(word, False):
            bidir = False
        elif frame_crc_ok(word, True):
            bidir = True
        else:
            self.errors += 1
            return self.throttle_norm
        self.bidir = bidir
        self.frames += 1
        value = (word >> 5) & 0x7FF
        self._throttle_word = word if value >= THROTTLE_MIN else -1
        if value == 0:  # stop; stop frames between a command's repeats keep its count
            self.throttle_norm = 0.0
        elif value < THROTTLE_MIN:
            self._command(value)
            self.throttle_norm = 0.0
        else:
            self._cmd_run = 0
            if self.mode_3d:
                # 3D: 48..1047 reverse, 1048..2047 forward. Reverse thrust is not modelled: none.
                self.throttle_norm = (value - 1048) / 999.0 if value >= 1048 else 0.0
            else:
                self.throttle_norm = (value - THROTTLE_MIN) / THROTTLE_RANGE
                if WORD_CACHE:
                    _THROTTLE_FRAMES[word] = (bidir, self.throttle_norm)
        return self.throttle_norm

    def receive_line(self, pulses):
        """A DShot frame as (level, ns) pulses: decoded with timing tolerance, then as receive_word.

        The ESC follows the line's idle level: idle low is normal DShot, idle high bidirectional."""
        bidir = bool(pulses) and pulses[0][0] == 0
        word = (self._line_bidir if bidir else self._line_normal).decode(pulses)
        if word is None:
            self.errors += 1
            return self.throttle_norm
        return self.receive_word(word)

    def _command(self, value):
        self.commands += 1
        if value == self._cmd_value:
            self._cmd_run += 1
        else:
            self._cmd_value = value
            self._cmd_run = 1
        if self._cmd_run != ACT_AFTER_REPEATS:
            return
        self.commands_done += 1
        self.last_command = value
        if value in (CMD_SPIN_DIRECTION_1, CMD_SPIN_DIRECTION_NORMAL):
            self.spin_reversed = False
        elif value in (CMD_SPIN_DIRECTION_2, CMD_SPIN_DIRECTION_REVERSED):
            self.spin_reversed = True
        elif value == CMD_3D_MODE_OFF:
            self.mode_3d = False
        elif value == CMD_3D_MODE_ON:
            self.mode_3d = True
        elif value == CMD_EXTENDED_TELEMETRY_ENABLE:
            self.edt = True
        elif value == CMD_EXTENDED_TELEMETRY_DISABLE:
            self.edt = False

    def reply_word(self, omega_rad_s):
        """Bidirectional reply: the 16-bit word of the rotor's eRPM (the stopped code at rest)."""
        return erpm_reply_word(int(omega_rad_s * _RPM_PER_RAD_S * (self.poles // 2) + 0.5))

    def reply_code(self, omega_rad_s):
        """The reply as its 21-bit GCR line code (start bit included)."""
        word = self.reply_word(omega_rad_s)
        if word != self._reply_word:
            # the eRPM word holds a 9-bit period: a steady rotor sends the same word pass after pass
            self._reply_word = word
            self._reply_code = gcr_encode(word)
        return self._reply_code

    # ----------------------------------------------------------- analog
    def receive_pulse_us(self, width_us):
        """One analog pulse; returns the throttle 0..1 the motor now runs to."""
        t = (width_us - self.min_us) / self.len_us
        tol = self.tolerance_us / self.len_us
        if not (-tol <= t <= 1.0 + tol):
            self.errors += 1
            return self.throttle_norm
        self.frames += 1
        self.throttle_norm = 0.0 if t < 0.0 else (1.0 if t > 1.0 else t)
        return self.throttle_norm


    def receive_analog_line(self, pulses):
        """One analog period as (level, ns) pulses: the width measured, then as receive_pulse_us."""
        width_ns = self._line_analog.decode(pulses)
        if width_ns is None:
            self.errors += 1
            return self.throttle_norm
        return self.receive_pulse_us(width_ns * 1e-3)


class SimServo:
    """A servo with its own end points: width (µs) -> position -1..1 (clamped at its stops)."""

    def __init__(self, min_us=1000.0, mid_us=1500.0, max_us=2000.0):
        self.min_us = min_us
        self.mid_us = mid_us
        self.max_us = max_us
        self.position = 0.0

    def receive_pulse_us(self, width_us):
        if width_us >= self.mid_us:
            x = (width_us - self.mid_us) / (self.max_us - self.mid_us)
        else:
            x = (width_us - self.mid_us) / (self.mid_us - self.min_us)
        self.position = -1.0 if x < -1.0 else (1.0 if x > 1.0 else x)
        return self.position
