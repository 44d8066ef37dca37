"""Built-in test (seed 001): a continuous status bitfield, one bit per failing check.

Takes, once per slow pass, what the other stages already know (IMU alive, receiver alive,
loop keeping its rate, battery above critical, parameter storage loaded, gyro calibrated)
and gives `flags` (u32, bit set = check failing; 0 = all good) and `names()`. Telemetry,
MSP and seed 001's maintenance protocol (`builtin_test_status`, u32) read `flags`. The
configuration links set `storage_ok` when a stored parameter set failed to load.
"""

from hoverfly.compat import const

BIT_IMU = const(0)
BIT_RECEIVER = const(1)
BIT_LOOP = const(2)
BIT_BATTERY = const(3)
BIT_STORAGE = const(4)
BIT_CALIBRATION = const(5)
BIT_BOARD = const(6)
BIT_PARAMS = const(7)
BIT_TASKS = const(8)

CHECK_NAMES = ("imu", "receiver", "loop", "battery", "storage", "calibration", "board", "params", "tasks")
CHECK_SENTENCES = (
    "IMU: no new samples, or frozen or saturated values",
    "receiver: no valid frames",
    "loop: the flight loop does not keep its rate",
    "battery: below vbat_min_cell per cell",
    "storage: the stored parameters did not load (defaults in use)",
    "calibration: gyro not calibrated",
    "board: a device failed (IMU, receiver wiring or motor outputs; see the board status line)",
    "params: stored values were skipped at boot (out of range, not finite or unfit; see status)",
    "tasks: a slow task, link, telemetry encoder or the log raised and was stopped there (see status)",
)

# Failing checks that have no arming reason of their own raise BIT_FAILED.
BLOCKING = (1 << BIT_STORAGE) | (1 << BIT_BOARD)


class BuiltInTest:
    def __init__(self):
        self.flags = 0
        self.storage_ok = True  # set by the configuration links (storage load result)
        self.board_faults = 0  # set by the board's health check (rp2: board.faults)
        self.params_ok = True  # set at boot (Flight.start): False if the storage load skipped a stored value
        self.tasks_ok = True  # set by the flight's 100 Hz task: False once a guarded call raised (Flight.loop_errors)
        self.runs = 0

    def update(self, imu_ok, rx_ok, loop_ok, battery_ok, calibrated):
        f = 0
        if not imu_ok:
            f |= 1 << BIT_IMU
        if not rx_ok:
            f |= 1 << BIT_RECEIVER
        if not loop_ok:
            f |= 1 << BIT_LOOP
        if not battery_ok:
            f |= 1 << BIT_BATTERY
        if not self.storage_ok:
            f |= 1 << BIT_STORAGE
        if not calibrated:
            f |= 1 << BIT_CALIBRATION
        if self.board_faults:
            f |= 1 << BIT_BOARD
        if not self.params_ok:
            f |= 1 << BIT_PARAMS
        if not self.tasks_ok:
            f |= 1 << BIT_TASKS
        self.flags = f
        self.runs += 1
        return f

    def blocks_arming(self):
        return (self.flags & BLOCKING) != 0

    def names(self):
        """Names of the failing checks, lowest bit first (empty list: all good)."""
        out = []
        for i in range(len(CHECK_NAMES)):
            if self.flags & (1 << i):
                out.append(CHECK_NAMES[i])
        return out

    def sentences(self):
        out = []
        for i in range(len(CHECK_SENTENCES)):
            if self.flags & (1 << i):
                out.append(CHECK_SENTENCES[i])
        return out
