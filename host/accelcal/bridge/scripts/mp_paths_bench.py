# `accelcal bench`: the device paths mp_bench.py and mp_fit_bench.py do not time, under the
# MicroPython unix port or on the emulated RP2040 (host/accelcal/studies/bench_chip.py runs it
# on both; studies/bench_circuitpython.py on CircuitPython).  argv (the unix port): a writable
# folder; on the chip, main('/', 1) is appended.
# Prints "key value" lines: import time, per-sample apply (base, the largest composed model),
# the log's append per record, the Processor (all the app does after acquisition) per sample,
# the heap free after the app starts with the largest model, and what the FIFO's conversion
# tables (a board file's FIFO_TABLES) take of it.
import gc
import os
import sys
import time

LARGEST = "base+temp_offset+temp_scale+drift+nonlinear"   # the largest model the device fits
N_APPLY = 1000
N_RECORDS = 200
N_FEED = 41 * 50


# CircuitPython has no ticks_us: monotonic_ns, whose read allocates a long (nothing here counts bytes)
ticks = getattr(time, "ticks_us", None) or (lambda: time.monotonic_ns() // 1000)


def us(t0):
    t = ticks()
    return time.ticks_diff(t, t0) if hasattr(time, "ticks_diff") else t - t0


class RegisterBus:
    """Just enough of an I2C bus for App to start: a LIS3DH's registers (WHO_AM_I answers 0x33)
    that keep what is written; no samples (App is not stepped here)."""

    def __init__(self):
        self.regs = bytearray(128)
        self.regs[0x0F] = 0x33

    def readfrom_mem_into(self, addr, reg, buf):
        reg &= 0x7F
        for i in range(len(buf)):
            buf[i] = self.regs[(reg + i) & 0x7F]

    def writeto_mem(self, addr, reg, buf):
        reg &= 0x7F
        for i in range(len(buf)):
            self.regs[(reg + i) & 0x7F] = buf[i]


class Board:
    I2C_ADDRESS = 0x18

    def __init__(self):
        self.bus = RegisterBus()
        if not hasattr(time, "ticks_us"):   # CircuitPython: the Feather board file's clock
            import supervisor
            from acal.logger.app import MsTicksClock
            self.clock = MsTicksClock(supervisor.ticks_ms, None)

    def i2c(self):
        return self.bus


def remove(names):
    for f in names:
        try:
            os.remove(f)
        except OSError:
            pass


def apply_us(cal, n, repeat):
    """The shortest of `repeat` timed runs (one on the chip: the emulator is deterministic)."""
    from array import array
    buf = array("i", [0] * (3 * n))
    best = 1 << 40
    for _ in range(repeat):
        for i in range(n):        # ~1 g on x, a little on y and z, varying
            buf[3 * i] = 1000 - (i % 50)
            buf[3 * i + 1] = -300 + (i % 7)
            buf[3 * i + 2] = 20 + (i % 13)
        t0 = ticks()
        cal.apply_samples(buf, 0, n)
        best = min(best, us(t0))
    return best


def processor_us(log, Processor, repeat):
    """The app's work per sample after acquisition (wear profile, base model, no calibration
    yet): N_FEED samples in blocks of 41 at 100 Hz, still in one orientation with +-3 LSB of
    noise, so rest segments close every 5 s, reach the bins and the log."""
    n = log.SAMPLES_PER_RECORD
    blocks = []
    s = 12345
    from array import array
    for b in range(N_FEED // n):
        buf = array("i", [0] * (3 * n))   # as a FIFO read gives it (the scans' typed pointer)
        for i in range(3 * n):
            s = (s * 1103515245 + 12345) & 0x7FFFFFFF
            buf[i] = (102, -205, 993)[i % 3] + (s >> 16) % 7 - 3
        blocks.append(buf)
    best = 1 << 40
    for _ in range(repeat):
        remove(("bench_log.bin",))
        lg = log.Log("bench_log.bin", 1 << 20)
        proc = Processor(lg, 100)
        t0 = ticks()
        for buf in blocks:
            proc.feed(buf, n)
        best = min(best, us(t0))
        lg.close()
    return best


def main(work, repeat):
    gc.collect()
    t0 = ticks()
    from acal.logger import app
    print("import_app_us", us(t0))
    from acal.core import effects
    from acal.logger import log
    from acal.core.calibration import Calibration
    from acal.core.fixed import C_TEMP, C_TIME
    print("apply_base_us_per_1000", apply_us(Calibration(()), N_APPLY, repeat) * 1000 // N_APPLY)
    cal = Calibration(effects.parse_model(LARGEST))
    cal.now[C_TEMP] = 5
    cal.now[C_TIME] = 100
    print("apply_largest_us_per_1000", apply_us(cal, N_APPLY, repeat) * 1000 // N_APPLY)
    os.chdir(work)
    remove(("bench_log.bin",))
    lg = log.Log("bench_log.bin", 1 << 20)
    t0 = ticks()
    for i in range(N_RECORDS):
        lg.write(log.REST, i, 65536, -300, 20, 5, 0, 3)   # flushed: as the app's log
    lg.flush()
    print("log_rest_us_per_1000", us(t0) * 1000 // N_RECORDS)
    lg.close()
    remove(("bench_log.bin",))
    gc.collect()   # a collection owed by what ran before is not the processor's cost
    print("processor_us_per_1000", processor_us(log, app.Processor, repeat) * 1000 // N_FEED)
    remove(("bench_log.bin", "log.bin", "cal_a.bin", "cal_b.bin"))
    cal = None
    lg = None
    gc.collect()
    before = gc.mem_free()
    print("heap_free_before_app", before)
    a = app.App(Board(), model=LARGEST)
    gc.collect()
    print("heap_total", gc.mem_free() + gc.mem_alloc())
    print("heap_free_app_largest", gc.mem_free())
    # what the FIFO's conversion tables add to it where a board file says FIFO_TABLES (as
    # boards/feather_rp2040.py): the app's driver builds them (LIS3DH(tables=True) does so);
    # their code's module is loaded first, as the Feather's board file has it (its bus registers)
    import acal.logger.lis3dh_cp  # noqa: F401
    gc.collect()     # the prints' garbage
    free = gc.mem_free()
    a.sensor.use_fifo_tables()
    gc.collect()
    print("fifo_tables_bytes", free - gc.mem_free())
    a.log.close()
    remove(("log.bin", "cal_a.bin", "cal_b.bin"))


if len(sys.argv) > 1:
    main(sys.argv[1], 5)
