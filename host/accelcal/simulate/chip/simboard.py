# The virtual board's hardware in one object: a simulated LIS3DH fed by a stimulus file, on a fake
# machine.I2C (fault_per_mille of its transactions fail) and on a fake machine.SPI with its
# chip-select Pin (the chip's SPI front end; no faults), with a virtual clock.  MicroPython-
# compatible; boards/virtual.py, the tests and the bench build their boards from it.
from vbus import I2C, SPI, Pin
from vclock import Clock
from vlis3dh import SimLIS3DH, Stimulus

ADDRESS = 0x18


class SimBoard:
    I2C_ADDRESS = ADDRESS

    def __init__(self, stimulus_path, fault_per_mille=0, clock=None):
        self.clock = clock if clock is not None else Clock()
        self.chip = SimLIS3DH(Stimulus(stimulus_path), self.clock)
        self.bus = I2C({ADDRESS: self.chip}, fault_per_mille)
        self.spi_bus = SPI(self.chip)
        self.cs = Pin(self.chip)

    def i2c(self):
        return self.bus

    def exhausted(self):
        return self.chip.exhausted

    def has_supply(self):
        return self.chip.stim.has_supply

    def supply_mv(self):
        """The board's supply (mV) with the sample the chip converted last (a version-2
        stimulus: the simulated battery)."""
        return self.chip.stim.supply_mv
