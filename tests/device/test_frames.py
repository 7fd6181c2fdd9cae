"""The acquisition path takes no call frame from the heap (docs/method-and-formats.md "Frames").

MicroPython takes a bytecode call's frame (its locals and value stack) from the heap when it is
larger than 11 words (py/objfun.c fun_bc_call, VM_MAX_STATE_ON_STACK) and frees it on return;
under heap_lock it goes on the C stack instead, so the heap_lock tests (test_heap.py,
test_app.py) cannot see it.  Each such call makes the allocator scan for room, and on the
emulated Pico that scan was 30 % of the Processor's cycles a sample, more or less by what the
heap held (docs/notes/boards-and-logs.md).  micropython.mem_total() counts every byte ever
allocated, freed or not: here it must not move over a FIFO drain (the chip on I2C and on SPI), a
sample read from the output registers, a block fed to the Processor or a block's calibrated
output, under the real MicroPython (the unix port, the hot loops viper as on a board:
runtime.emitted_device_dir), the 5 s rest segment never ending within them (a segment's end and
a fit's slices are per segment or per fit, not per sample; the bins' readiness is computed at
the first block, then kept until a segment's end changes them)."""
from accelcal.bridge import runtime

FRAMES_SCRIPT = r'''
import micropython
from array import array
from acal.core import effects
from acal.core.calibration import Calibration
from acal.logger import log
from acal.logger.processor import Processor
from acal.logger.app import App

total = micropython.mem_total


def small(a, b, c):
    return a + b + c


def large(a, b, c):     # a frame of 12 words: the control, taken from the heap
    d = a + b
    e = b + c
    f = a + c
    g = d + e
    h = e + f
    i = f + g
    return small(d + e, f + g, h + i)


# Every fake below keeps its frames small, or it would count itself.
class Clock:
    def __init__(self):
        self.t = 0

    def ticks_us(self):
        return self.t

    def ticks_diff(self, a, b):
        return a - b

    def sleep_us(self, us):
        self.t += us

    def sleep_ms(self, ms):
        self.t += 1000 * ms


class Bus:
    """A LIS3DH whose FIFO fills at the clock's rate (100 Hz) with still samples (codes 0)."""

    def __init__(self, clock):
        self.regs = bytearray(128)
        self.regs[0x0F] = 0x33     # WHO_AM_I
        self.clock = clock
        self.read = 0              # samples read from the FIFO so far

    def readfrom_mem_into(self, addr, reg, buf):
        reg &= 0x7F
        if reg == 0x2F:            # FIFO_SRC_REG: the level, WTM set
            buf[0] = 0x80 | min(self.clock.t // 10000 - self.read, 31)
        elif reg == 0x28 and len(buf) > 6:   # OUT_X_L, the FIFO's samples
            self.read += len(buf) // 6
        else:
            buf[0] = self.regs[reg]

    def writeto_mem(self, addr, reg, buf):
        self.regs[reg & 0x7F] = buf[0]


class SPI:
    """The same chip behind machine.SPI's calls (write the command byte, then readinto)."""

    def __init__(self, clock):
        self.bus = Bus(clock)
        self.reg = 0

    def write(self, b):
        self.reg = b[0] & 0x3F
        if len(b) > 1:
            self.bus.regs[self.reg] = b[1]

    def readinto(self, buf):
        self.bus.readfrom_mem_into(0x18, self.reg, buf)


def cs(level):
    pass


class Board:
    I2C_ADDRESS = 0x18

    def __init__(self):
        self.clock = Clock()
        self.bus = Bus(self.clock)

    def i2c(self):
        return self.bus


class SPIBoard(Board):
    def sensor_bus(self, bus):
        from acal.logger.lis3dh_spi import SPIRegisters
        return SPIRegisters(SPI(self.clock), cs)


# each measured at its call, bytes in a preallocated array: nothing else allocates between
taken = array("i", [0] * 128)
t = total()
small(1, 2, 3)
taken[0] = total() - t
t = total()
large(1, 2, 3)
taken[1] = total() - t
print("control", taken[0], taken[1])
n = log.SAMPLES_PER_RECORD

# the FIFO drained over I2C and over SPI, and (fifo=False) one sample a step from the output
# registers at 25 Hz; after the first block (the bins' readiness is computed once, then kept
# until they change: a segment's end)
for name, board, fifo, rate, most in (("drains", Board(), True, 100, 450),
                                      ("spi", SPIBoard(), True, 100, 450),
                                      ("registers", Board(), False, 25, 120)):
    app = App(board, rate_hz=rate, capture_bytes=0, fifo=fifo)
    while app.samples <= n:       # the first steps and block: what a first call makes, made
        app.step()
    k = 0
    while app.samples < most:     # within the first 5 s segment
        t = total()
        app.step()
        taken[k] = total() - t
        k += 1
    print(name, k, app.proc.pipe.rest.segments, max(taken[:k]), sum(taken[:k]))

proc = Processor(log.Log("frames_log.bin", 1 << 16), 100)
block = array("i", [0] * (3 * n))
for i in range(3 * n):
    block[i] = (i * 37) % 11 - 5 + (1024 if i % 3 == 2 else 0)
proc.feed(block, n)
for k in range(10):
    t = total()
    proc.feed(block, n)
    taken[k] = total() - t
print("feeds", 10, proc.pipe.rest.segments, max(taken[:10]), sum(taken[:10]))

out = array("i", [0] * (3 * n))
for kinds in ((), (effects.TEMP_OFFSET, effects.DRIFT, effects.NONLINEAR)):
    cal = Calibration(kinds)
    cal.apply_samples(out, 0, n, block)
    for k in range(5):
        t = total()
        cal.apply_samples(out, 0, n, block)
        taken[k] = total() - t
    print("apply", len(kinds), max(taken[:5]))
'''


def test_acquisition_takes_no_frame_from_the_heap(tmp_path):
    script = tmp_path / "frames.py"
    script.write_text(FRAMES_SCRIPT)
    import os
    cwd = os.getcwd()
    os.chdir(tmp_path)
    try:
        out = runtime.run_micropython_script(str(script))
    finally:
        os.chdir(cwd)
    lines = {ln.split()[0] + (ln.split()[1] if ln.startswith("apply") else ""): ln.split()[1:]
             for ln in out.splitlines()}
    small, large = map(int, lines["control"])
    assert small == 0 and large >= 12 * 8, out      # the measure sees a frame of 12 words
    for reader in ("drains", "spi", "registers"):
        steps, segments, worst, whole = map(int, lines[reader])
        assert steps >= 14 and segments == 0, out
        assert worst == 0 and whole == 0, out
    feeds, segments, worst, whole = map(int, lines["feeds"])
    assert feeds == 10 and segments == 0, out
    assert worst == 0 and whole == 0, out
    assert lines["apply0"] == ["0", "0"] and lines["apply3"] == ["3", "0"], out
