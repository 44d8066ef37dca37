"""The receiver decoder for an `rx_provider` name (Betaflight's serialrx_provider and PPM/PWM).

Takes a protocol name; gives a fresh decoder with the common interface of rxcodec.py. Its own
module because it names every codec and each codec imports rxcodec, their shared base: kept in
rxcodec it made an import circle. Used by the receiver stage (core/stages/receiver.py) at configure.
"""


def make_decoder(protocol, channels=8):
    """A fresh decoder by name: "crsf", "sbus", "ibus", "ppm" or "pwm" (`channels` inputs).

    Imports only the module asked for, so a Pico carries one protocol's tables.
    An unknown name is a configuration mistake and raises ValueError.
    """
    if protocol == "crsf":
        from hoverfly.protocols.crsf import CrsfDecoder

        return CrsfDecoder()
    if protocol == "sbus":
        from hoverfly.protocols.sbus import SbusDecoder

        return SbusDecoder()
    if protocol == "ibus":
        from hoverfly.protocols.ibus import IbusDecoder

        return IbusDecoder()
    if protocol == "ppm":
        from hoverfly.protocols.pulses import PpmCapture

        return PpmCapture()
    if protocol == "pwm":
        from hoverfly.protocols.pulses import PwmCapture

        return PwmCapture(channels)
    raise ValueError("unknown receiver protocol %r (one of crsf, sbus, ibus, ppm, pwm)" % (protocol,))
