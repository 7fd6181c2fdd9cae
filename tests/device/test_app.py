"""The device app on the simulated LIS3DH under CPython: bus faults and FIFO overruns are counted
and survived, lost samples are counted exactly (against the simulated chip's ground truth), the
samples fed on are the chip's samples at the right stream positions, and the host replay of the
capture reproduces the board's log bit for bit.  Under MicroPython, the acquisition path
allocates nothing per sample (heap locked)."""
import os
import sys

import numpy as np
import pytest

from accelcal.bridge import boardlog, runtime
from accelcal import simulate
from accelcal.simulate.stimulus import write_stimulus
from conftest import ROOT

from accelcal.locations import CHIP_DIR  # noqa: E402
sys.path.insert(0, str(CHIP_DIR))
from simboard import ADDRESS, SimBoard  # noqa: E402
from vbus import I2C  # noqa: E402
from vclock import Clock  # noqa: E402

from acal.core import fixed
from acal.logger import log  # noqa: E402
from acal.logger.app import App  # noqa: E402
from acal.core.profile import PAPER, WEAR  # noqa: E402

RATE = 25
TRUTH = np.array([1.02, 0.98, 1.01, 0.01, -0.01, 0.005, 0.03, -0.02, 0.04])


def stimulus(path, rng, n_rest=120, rest_s=8, move_s=4):
    """Rest at random orientations (1.6 mg noise) between moves whose acceleration changes by
    tens of mg from one sample to the next (so a sample read at the wrong position shows)."""
    parts = []
    for d in simulate.unit_points(rng, n_rest):
        v = simulate.uncorrect(TRUTH, d[None, :])[0]
        parts.append(v + rng.normal(scale=0.0016, size=(RATE * rest_s, 3)))
        parts.append(v + rng.normal(scale=0.3, size=(RATE * move_s, 3)))
    xyz = np.clip(np.concatenate(parts), -1.9, 1.9)
    write_stimulus(path, RATE, xyz, 30 + np.linspace(0, 3, len(xyz)))
    return xyz


class StallingClock(Clock):
    """Every `every`-th sleep the app is also busy for `stall_us` (a flash erase, say)."""

    def __init__(self, every, stall_us):
        super().__init__()
        self.calls = 0
        self.every = every
        self.stall_us = stall_us

    def sleep_us(self, us):
        self.calls += 1
        if self.every and self.calls % self.every == 0:
            us += self.stall_us
        super().sleep_us(us)


def board(stim_path, faults=0, clock=None):
    return SimBoard(str(stim_path), faults, clock)


def run_app(tmp_path, b, **settings):
    os.chdir(tmp_path)
    settings = {"rate_hz": RATE, "capture_bytes": 1 << 24, "recal_seconds": 600, **settings}
    app = App(b, **settings)
    app.run(10 ** 6)
    return app


def captured(tmp_path):
    cap = boardlog.read_capture(tmp_path)
    idx, xyz = [], []
    for blk in cap.blocks:
        if blk[0] == "samples":
            idx.append(blk[1] + np.arange(len(blk[3])))
            xyz.append(blk[3])
    return np.concatenate(idx), np.concatenate(xyz) / 1024.0


def compare(idx, got, xyz):
    """Captured sample i against the stimulus sample the chip converted for it: i + 1 (past the
    stimulus's end the chip holds its last input)."""
    return got - xyz[np.minimum(idx + 1, len(xyz) - 1)]


@pytest.fixture
def stim(tmp_path, rng):
    path = tmp_path / "stim.bin"
    return path, stimulus(path, rng)


