# The LIS3DH on CircuitPython: adafruit_lis3dh finds and identifies the chip (what it does well),
# and samples are read as raw integers through the same register code as lis3dh.LIS3DH, over
# busio via adafruit_bus_device (no floats, no per-sample allocation).
from acal.logger.lis3dh import LIS3DH, ADDRESS, LIS3DHError, spi_command

SPI_BAUD = 10000000    # the LIS3DH's fastest SPC (DocID17530's SPI timing: fc(SPC) <= 10 MHz)


class BusioRegisters:
    """machine.I2C-style register calls (readfrom_mem_into, writeto_mem) over a busio.I2C."""

    def __init__(self, i2c, address):
        from adafruit_bus_device.i2c_device import I2CDevice
        self.device = I2CDevice(i2c, address)
        self._reg = bytearray(1)
        self._reg_val = bytearray(2)

    def readfrom_mem_into(self, addr, memaddr, buf):
        self._reg[0] = memaddr
        with self.device as d:
            d.write_then_readinto(self._reg, buf)

    def writeto_mem(self, addr, memaddr, buf):
        if len(buf) != 1:
            raise ValueError("single-register writes only")
        self._reg_val[0] = memaddr
        self._reg_val[1] = buf[0]
        with self.device as d:
            d.write(self._reg_val)


class BusioSPIRegisters:
    """lis3dh.SPIRegisters's calls over a busio.SPI and a chip-select digitalio pin, through
    adafruit_bus_device's SPIDevice (it locks and configures the bus, mode 3, and drives CS
    around each transaction)."""

    def __init__(self, spi, cs, baudrate=SPI_BAUD):
        from adafruit_bus_device.spi_device import SPIDevice
        self.device = SPIDevice(spi, cs, baudrate=baudrate, polarity=1, phase=1)
        self._cmd = bytearray(1)
        self._wr = bytearray(2)

    def readfrom_mem_into(self, addr, memaddr, buf):
        self._cmd[0] = spi_command(memaddr, True)
        with self.device as spi:
            spi.write(self._cmd)
            spi.readinto(buf)

    def writeto_mem(self, addr, memaddr, buf):
        if len(buf) != 1:
            raise ValueError("single-register writes only")
        self._wr[0] = spi_command(memaddr, False)
        self._wr[1] = buf[0]
        with self.device as spi:
            spi.write(self._wr)


def make(i2c, address=ADDRESS, **settings):
    """An LIS3DH (lis3dh.LIS3DH API) on a busio.I2C; settings as lis3dh.LIS3DH."""
    import adafruit_lis3dh
    try:
        adafruit_lis3dh.LIS3DH_I2C(i2c, address=address)  # probes the bus, checks WHO_AM_I
    except (ValueError, RuntimeError) as e:
        raise LIS3DHError(str(e))
    return LIS3DH(BusioRegisters(i2c, address), address, **settings)
