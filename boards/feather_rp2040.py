# Adafruit Feather RP2040, CircuitPython: LIS3DH on the STEMMA QT / board.I2C() bus.
import supervisor
import time

from acal.logger.app import MsTicksClock

RUNTIME = "circuitpython"
ARCH = None          # CircuitPython runs the sources (its .mpy format differs from MicroPython's)
I2C_ADDRESS = 0x18
TEMP_REF_C = None


def i2c():
    import board
    from acal.logger.lis3dh_cp import BusioRegisters
    return BusioRegisters(board.I2C(), I2C_ADDRESS)


def _sleep_us(us):
    # CircuitPython sleeps in float seconds; its floats are immediate objects (30 bits, like
    # its small ints), so this allocates nothing.  (The board file is not device/: not integer-only.)
    time.sleep(us / 1000000)


# CircuitPython has no time.ticks_us: the app's time from supervisor.ticks_ms() (wraps at 2^29 ms;
# time.monotonic_ns() would allocate a long int at every read)
clock = MsTicksClock(supervisor.ticks_ms, _sleep_us)