def test_bus_faults_are_retried_counted_and_lost_samples_exact(tmp_path, stim):
    path, xyz = stim
    b = board(path, faults=150)  # 15 % of transactions fail: ~0.3 % of samples fail 3 times
    app = run_app(tmp_path, b, fifo=False)   # the output registers: a transaction a sample
    assert app.bus_errors == b.bus.faults > 1000
    assert app.lost > 0
    assert app.samples + app.lost == b.chip.generated  # every sample is read or counted lost
    # The samples were fed at their stream positions: sample i is the chip's sample i + 1
    # of the stimulus (12-bit registers: within 1 mg of rounding, 0.03 % of Q10 conversion).
    idx, got = captured(tmp_path)
    assert len(idx) == app.samples and len(np.unique(idx)) == len(idx)
    assert np.abs(compare(idx, got, xyz)).max() < 0.0016
    # The counters record says the same.
    counters = boardlog.decode(tmp_path / "log.bin").dicts(log.COUNTERS)[-1]
    assert (counters["samples"], counters["lost"], counters["bus_errors"]) == \
        (app.samples, app.lost, app.bus_errors)


def test_fifo_overruns_counted_and_lost_samples_exact(tmp_path, stim):
    path, xyz = stim
    clock = StallingClock(every=7, stall_us=3 * 10 ** 6)  # 3 s stall: 75 samples, FIFO holds 32
    b = board(path, faults=20, clock=clock)
    app = run_app(tmp_path, b, fifo=True)
    assert app.fifo_overruns > 0
    assert app.lost >= b.chip.dropped > 0
    assert app.samples + app.lost == b.chip.generated
    idx, got = captured(tmp_path)
    assert len(idx) == app.samples
    # The FIFO keeps 10 bits (4 mg steps, the HR digit's two low bits dropped); the driver reads
    # a code as the middle of its four digits: within 2 mg (and Q10's floor with a dither in
    # [0, 1) LSB, < 1 mg, fixed.DITHER_STEP), unbiased.
    err = compare(idx, got, xyz)
    assert np.abs(err).max() < 0.0031 and abs(err.mean()) < 0.0003


class TimedI2C(I2C):
    """machine.I2C whose transactions take their time on the virtual clock: 9 bits a byte at
    100 kHz (CircuitPython's board.I2C()), the chip answering at the transaction's start; a FIFO
    read of 25 samples takes 14 ms, over a third of a period at 25 Hz."""

    def __init__(self, devices, fault_per_mille, clock, us_per_byte=90):
        super().__init__(devices, fault_per_mille)
        self.clock = clock
        self.us_per_byte = us_per_byte

    def _take(self, nbytes):
        Clock.sleep_us(self.clock, (3 + nbytes) * self.us_per_byte)  # address, register, address

    def readfrom_mem_into(self, addr, memaddr, buf, addrsize=8):
        try:
            super().readfrom_mem_into(addr, memaddr, buf, addrsize)
        finally:
            self._take(len(buf))

    def writeto_mem(self, addr, memaddr, buf, addrsize=8):
        try:
            super().writeto_mem(addr, memaddr, buf, addrsize)
        finally:
            self._take(len(buf))


@pytest.mark.parametrize("stall_every", [0, 7])
def test_samples_converted_during_a_fifo_read_are_not_counted_lost(tmp_path, stim, stall_every):
    """A FIFO read takes bus time, and samples the chip converts meanwhile wait in the FIFO for
    the next read: the app counts lost exactly what the chip overwrote (none without stalls),
    and every sample goes in at its own stream position (a sample counted lost though it
    waited would shift every later one by one)."""
    path, xyz = stim
    clock = StallingClock(every=stall_every, stall_us=3 * 10 ** 6)
    b = board(path, clock=clock)
    b.bus = TimedI2C({ADDRESS: b.chip}, 20, clock)
    app = run_app(tmp_path, b, fifo=True)
    assert b.bus.faults > 0 and app.samples + app.lost <= b.chip.generated
    idx, got = captured(tmp_path)
    assert len(idx) == app.samples and idx[-1] == app.samples + app.lost - 1
    # each sample is the chip's FIFO code for the stimulus sample it converted, to the bit
    from test_pico_lis3dh import fifo_q10
    cap = np.round(got * 1024).astype(int)
    want = fifo_q10(xyz[np.minimum(idx + 1, len(xyz) - 1)])   # the driver read them in order
    off = np.any(cap != want, axis=1)
    assert app.lost == b.chip.dropped and (app.fifo_overruns > 0) == (stall_every > 0)
    # Except where the FIFO was full: a sample the chip converts between the level's read and
    # the FIFO's overwrites the oldest, so that drain's samples are one later than counted
    # (its loss is counted at the next drain).
    late = fifo_q10(xyz[np.minimum(idx[off] + 2, len(xyz) - 1)], np.flatnonzero(off))
    assert np.array_equal(cap[off], late)
    print(f"\n{app.fifo_overruns} overruns, {app.lost} lost, {off.sum()} samples one late")
    assert off.sum() <= 32 * app.fifo_overruns // 2
    # and the case is met: with whole-ms waits (the app's sleep_ms) the drains fall at varying
    # phases of the chip's conversions (490 one late in 144 full drains).  While the app slept
    # in exact sleep_us on this virtual clock every drain fell at the same phase, clear of a
    # conversion, and none was ever late: the check above could not fail.
    assert (off.sum() > 0) == (stall_every > 0)


