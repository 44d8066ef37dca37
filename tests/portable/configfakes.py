"""Fakes for the configuration-link tests: a Board with in-memory serial ports and storage, and
a Flight built on it (optionally with recording stand-ins for the SAFETY/OUTPUTS seams)."""

from hoverfly.core.board import Board
from hoverfly.core.config.storage import MemoryStorageBoard
from hoverfly.core.flight import Flight

BOOT_US = 1000


class FakeBoard(Board):
    name = "fake"

    def __init__(self):
        self.t_us = BOOT_US
        self.rx = [bytearray(), bytearray()]
        self.tx = [bytearray(), bytearray()]
        self.gone = [False, False]
        self.store = MemoryStorageBoard()
        self.led = False

    def now_us(self):
        return self.t_us

    def read_imu(self, gyro_rad_s, accel_m_s2):
        accel_m_s2[0] = 0.0
        accel_m_s2[1] = 0.0
        accel_m_s2[2] = -9.80665
        return True

    def write_motors(self, motor_out, count):
        pass

    def load_storage(self):
        return self.store.load_storage()

    def save_storage(self, image):
        return self.store.save_storage(image)

    def serial_read(self, port, buf):
        if self.gone[port]:
            self.gone[port] = False
            return -1
        src = self.rx[port]
        n = len(src) if len(src) < len(buf) else len(buf)
        for i in range(n):
            buf[i] = src[i]
        self.rx[port] = src[n:]
        return n

    def serial_write(self, port, data, n=-1):
        if n < 0:
            n = len(data)
        self.tx[port].extend(bytes(data[:n]))
        return n

    def take(self, port):
        out = bytes(self.tx[port])
        self.tx[port] = bytearray()
        return out


class MotorTestRecorder:
    def __init__(self):
        self.requests = []
        self.active = False
        self.stops = 0

    def request(self, now_us, index, value_norm, props_off):
        if not props_off:
            return "props-off acknowledgement missing"
        self.requests.append((index, value_norm))
        self.active = value_norm > 0
        return None

    def stop(self, reason_code):
        self.stops += 1
        self.active = False


def make_flight(seams=True):
    board = FakeBoard()
    flight = Flight(board)
    flight.start(board.now_us())
    if seams:
        flight.rc_calls = []

        def on_msp_rc(now_us, channels_us, count):
            flight.rc_calls.append(list(channels_us[:count]))
            return None

        flight.on_msp_rc = on_msp_rc
        flight.motor_test = MotorTestRecorder()
    return flight, board
