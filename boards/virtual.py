# Virtual board: the MicroPython unix port with a simulated LIS3DH (host/accelcal/sim) behind a
# fake machine.I2C.  `accelcal board virtual` puts the simulator on the path and sets
# ACCELCAL_STIMULUS (the wearer's signal) and ACCELCAL_BUS_FAULTS (per mille of failed
# transactions) and ACCELCAL_SPEED (0: virtual time runs as fast as the interpreter can; N: N times
# real time).  Time is virtual: it advances when the app sleeps.  The chip answers on I2C and on
# SPI; BUS (ACCELCAL_BUS, default "i2c") picks, as boards/pico.py's does.
import os

from simboard import SimBoard
from vclock import Clock

RUNTIME = "micropython"
ARCH = None          # runs the sources; no .mpy needed
I2C_ADDRESS = 0x18
TEMP_REF_C = None    # the simulated chip's reference is unknown to the board, as on a real one
BUS = os.getenv("ACCELCAL_BUS") or "i2c"

_hw = SimBoard(os.getenv("ACCELCAL_STIMULUS") or "stimulus.bin",
               int(os.getenv("ACCELCAL_BUS_FAULTS") or "0"),
               Clock(int(os.getenv("ACCELCAL_SPEED") or "0")))
clock = _hw.clock
chip = _hw.chip
bus = _hw.bus
i2c = _hw.i2c
exhausted = _hw.exhausted
if _hw.has_supply():   # a stimulus with the simulated battery: the board reads its supply
    supply_mv = _hw.supply_mv


def spi():
    from acal.logger.lis3dh_spi import SPIRegisters
    return SPIRegisters(_hw.spi_bus, _hw.cs)


def sensor_bus(bus=None):
    """The LIS3DH's register bus: bus, or BUS when None (lis3dh.open_bus)."""
    from acal.logger.lis3dh import open_bus
    return open_bus(bus or BUS, spi, i2c)