def test_replay_reproduces_the_boards_log(tmp_path, stim):
    path, _ = stim
    b = board(path, faults=150, clock=StallingClock(every=500, stall_us=400000))
    app = run_app(tmp_path, b)
    assert app.lost > 0 and app.proc.calibrations >= 1
    cals = boardlog.decode(tmp_path / "log.bin").dicts(log.CAL)
    ok = [c for c in cals if c["status"] == 0]
    p = np.array([ok[-1][n] for n in fixed.PARAM_NAMES]) / 2 ** 24
    assert np.abs(p - TRUTH).max() < 0.01  # the board calibrated itself near the truth
    r = boardlog.replay(tmp_path)
    assert r["identical"], r
    assert r["rest"]["board"] > 30 and r["cal"]["board"] == len(cals)


@pytest.mark.parametrize("prof", [PAPER, WEAR])
def test_replay_finds_a_changed_device_module(tmp_path, stim, monkeypatch, prof):
    path, _ = stim
    run_app(tmp_path, board(path), profile=prof)
    assert boardlog.replay(tmp_path)["identical"]
    if prof == PAPER:  # a "change" to the device code: one iteration fewer
        from acal.paper import optimiser
        real_begin = optimiser.Optimiser.begin
        monkeypatch.setattr(optimiser.Optimiser, "begin",
                            lambda self, pts, n, it, *a: real_begin(self, pts, n, it - 1, *a))
    else:  # a laxer convergence rule
        from acal.core import gaussnewton
        monkeypatch.setattr(gaussnewton, "CONVERGED_SHIFT", 4)
    r = boardlog.replay(tmp_path)
    assert not r["identical"] and r["cal"]["differ"] >= 1


HEAP_SCRIPT = r'''
import sys, os, micropython
from simboard import SimBoard
from acal.logger.app import App, BLOCK

os.chdir(sys.argv[2])
app = App(SimBoard(sys.argv[1]), rate_hz=25, capture_bytes=0, recal_seconds=600,
          fifo=sys.argv[-1] == "fifo")
most = 32 if app.fifo else 1   # samples a step can read

def work(n):  # the per-sample steps (a block flush, which logs, excluded) with the heap locked
    locked = 0
    while locked < n:
        if app.fill + most >= BLOCK:
            app.step()
            continue
        micropython.heap_lock()
        got = app.step()
        micropython.heap_unlock()
        locked += got
    return locked

try:
    k = work(5000)
    print("OK", k, app.samples, app.lost)
except MemoryError:
    micropython.heap_unlock()
    print("ALLOCATED", app.samples)
'''


@pytest.mark.parametrize("reader", ["fifo", "registers"])
def test_acquisition_allocates_nothing_per_sample_under_micropython(tmp_path, stim, reader):
    path, _ = stim
    script = tmp_path / "heap_app.py"
    script.write_text(HEAP_SCRIPT)
    sim = str(CHIP_DIR)
    out = runtime.run_micropython_script(str(script), str(path), str(tmp_path), reader,
                                         extra_path=[sim]).split()
    assert out[0] == "OK", out
    assert 5000 <= int(out[1]) < 5032 and int(out[3]) == 0


