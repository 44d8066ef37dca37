"""IMU detection at boot: which known chip answers on an I2C bus (Betaflight's gyro detect).

Takes an I2C bus and the board's mounting; gives the first driver whose chip answers and
configures, or None. It sits beside the drivers rather than in drivers/imu.py, their shared
base, because it imports every driver and each driver imports that base: kept there it made
an import circle. Boot only; `boards/rp2/board.py` calls it for `imu_type = auto`.
"""

from hoverfly.drivers.bno055 import BNO055
from hoverfly.drivers.lsm9ds1 import LSM9DS1
from hoverfly.drivers.mpu6050 import MPU6050


def detect_i2c(bus, orientation, delay_us=None):
    """The first known IMU answering on an I2C bus, configured, or None.

    Tries MPU-6050 (0x68, 0x69), LSM9DS1 (AG 0x6B/0x6A), BNO055 (0x28, 0x29) with each
    driver's default configuration.
    """
    candidates = (
        (MPU6050, 0x68), (MPU6050, 0x69),
        (LSM9DS1, 0x6B), (LSM9DS1, 0x6A),
        (BNO055, 0x28), (BNO055, 0x29),
    )
    for cls, address in candidates:
        imu = cls(bus, orientation, address=address, delay_us=delay_us)
        if imu.probe() and imu.configure():
            return imu
    return None
