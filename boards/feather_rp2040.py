# Adafruit Feather RP2040, CircuitPython: the LIS3DH on board.SPI() (SCK GP18 -> SPC, MO GP19 ->
# SDA/SDI, MI GP20 <- SDO/SA0) with CS on D5 (GP7), or on the STEMMA QT bus (board.SCL GP3,
# board.SDA GP2, CS tied high) at I2C_FREQ.  BUS: "auto" (SPI when the LIS3DH answers there, else
# I2C: a board wired for either works unchanged), "spi" or "i2c"; the app's bus setting (deploy
# --bus) wins.  I2C runs at 400 kHz, the LIS3DH's fast mode (DocID17530 Rev 2, 2.4.2 Table 8
# "I2C slave timing values": f(SCL) 0-400 kHz), as boards/pico.py: board.I2C() would give
# CircuitPython's shared singleton at a fixed 100 kHz (shared-module/board/__init__.c), and
# busio.I2C polls each transfer awake, so 4x the bus time is 4x the core awake for it.
import supervisor
import time

from acal.logger.app import MsTicksClock

RUNTIME = "circuitpython"
ARCH = None          # CircuitPython runs the sources (its .mpy format differs from MicroPython's)
BUS = "auto"
I2C_ADDRESS = 0x18
I2C_FREQ = 400000
TEMP_REF_C = None
# CircuitPython has no viper: the FIFO's codes convert through two tables the driver builds once
# (4 kB of heap; 1.9 ms a drain of 25 samples on the emulated Feather, 3.1 ms without)
FIFO_TABLES = True

_spi = None
_i2c = None
_i2c_bus = None


def i2c_bus():
    """The STEMMA QT bus, a busio.I2C at I2C_FREQ: one object for the board's life, as spi()'s
    (busio.I2C claims SCL/SDA, which cannot be claimed twice: a retried set-up asks again);
    nothing else may then use board.I2C().  Another driver on the same bus takes this one."""
    global _i2c_bus
    if _i2c_bus is None:
        import board
        import busio
        _i2c_bus = busio.I2C(board.SCL, board.SDA, frequency=I2C_FREQ)
    return _i2c_bus


def i2c():
    global _i2c
    if _i2c is None:
        from acal.logger.lis3dh_cp import BusioRegisters
        _i2c = BusioRegisters(i2c_bus(), I2C_ADDRESS)
    return _i2c


def spi():
    # one object for the board's life: D5 cannot be claimed twice (a retried set-up asks again)
    global _spi
    if _spi is None:
        import board
        import digitalio
        from acal.logger.lis3dh_cp import BusioSPIRegisters
        _spi = BusioSPIRegisters(board.SPI(), digitalio.DigitalInOut(board.D5))
    return _spi


def sensor_bus(bus=None):
    """The LIS3DH's register bus: bus, or BUS when None (lis3dh.open_bus)."""
    from acal.logger.lis3dh import open_bus
    return open_bus(bus or BUS, spi, i2c)


def _sleep_us(us):
    # CircuitPython sleeps in float seconds; its floats are immediate objects (30 bits, like
    # its small ints), so this allocates nothing.  (The board file is not device/: not integer-only.)
    time.sleep(us / 1000000)


# CircuitPython has no time.ticks_us: the app's time from supervisor.ticks_ms() (wraps at 2^29 ms;
# time.monotonic_ns() would allocate a long int at every read)
clock = MsTicksClock(supervisor.ticks_ms, _sleep_us)