def test_acquisition_and_simulator_allocate_nothing_on_the_32_bit_port(tmp_path, stim, mp32):
    """Where ints past 2^30 allocate (the WebAssembly port, as an RP2040): the app's per-sample
    steps on the simulated chip (register reads: a step a sample, so 5000 locked steps span the
    wrap; the FIFO's drains are heap-checked on the unix port above), its clock started 100 s
    before the 2^30 us tick wrap, for 200 s at 25 Hz (past the 43 s where the chip's stimulus index used to leave 2^30): the app, the
    driver, the simulated chip, its bus and clock allocate nothing, and no sample is lost."""
    path, _ = stim
    script = tmp_path / "heap_app32.py"
    script.write_text(HEAP_SCRIPT.replace(
        "app = App(SimBoard(sys.argv[1]),",
        "from vclock import Clock, TICKS_PERIOD\n"
        "app = App(SimBoard(sys.argv[1], clock=Clock(0, TICKS_PERIOD - 100000000)),").replace(
        'print("OK", k, app.samples, app.lost)',
        'print("OK", k, app.samples, app.lost, app.board.clock.s, app.board.clock.ticks_us())'))
    sim = str(CHIP_DIR)
    out = mp32(str(script), str(path), str(tmp_path), "registers", extra_path=[sim]).split()
    assert out[0] == "OK", out
    assert int(out[1]) == 5000 and int(out[3]) == 0
    assert int(out[4]) * 10 ** 6 > (1 << 30) + 60 * 10 ** 6 and int(out[5]) < 200 * 10 ** 6  # wrapped


def test_the_millisecond_clock_allocates_nothing_on_the_32_bit_port(tmp_path, stim, mp32):
    """The app's per-sample steps with the clock of boards/feather_rp2040.py (MsTicksClock on a
    2^29 ms counter, started 100 s before its wrap) heap-locked on the 32-bit port: nothing
    allocated per tick, across the wrap, and no sample lost."""
    path, _ = stim
    script = tmp_path / "heap_ms32.py"
    script.write_text(HEAP_SCRIPT.replace(
        "app = App(SimBoard(sys.argv[1]),",
        "from vclock import Clock\n"
        "from acal.logger.app import MsTicksClock\n"
        "b = SimBoard(sys.argv[1], clock=Clock(0, %d))\n"
        "b.clock = MsTicksClock(lambda: b.chip.clock.ticks_ms() & %d, b.chip.clock.sleep_us)\n"
        "app = App(b," % (MS_WRAP * 1000 - 100 * 10 ** 6, MS_WRAP - 1)).replace(
        'print("OK", k, app.samples, app.lost)',
        'print("OK", k, app.samples, app.lost, app.board.clock._ms())'))
    out = mp32(str(script), str(path), str(tmp_path), extra_path=[str(CHIP_DIR)]).split()
    assert out[0] == "OK", out
    assert int(out[1]) == 5000 and int(out[3]) == 0
    assert int(out[4]) < 200 * 1000   # the counter wrapped

