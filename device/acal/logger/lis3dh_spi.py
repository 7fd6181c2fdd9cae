# The LIS3DH's registers over SPI (DocID17530 6.2): machine.I2C's register calls
# (readfrom_mem_into, writeto_mem) over a machine.SPI and a chip-select Pin, for LIS3DH (lis3dh.py).
# Its own module so that a board with the chip on I2C loads none of it: the board files' spi()
# import SPIRegisters, and lis3dh.open_bus calls spi() for "spi" and "auto" only.  The CircuitPython
# driver's busio SPI (lis3dh_cp.BusioSPIRegisters) frames its first byte with the same
# lis3dh.spi_command.
from acal.logger.lis3dh import spi_command


class SPIRegisters:
    """machine.I2C's register calls over a 4-wire SPI (DocID17530 6.2, mode 3: CPOL = CPHA = 1,
    SPC up to 10 MHz): spi a machine.SPI (write, readinto), cs its chip-select Pin (an output,
    high between transactions).  A read is CS low, RW | MS | AD5:0, then the bytes clocked in,
    CS high; a write RW = 0, AD5:0, its byte.  The I2C sub-address's bit 7 (auto-increment)
    becomes MS; addr is ignored (the chip is chosen by cs).  No allocation per call: the first
    bytes go out of preallocated buffers.  SPI has no acknowledge: a board without the chip
    reads what MISO floats to, which check() refuses (WHO_AM_I)."""

    def __init__(self, spi, cs):
        self.spi = spi
        self.cs = cs
        self._cmd = bytearray(1)
        self._wr = bytearray(2)
        cs(1)

    def readfrom_mem_into(self, addr, memaddr, buf):
        self._cmd[0] = spi_command(memaddr, True)
        self._read_into(buf)

    def _read_into(self, buf):
        # CS low, the command out, buf clocked in, CS high.  Apart from readfrom_mem_into: with
        # its four arguments the try block made a frame of 13 words, which MicroPython takes
        # from the heap on every call (docs/method-and-formats.md "Frames").
        self.cs(0)
        try:
            self.spi.write(self._cmd)
            self.spi.readinto(buf)
        finally:
            self.cs(1)

    def writeto_mem(self, addr, memaddr, buf):
        if len(buf) != 1:
            raise ValueError("single-register writes only")
        w = self._wr
        w[0] = spi_command(memaddr, False)
        w[1] = buf[0]
        self.cs(0)
        try:
            self.spi.write(w)
        finally:
            self.cs(1)
