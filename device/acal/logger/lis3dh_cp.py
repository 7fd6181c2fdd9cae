# The LIS3DH on CircuitPython: adafruit_lis3dh finds and identifies the chip (what it does well),
# and samples are read as raw integers through the same register code as lis3dh.LIS3DH, over
# busio via adafruit_bus_device (no floats, no per-sample allocation); the FIFO's codes convert
# through two tables (FifoTables: CircuitPython has no emitters for lis3dh.fifo_codes_q10).
# Only CircuitPython boards get this module (board/deploy.py CIRCUITPYTHON_ONLY).
from array import array

from acal.core.fixed import DITHER_STEP, DITHER_MASK
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
    """lis3dh_spi.SPIRegisters's calls over a busio.SPI and a chip-select digitalio pin, through
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


def fifo_tables(mid, so, top):
    """fifo_codes_q10's conversion of a 10-bit FIFO code u (0..1023, the code r read unsigned:
    r + 1024 when negative) as two tables: v0[u], the value with the carry of the dither's
    rounding not taken, clamped to +-top, and carry[u], the least doubled dither 2d (0..32766)
    that adds 1; 32768 (never) where the clamp absorbs it.  With A = (8 r + mid) so = 32768 q +
    m (m in 0..32767): (A + 2d) >> 15 is q + 1 when m + 2d >= 32768, else q (m + 2d < 65536)."""
    v0 = array("h", bytearray(2048))
    carry = array("H", bytearray(2048))
    for u in range(1024):
        a = ((u - 1024 if u & 512 else u) * 8 + mid) * so    # < 8.3e8 < 2**30 (fifo_codes_q10)
        q = a >> 15
        lo = -top if q < -top else (top if q > top else q)
        hi = -top if q + 1 < -top else (top if q + 1 > top else q + 1)
        v0[u] = lo
        carry[u] = 32768 if hi == lo else 32768 - (a - (q << 15))
    return v0, carry


def fifo_codes_table(b, i, end, out, at, v0, carry, dith):
    # fifo_codes_q10 through fifo_tables' tables (i, end multiples of 3): the code's top 10 bits
    # read unsigned as the index, a sample's three values unrolled (CircuitPython's bytecode:
    # 1.9 ms for 25 samples on the emulated Feather, against 2.25 ms without the tables)
    step = DITHER_STEP    # locals: the loop looks up no global
    mask = DITHER_MASK
    j = 2 * i
    end += at - i
    while at < end:
        d2 = dith << 1
        u = (b[j] >> 6) | (b[j + 1] << 2)
        out[at] = v0[u] + (d2 >= carry[u])
        u = (b[j + 2] >> 6) | (b[j + 3] << 2)
        out[at + 1] = v0[u] + (d2 >= carry[u])
        u = (b[j + 4] >> 6) | (b[j + 5] << 2)
        out[at + 2] = v0[u] + (d2 >= carry[u])
        at += 3
        j += 6
        dith = (dith + step) & mask
    return dith


class FifoTables:
    """A configuration's FIFO conversion through fifo_tables' two tables (v0, carry: 4 kB, made
    once): convert(b, i, end, out, at, dith) is lis3dh.fifo_codes_q10's, the same values and the
    next sample's dither, for a port without emitters (LIS3DH.use_fifo_tables).  mid, so, top:
    fifo_codes_q10's."""

    def __init__(self, mid, so, top):
        self.v0, self.carry = fifo_tables(mid, so, top)

    def convert(self, b, i, end, out, at, dith):
        return fifo_codes_table(b, i, end, out, at, self.v0, self.carry, dith)