def test_fourteen_worst_case_days_fit_in_one_megabyte(tmp_path):
    """A wearer who rests 5 s in a new orientation every 5 s for 14 days (every rest segment
    differs, all of them logged were there no allowance), with hourly counters and calibrations
    every 6 h: the log stays within 1 MiB and refuses nothing."""
    from acal.logger.app import Processor, REST_BUDGET_BYTES
    rate = 1
    lg = log.Log(str(tmp_path / "log.bin"), 1 << 20)
    proc = Processor(lg, rate, recal_seconds=6 * 3600)
    rng = np.random.default_rng(5)
    dirs = simulate.uncorrect(TRUTH, simulate.unit_points(rng, 4000))
    q = np.rint(dirs * 1024).astype(int)
    block = [0] * 15
    counters = 0
    for seg in range(14 * 86400 // 5 - 1):  # up to the last sample of day 14
        x, y, z = q[seg % len(q)] + (seg // len(q))  # a new mean each time round
        # one digit of noise: still to the default profile's noise gauge (an exactly constant
        # segment is imputed data, not a sensor)
        block[0::3], block[1::3], block[2::3] = [x, x + 1] * 2 + [x], [y] * 5, [z] * 5
        proc.feed(block, 5)
        if proc.index // 3600 > counters:
            counters += 1
            lg.write(log.COUNTERS, proc.index, proc.index, 0, 0, 0, 0, 0, proc.rest_logged,
                     proc.rest_skipped)
    lg.close()
    size = (tmp_path / "log.bin").stat().st_size
    assert lg.refused == 0 and size <= 1 << 20
    assert proc.rest_skipped > 100000                    # the allowance did the work
    assert proc.rest_bytes <= REST_BUDGET_BYTES           # and held over the 14 days
    assert proc.calibrations >= 14 * 4 - 1


def test_circuitpython_board_path_logs_the_same(tmp_path, stim):
    """The CircuitPython board's bus (busio.I2C through adafruit_bus_device) and FIFO conversion
    (the tables its FIFO_TABLES asks for), as boards/feather_rp2040.py wires them, give the app
    the same samples, hence the same log; only a board that asks gets the tables."""
    from vbus import BusioI2C
    from acal.logger.lis3dh_cp import BusioRegisters
    path, _ = stim
    logs = []
    for name in ("machine", "busio"):
        d = tmp_path / name
        d.mkdir()
        b = board(path)
        if name == "busio":
            regs = BusioRegisters(BusioI2C({0x18: b.chip}), 0x18)
            b.i2c = lambda: regs
            b.FIFO_TABLES = True
        app = run_app(d, b)
        assert (app.sensor.fifo_tables is not None) == (name == "busio")
        logs.append(boardlog.decode(d / "log.bin"))
    for rtype in (log.REST, log.CAL):
        assert logs[0].of(rtype) == logs[1].of(rtype) and len(logs[0].of(rtype)) > 0
    b = board(path)
    b.FIFO_TABLES = True   # the output registers (fifo=False) convert no FIFO codes: no tables
    d = tmp_path / "registers"
    d.mkdir()
    os.chdir(d)
    assert App(b, rate_hz=RATE, fifo=False).sensor.fifo_tables is None


def test_setup_retries_bus_faults_and_says_why_when_the_chip_is_absent(tmp_path, stim):
    from acal.logger.lis3dh import LIS3DHError
    path, _ = stim
    b = board(path, faults=150)  # setup (8 transactions) often needs its retries
    os.chdir(tmp_path)
    retried = 0
    for seed in range(1, 40):
        b.bus.state = seed
        try:
            app = App(b, rate_hz=RATE)
        except LIS3DHError:
            continue
        retried += app.bus_errors > 0 and app.sensor is not None
    assert retried > 0
    b.bus.devices.clear()  # nothing at 0x18
    with pytest.raises(LIS3DHError, match="setup failed 3 times"):
        App(b, rate_hz=RATE)


SLICE_US = 5000  # what a fit slice is taken to cost (the RP2040 estimate's bound, README)


def test_the_sliced_fit_loses_no_sample_at_100_hz(tmp_path, rng, monkeypatch):
    """At 100 Hz with the FIFO, every fit slice charged SLICE_US of board time: the sliced fit
    loses nothing (no overrun, nothing lost) and still calibrates; the same fit run in one go
    (charged the same per slice) overruns the FIFO."""
    rate = 100
    parts = []
    for d in simulate.unit_points(rng, 60):
        v = simulate.uncorrect(TRUTH, d[None, :])[0]
        parts.append(v + rng.normal(scale=0.0016, size=(rate * 8, 3)))
        parts.append(v + rng.normal(scale=0.3, size=(rate * 2, 3)))
    path = tmp_path / "stim100.bin"
    write_stimulus(path, rate, np.clip(np.concatenate(parts), -1.9, 1.9), np.full(60 * 10 * rate, 30.0))
    from acal.core import pipeline
    real_step = pipeline.Pipeline.fit_step
    results = {}
    for mode in ("sliced", "one go"):
        b = board(path)

        def charged(self, b=b):
            b.clock.sleep_us(SLICE_US)  # the board is busy: time passes, the chip samples on
            return real_step(self)
        monkeypatch.setattr(pipeline.Pipeline, "fit_step", charged)
        if mode == "one go":
            from acal.logger import processor
            monkeypatch.setattr(processor, "FIT_STEPS_PER_FEED", 1 << 20)
        d = tmp_path / mode.replace(" ", "_")
        d.mkdir()
        app = run_app(d, b, rate_hz=rate, fifo=True, recal_seconds=60)
        results[mode] = app, b
    s, b = results["sliced"]
    assert s.proc.calibrations >= 2
    assert s.fifo_overruns == 0 and s.lost == 0
    # every sample of the stimulus read (past its end the chip samples on, holding its last
    # input, while the last step's fit slices run)
    assert 60 * 10 * rate <= s.samples < 60 * 10 * rate + 32
    one, _ = results["one go"]
    assert one.fifo_overruns > 0 and one.lost > 0


def test_replay_with_the_other_profile(tmp_path, stim):
    """replay --profile runs the capture through the other profile's settings: the board ran
    the paper's; the wear profile's replay differs and its calibration is nearer the truth."""
    path, _ = stim
    run_app(tmp_path, board(path), profile=PAPER)
    assert boardlog.replay(tmp_path)["identical"]
    other = boardlog.replay(tmp_path, "wear")
    assert not other["identical"] and other["profile"] == "wear"
    with_wear = boardlog.run_capture(tmp_path, tmp_path / "wear_log.bin", "wear")
    assert with_wear.pipe.fit == 1 and with_wear.calibrations >= 1
    p = np.array(with_wear.params) / 2 ** 24
    assert np.abs(p - TRUTH).max() < 0.005


def test_the_app_across_the_tick_wrap(tmp_path, stim):
    """Board ticks wrap at 2^30 us (17.9 min); the virtual clock's do too.  Started 5 min before
    a wrap, the app reads, loses and logs exactly what it does on a clock that starts at 0: no
    sample lost or counted twice, the same log."""
    from vclock import TICKS_PERIOD
    path, _ = stim
    runs = {}
    for name, start in (("plain", 0), ("wrapping", TICKS_PERIOD - 300 * 10 ** 6)):
        d = tmp_path / name
        d.mkdir()
        clock = StallingClock(every=500, stall_us=400000)   # stalls: samples lost, the same ones
        clock.set_us(start)
        b = board(path, faults=30, clock=clock)
        app = run_app(d, b)
        runs[name] = (app, b, (d / "log.bin").read_bytes(), (d / "capture.bin").read_bytes())
    app, b, log_bytes, cap = runs["wrapping"]
    plain, _, plain_log, plain_cap = runs["plain"]
    assert b.clock.now_us() > TICKS_PERIOD + 60 * 10 ** 6   # ran on well past the wrap
    assert app.samples + app.lost == b.chip.generated and app.lost > 0
    assert (app.samples, app.lost) == (plain.samples, plain.lost)
    assert cap == plain_cap and log_bytes == plain_log   # segments, means, calibrations alike


MS_WRAP = 1 << 29   # CircuitPython's supervisor.ticks_ms() wraps at 2^29 ms (6.2 days)


def ms_ticks_board(path, start_us, faults=30):
    """The virtual board with the clock boards/feather_rp2040.py gives the app: MsTicksClock on
    a millisecond counter that wraps at 2^29 (supervisor.ticks_ms, read off the virtual clock);
    the same stalls as the tick-wrap test."""
    from acal.logger.app import MsTicksClock
    clock = StallingClock(every=500, stall_us=400000)
    clock.set_us(start_us)
    b = board(path, faults=faults, clock=clock)
    b.clock = MsTicksClock(lambda: clock.ticks_ms() & (MS_WRAP - 1), clock.sleep_us)
    return b


@pytest.mark.parametrize("fifo", [False, True], ids=["registers", "fifo"])
def test_the_app_across_the_millisecond_counters_wrap(tmp_path, stim, fifo):
    """On CircuitPython the app's time comes from supervisor.ticks_ms(), which wraps at 2^29 ms.
    Started 5 min before that wrap, the app reads, loses and logs exactly what it does with the
    same counter started at 0, and what it does on the microsecond ticks (time.ticks_us) from
    0: the same samples, losses, capture and log (FIFO drains and fit slices alike)."""
    path, _ = stim
    runs = {}
    for name, start in (("us ticks", None), ("ms from 0", 0),
                        ("ms wrapping", MS_WRAP * 1000 - 300 * 10 ** 6)):
        d = tmp_path / name.replace(" ", "_")
        d.mkdir()
        if start is None:
            clock = StallingClock(every=500, stall_us=400000)
            b = board(path, faults=30, clock=clock)
        else:
            b = ms_ticks_board(path, start)
        app = run_app(d, b, fifo=fifo)
        runs[name] = (app, b, (d / "log.bin").read_bytes(), (d / "capture.bin").read_bytes())
    app, b, log_bytes, cap = runs["ms wrapping"]
    assert b.chip.clock.now_us() > MS_WRAP * 1000 + 600 * 10 ** 6   # ran on well past the wrap
    assert b.clock._ms() < 2000 * 1000                               # the counter did wrap
    assert app.samples + app.lost == b.chip.generated and app.lost > 0
    assert app.proc.calibrations >= 1
    for name in ("ms from 0", "us ticks"):
        other, _, other_log, other_cap = runs[name]
        assert (app.samples, app.lost, app.fifo_overruns) == \
            (other.samples, other.lost, other.fifo_overruns), name
        assert cap == other_cap and log_bytes == other_log, name


def test_the_millisecond_clock_against_the_modular_definitions(rng):
    """MsTicksClock's ticks_us (whole ms, wrapping at 2^30 us) read after random waits from
    random starts, across the 2^29 ms counter wrap: always (t // 1000 * 1000) mod 2^30, and
    its ticks_diff the true difference for waits below 2^29 us."""
    from acal.logger.app import MsTicksClock
    from vclock import TICKS_PERIOD
    for start in (0, MS_WRAP * 1000 - 5, MS_WRAP * 1000 - 123456789, 10 ** 15 + 999999):
        c = Clock(start_us=start)
        m = MsTicksClock(lambda: c.ticks_ms() & (MS_WRAP - 1), c.sleep_us)
        t = start
        base = m.ticks_us() - (t // 1000 * 1000)   # ticks_us starts at 0: an offset, kept
        prev = m.ticks_us()
        for us in list(rng.integers(1, 1 << 28, size=300)) + [1] * 50 + [999, 1000, 1001]:
            c.sleep_us(int(us))
            before = t
            t += int(us)
            now = m.ticks_us()
            assert 0 <= now < TICKS_PERIOD
            assert (now - base - t // 1000 * 1000) % TICKS_PERIOD == 0
            assert m.ticks_diff(now, prev) == t // 1000 * 1000 - before // 1000 * 1000
            prev = now


APP_LOG_SCRIPT = r'''
import sys, os
from simboard import SimBoard
from acal.logger.app import App
from acal.logger import log
os.chdir(sys.argv[2])
app = App(SimBoard(sys.argv[1], 100), rate_hz=25, capture_bytes=0, recal_seconds=600)
app.run(10 ** 6)
with open("log.bin", "rb") as f:
    data = f.read()
print(len(data), log.crc32(data), app.samples, app.lost, app.bus_errors, app.proc.calibrations)
'''


def test_the_apps_log_is_identical_on_every_runtime(tmp_path, stim, mp):
    """The app on the simulated chip (10 % bus faults, the wear profile's sliced fit) writes the
    same log.bin, byte for byte, under CPython and under each real MicroPython."""
    import subprocess
    path, _ = stim
    script = tmp_path / "app_log.py"
    script.write_text(APP_LOG_SCRIPT)
    sim = str(CHIP_DIR)
    work = [tmp_path / "cpython", tmp_path / mp]
    for w in work:
        w.mkdir()
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([sim, str(ROOT / "device")]))
    host = subprocess.run([sys.executable, str(script), str(path), str(work[0])], env=env,
                          capture_output=True, text=True, check=True).stdout.split()
    run = runtime.run_micropython_script if mp == "micropython" else runtime.run_micropython32_script
    got = run(str(script), str(path), str(work[1]), extra_path=[sim]).split()
    assert got == host
    assert int(host[3]) > 0 and int(host[5]) >= 1   # samples lost to faults, a calibration


def test_virtual_clock_ticks_match_the_modular_definitions(rng):
    """The 32-bit-safe clock (seconds + microseconds, wrapped tick counters kept beside them)
    against the plain definitions on unbounded ints: ticks_us = t mod 2^30, ticks_ms =
    floor(t / 1000) mod 2^30, ticks_diff in [-2^29, 2^29) congruent to a - b."""
    from vclock import TICKS_PERIOD
    half = TICKS_PERIOD >> 1
    for start in (0, TICKS_PERIOD - 5, TICKS_PERIOD * 1000 - 123456, 10 ** 12 + 999999):
        c = Clock(start_us=start)
        t = start
        for us in list(rng.integers(1, 1 << 29, size=200)) + [1] * 50 + [999999, 1000000, 1001]:
            c.sleep_us(int(us))
            t += int(us)
            assert c.now_us() == t
            assert c.ticks_us() == t % TICKS_PERIOD
            assert c.ticks_ms() == (t // 1000) % TICKS_PERIOD
    for a, b in list(rng.integers(0, TICKS_PERIOD, size=(2000, 2))) + [(0, half), (half, 0),
                                                                         (TICKS_PERIOD - 1, 0)]:
        d = Clock().ticks_diff(int(a), int(b))
        assert -half <= d < half and (d - (int(a) - int(b))) % TICKS_PERIOD == 0


class SkewedClock:
    """The board's clock running `ppm` fast against the chip's conversions (the chip's ODR is
    that much slower than nominal), in whole milliseconds as CircuitPython's ticks_ms."""

    def __init__(self, clock, ppm):
        self.clock, self.ppm = clock, ppm

    def ticks_us(self):
        t = self.clock.now_us()
        return ((t + t * self.ppm // 10 ** 6) // 1000 * 1000) & ((1 << 30) - 1)

    def ticks_diff(self, a, b):
        return self.clock.ticks_diff(a, b)

    def sleep_us(self, us):
        self.clock.sleep_us(us * 10 ** 6 // (10 ** 6 + self.ppm))


@pytest.mark.parametrize("rate", [200, 400])
def test_a_board_clock_ahead_of_the_chip_counts_nothing_lost_that_the_fifo_held(tmp_path, stim,
                                                                                rate):
    """A board's clock and the chip's conversions disagree: CircuitPython's ticks_ms has whole
    milliseconds (on the emulated Feather at 200 Hz, 1 of 4 008 samples was counted lost that
    the chip never dropped), and a real LIS3DH's ODR is not its nominal one.  Time alone then
    says more samples are due than the chip converted, every drain.  Without an overrun the
    FIFO held every conversion: nothing is counted lost, and every sample is at its position
    (here the board's clock runs 0.2 % fast: 20 s would otherwise count ~8 lost at 400 Hz)."""
    from test_pico_lis3dh import fifo_q10
    path, xyz = stim
    for start in (0, 625):
        d = tmp_path / str(start)
        d.mkdir()
        clock = Clock()
        clock.set_us(start)
        b = board(path, clock=clock)
        b.bus = TimedI2C({ADDRESS: b.chip}, 0, clock)       # busio's 100 kHz
        b.clock = SkewedClock(clock, 2000)
        os.chdir(d)
        app = App(b, rate_hz=rate, capture_bytes=1 << 22)
        app.run(20)
        assert (app.lost, b.chip.dropped, app.fifo_overruns) == (0, 0, 0), start
        assert app.samples <= b.chip.generated <= app.samples + 32
        cap = boardlog.read_capture(d)
        got = np.concatenate([blk[3] for blk in cap.blocks if blk[0] == "samples"])
        k = ((start + np.arange(1, app.samples + 1) * (10 ** 6 // rate)) * RATE) // 10 ** 6
        assert np.array_equal(got, fifo_q10(xyz[np.minimum(k, len(xyz) - 1)])), start
