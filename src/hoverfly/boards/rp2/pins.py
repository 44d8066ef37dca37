"""Raspberry Pi Pico / Pico 2 pin map for hoverfly (GPIO numbers; docs/pico.md draws it).

Every pin the rp2 board uses is named here once; `board.py` reads these and nothing
else hard-codes a GPIO. The choices keep each function on the peripheral that can
serve it: I2C0 on GP4/GP5 and SPI0 on GP16-19 (their default pads), UART1 for the
receiver (GP8 TX, GP9 RX), UART0 for the HC-05 Bluetooth link (GP0 TX, GP1 RX, seed 001),
four motor lines on GP10-GP13 (one PIO state machine each for DShot, or PWM slices
5A/5B/6A/6B for PWM/OneShot), receiver PWM/PPM inputs on GP2, GP3, GP6, GP7, GP14, GP15
(FS-IA6 channels 1-6, seed 001; PPM on the first), servos 0-3 on GP22, GP20, GP21, GP28, battery
voltage/current on ADC0/ADC1 (GP26/GP27) and the on-board LED on GP25.
"""

LED = 25  # on-board LED (Pico; the Pico W routes it through the radio: name "LED")

# IMU over I2C0 (MPU-6050 / BNO055 / LSM9DS1), 400 kHz: the MPU-6050's fastest (seed 000).
I2C_ID = 0
I2C_SDA = 4
I2C_SCL = 5
I2C_FREQ_HZ = 400000

# IMU over SPI0 (ICM-42688-P, seed 002): mode 3, up to 24 MHz on the chip; 10 MHz here.
SPI_ID = 0
SPI_SCK = 18
SPI_MOSI = 19
SPI_MISO = 16
SPI_CS = 17
SPI_BAUD_HZ = 10000000

# Serial receiver (CRSF 420000 8N1, SBUS 100000 8E2 inverted, iBUS 115200 8N1).
RX_UART_ID = 1
RX_TX = 8
RX_RX = 9
RX_BUF_BYTES = 1024  # the port's default 256 B is ~6 ms at 420 kbaud: too little for a late pass

# Maintenance link: HC-05 Bluetooth module on UART0, 115200 8N1 (seed 001).
MAINT_UART_ID = 0
MAINT_TX = 0
MAINT_RX = 1
MAINT_BAUD = 115200

# Motor outputs M1..M4 in Betaflight motor order (quad X: rear right, front right,
# rear left, front left).
MOTORS = (10, 11, 12, 13)

# PWM / PPM receiver inputs: channels 1..6 (PPM uses the first pin only).
RX_PWM = (2, 3, 6, 7, 14, 15)

# Servo outputs 0..3 (a tricopter's tail is servo 0; a plane's surfaces by its smix rules), PWM at
# servo_pwm_rate. GP22 is slice 3A, GP20/GP21 slice 2 (both servos: one rate), GP28 slice 6A, which it
# shares with motor 3 (GP12): a plane has one motor, and a multirotor with a PWM motor 3 drives at most
# the tail servo, so the two never meet.
SERVOS = (22, 20, 21, 28)
SERVO = SERVOS[0]

ADC_BATTERY = 26  # ADC0 through a divider
ADC_CURRENT = 27  # ADC1 from a current sensor
BATTERY_DIVIDER = 11.0  # 10 kΩ / 1 kΩ divider: 3S-4S packs stay under the ADC's 3.3 V
CURRENT_A_PER_V = 40.0  # a typical 40 A/V (25 mV/A) hall sensor


def describe():
    """One line per function: what is wired where (boot status, `hoverfly` docs)."""
    return (
        "imu i2c%d sda=GP%d scl=GP%d | spi%d sck=GP%d mosi=GP%d miso=GP%d cs=GP%d"
        % (I2C_ID, I2C_SDA, I2C_SCL, SPI_ID, SPI_SCK, SPI_MOSI, SPI_MISO, SPI_CS),
        "receiver uart%d rx=GP%d tx=GP%d | pwm/ppm GP%s" % (RX_UART_ID, RX_RX, RX_TX,
                                                           ",GP".join([str(p) for p in RX_PWM])),
        "motors GP%s | servos GP%s | led GP%d" % (",GP".join([str(p) for p in MOTORS]),
                                                 ",GP".join([str(p) for p in SERVOS]), LED),
        "hc-05 uart%d rx=GP%d tx=GP%d | battery adc GP%d, current GP%d"
        % (MAINT_UART_ID, MAINT_RX, MAINT_TX, ADC_BATTERY, ADC_CURRENT),
    )
