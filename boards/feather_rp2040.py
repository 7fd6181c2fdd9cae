# Adafruit Feather RP2040, CircuitPython: the LIS3DH on board.SPI() (SCK GP18 -> SPC, MO GP19 ->
# SDA/SDI, MI GP20 <- SDO/SA0) with CS on D5 (GP7), or on the STEMMA QT / board.I2C() bus (SDA
# GP2, SCL GP3, CS tied high).  BUS: "auto" (SPI when the LIS3DH answers there, else I2C: a board
# wired for either works unchanged), "spi" or "i2c"; the app's bus setting (deploy --bus) wins.
import supervisor
import time

from acal.logger.app import MsTicksClock

RUNTIME = "circuitpython"
ARCH = None          # CircuitPython runs the sources (its .mpy format differs from MicroPython's)
BUS = "auto"
I2C_ADDRESS = 0x18
TEMP_REF_C = None

_spi = None


def i2c():
    import board
    from acal.logger.lis3dh_cp import BusioRegisters
    return BusioRegisters(board.I2C(), I2C_ADDRESS)


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
