# Fake I2C and SPI buses in front of simulated devices, MicroPython-compatible.
#
#   I2C       - the machine.I2C API the device driver uses (readfrom_mem_into, writeto_mem, ...)
#   BusioI2C  - the busio.I2C API CircuitPython drivers use (try_lock, writeto, readfrom_into,
#               writeto_then_readfrom), so the real adafruit_lis3dh runs on the simulated chip.
#   SPI, Pin  - machine.SPI (write, readinto, write_readinto) and a chip-select machine.Pin in
#               front of one device's SPI front end (spi_select, spi_byte: vlis3dh.py), byte by
#               byte; BusioSPI and DigitalInOut the same for busio.SPI and digitalio.  SPI has
#               no acknowledge, so no faults are drawn: a transfer with CS high reads 0.
#
# Fault injection: with fault_per_mille > 0, that share of transactions fails with OSError(EIO)
# before reaching the device (like a NACK in the address phase), so a retry is side-effect free.
# Faults come from a seeded generator: a run is reproducible.  It is Lehmer's, x <- a x mod m
# with m = 2**30 - 35 (prime) and a = 16808 (a primitive root: period m - 1), computed by
# Schrage's method so that every int stays below 2**30: the bus allocates nothing on a 32-bit
# port.
EIO = 5
ENODEV = 19
_M = 1073741789   # 2**30 - 35
_A = 16808
_Q = 63882        # _M // _A
_R = 13133        # _M % _A, < _Q: a (x mod q) and r (x div q) stay below _M


class _Bus:
    def __init__(self, devices, fault_per_mille=0, seed=1):
        self.devices = devices  # {address: device with read(reg, buf, start, end) / write(...)}
        self.fault_per_mille = fault_per_mille
        self.state = seed % _M or 1
        self.transactions = 0
        self.faults = 0

    def _device(self, addr):
        self.transactions += 1
        dev = self.devices.get(addr)
        if dev is None:
            raise OSError(ENODEV)
        if self.fault_per_mille:
            x = self.state
            x = _A * (x % _Q) - _R * (x // _Q)
            if x <= 0:
                x += _M
            self.state = x
            if x % 1000 < self.fault_per_mille:
                self.faults += 1
                raise OSError(EIO)
        return dev

    def scan(self):
        return sorted(self.devices)


class I2C(_Bus):
    """machine.I2C, the calls a register-based driver makes."""

    def readfrom_mem_into(self, addr, memaddr, buf, addrsize=8):
        self._device(addr).read(memaddr, buf, 0, len(buf))

    def readfrom_mem(self, addr, memaddr, nbytes, addrsize=8):
        buf = bytearray(nbytes)
        self.readfrom_mem_into(addr, memaddr, buf)
        return bytes(buf)

    def writeto_mem(self, addr, memaddr, buf, addrsize=8):
        self._device(addr).write(memaddr, buf, 0, len(buf))


class _BusioLock:
    """busio's bus lock: try_lock() before a transfer, unlock() after (both fakes share it)."""
    locked = False

    def try_lock(self):
        if self.locked:
            return False
        self.locked = True
        return True

    def unlock(self):
        self.locked = False


class BusioI2C(_BusioLock, _Bus):
    """busio.I2C: a write of one byte sets the register pointer; reads continue from it."""

    def __init__(self, devices, fault_per_mille=0, seed=1):
        _Bus.__init__(self, devices, fault_per_mille, seed)
        self.pointer = {}
        self.locked = False

    def writeto(self, addr, buf, start=0, end=None):
        dev = self._device(addr)
        end = len(buf) if end is None else end
        if end - start <= 0:
            return  # the address probe
        self.pointer[addr] = buf[start]
        if end - start > 1:
            dev.write(buf[start], buf, start + 1, end)

    def readfrom_into(self, addr, buf, start=0, end=None):
        dev = self._device(addr)
        end = len(buf) if end is None else end
        dev.read(self.pointer.get(addr, 0), buf, start, end)

    def writeto_then_readfrom(self, addr, out_buf, in_buf, out_start=0, out_end=None,
                              in_start=0, in_end=None):
        self.writeto(addr, out_buf, out_start, out_end)
        self.readfrom_into(addr, in_buf, in_start, in_end)


class Pin:
    """A chip-select machine.Pin (pin(v), pin.value(v)) and digitalio.DigitalInOut (.value,
    switch_to_output) in one: writing 0 selects the device's SPI front end."""

    def __init__(self, device, value=1):
        self.device = device
        self._v = 1
        Pin.value(self, value)

    def value(self, v=None):
        if v is None:
            return self._v
        v = 1 if v else 0
        if v != self._v:
            self._v = v
            self.device.spi_select(v == 0)

    __call__ = value

    def switch_to_output(self, value=False, drive_mode=None):
        self.value(value)


class DigitalInOut(Pin):
    """digitalio.DigitalInOut: .value is a property."""

    def __init__(self, device, value=1):
        Pin.__init__(self, device, value)

    @property
    def value(self):
        return self._v == 1

    @value.setter
    def value(self, v):
        Pin.value(self, v)

    def switch_to_output(self, value=False, drive_mode=None):
        Pin.value(self, value)


class SPI:
    """machine.SPI in front of one device (its chip select is a Pin on the same device)."""

    def __init__(self, device):
        self.device = device
        self.transfers = 0

    def write(self, buf):
        self.transfers += 1
        for i in range(len(buf)):      # indexed: an iterator would allocate
            self.device.spi_byte(buf[i])

    def readinto(self, buf, write=0):
        self.transfers += 1
        for i in range(len(buf)):
            buf[i] = self.device.spi_byte(write)

    def write_readinto(self, out, into):
        self.transfers += 1
        for i in range(len(out)):
            into[i] = self.device.spi_byte(out[i])


class BusioSPI(_BusioLock, SPI):
    """busio.SPI: locked and configured (as adafruit_bus_device's SPIDevice does) around
    transfers of a slice [start:end]."""

    def __init__(self, device):
        SPI.__init__(self, device)
        self.locked = False
        self.mode = (0, 0)
        self.baudrate = 100000

    def configure(self, baudrate=100000, polarity=0, phase=0, bits=8):
        self.baudrate = baudrate
        self.mode = (polarity, phase)

    def write(self, buf, start=0, end=None):
        SPI.write(self, memoryview(buf)[start:len(buf) if end is None else end])

    def readinto(self, buf, start=0, end=None, write_value=0):
        SPI.readinto(self, memoryview(buf)[start:len(buf) if end is None else end], write_value)
