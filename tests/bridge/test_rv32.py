"""`--runtime rv32`: an ESP32-C3-class RISC-V MicroPython (firmware/rv32, MicroPython v1.28's qemu
port with the RV32IMC viper emitter) under qemu-system-riscv32, the device package installed as
rv32imc .mpy, gives CPython's integers: both profiles on a point set, a composed model, the apply
at every full scale and the fits with the heap locked (0 bytes allocated), and the three
functions whose viper shifts once passed 31 (bridge/ranges.py) at the edges of their domains -
here a shift by 32 is no shift (`1000 >> 32` is 1000), as on an Xtensa ESP32.  Skipped, in one
line saying how to install it, where qemu is absent."""

import numpy as np
import pytest

from accelcal.bridge import runtime, rv32
from accelcal.errors import InputError
from conftest import calibrate_both, temp_offset_points


@pytest.fixture(scope="module")
def board():
    """The booted board with the package installed, for this module's tests."""
    try:
        rv32.check()
        b = rv32.board()
    except InputError as e:
        pytest.skip(f"rv32 runtime not available: {e}")
    yield b
    rv32.close()          # an idle board polls its UART: not kept for the rest of the suite


def test_firmware_is_an_rv32_micropython_that_masks_shift_amounts(board):
    from accelcal.board.deploy import mpy_arch
    out = rv32.run_script(
        "import sys, micropython\nprint(sys.implementation._mpy, sys.maxsize)\n"
        "import acal.core.wide\nprint(acal.core.wide.__file__)\n"
        "@micropython.viper\ndef shr(a: int, s: int) -> int:\n    return a >> s\n"
        "print(shr(1000, 31), shr(1000, 32), shr(1000, 40))\n").split("\n")
    mpy, maxsize = map(int, out[0].split())
    assert mpy_arch(mpy) == "rv32imc" and maxsize == 2**31 - 1   # 32-bit words: 2^30 small ints
    assert out[1] == "/lib/acal/core/wide.mpy"                     # installed as .mpy
    assert out[2] == "0 1000 3"           # the amount mod 32: Python's answer only below 32


def on_cpython(script):
    """A board script's printed words, run here by CPython (no heap to lock)."""
    import contextlib
    import io
    import types
    mp = types.SimpleNamespace(heap_lock=lambda: None, heap_unlock=lambda: None)
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        exec(script.replace("import micropython\n", ""), {"micropython": mp})
    return buf.getvalue().split()


EDGES = r"""
from array import array
from acal.core.wide import mul_shift
from acal.core.normal_sums import grow_columns
from acal.core.solve import _rhs_shift
L = (1 << 29) - 1
res = []
for s in (16, 31, 46, 47, 61, 62, 63, 64, 78, 100):
    for a in (L, -L, 1, -1, 0x7FFF):
        for b in (L, -L, -1, 3):
            if abs((a * b) >> s) < 1 << 29:        # its domain: a result below 2^29
                res.append(mul_shift(a, b, s))
sums = array("i", [(-1) ** i * ((1 << 30) - 1 - 977 * i) for i in range(16)])
high = array("i", [(1 << 21) - 3, -(1 << 21) + 5, 123457, -1])
low = array("i", [511, 0, 300, 17])
grow_columns(sums, high, low, array("i", [0, 20, 16, 15]), 4, 0)
res += list(sums) + list(high) + list(low)
for b, sc in (([(1 << 31) - 1, 0, -5], [0, 0, 0]), ([0, -(1 << 28)], [3, -9]),
              ([(1 << 29) - 1, -(1 << 29) + 1], [-4, 2]), ([1 << 27], [0])):
    res.append(_rhs_shift(array("i", b), array("i", sc), len(b), 0))
print(" ".join(str(v) for v in res))
"""


def test_shifts_past_31_give_cpythons_integers_on_rv32(board):
    """wide.mul_shift with s up to 100, normal_sums.grow_columns with the diagonal shifted by 2g
    up to 40, solve._rhs_shift with |b| up to 2^31 - 1 (it never returned here from 2^28):
    each bounds its amount at 31 and gives CPython's integers (tests/device/test_ranges.py
    proves the amounts over the worst cases)."""
    assert rv32.run_script(EDGES, timeout=60).split() == on_cpython(EDGES)


@pytest.mark.parametrize("profile", ["wear", "paper"])
def test_both_profiles_on_rv32_equal_cpython(paper_points, board, capsys, profile):
    cp, rv = calibrate_both(capsys, "rv32", paper_points, "--by", "device", "--profile", profile,
                            codes=(0,))
    assert rv == cp
    assert cp["status"] == "calibrated" and cp["profile"] == profile


def test_point_sets_identical_on_rv32(rng, board):
    """6 random devices' point sets (5-200 points, noise 0 to 50 mg) through the device
    pipeline, paper profile (first-come bins) and wear profile: every field of every result the
    same as CPython's (as tests/bridge/test_runtimes.py for the unix and WebAssembly ports)."""
    from accelcal import simulate
    groups = []
    for i in range(6):
        n = int(rng.integers(5, 200))
        noise = float(rng.choice([0.0, 1e-3, 5e-3, 0.05]))
        groups.append(runtime.Group(f"d{i}", points=simulate.paper_scenario(rng, n, noise)[1]))
    fits = 0
    for cfg in (runtime.Config(policy="first", max_count=3), runtime.Config.for_profile("wear")):
        a = runtime.run(groups, cfg, "cpython")
        assert runtime.run(groups, cfg, "rv32") == a and len(a) == 6
        fits += sum(r.status == 0 for r in a)
    assert fits >= 4                                     # real fits compared


@pytest.mark.slow
def test_composed_model_on_rv32_equals_cpython(tmp_path, board, capsys):
    """base+temp_offset on every 32nd rest point of a simulated wrist day with a temperature
    offset (as tests/bridge/test_rp2040.py): the bins, the base fit and the composed fit, through
    `calibrate` (slow: ~8 s, most of it simulating the day; the default suite's composed fits
    and apply are the heap-locked test's)."""
    pts = temp_offset_points(tmp_path)
    cp, rv = calibrate_both(capsys, "rv32", pts, "--model", "base+temp_offset", codes=(0,))
    assert rv == cp
    assert cp["status"] == "calibrated" and len(cp["params_int"]) == 12


# The apply at every full scale (parameters at the bounds' corner, readings at and past full
# scale), a composed model's apply, both profiles' fits: each under heap_lock, its integers out
HEAP = r"""
import micropython
from array import array
from acal.core.calibration import Calibration
from acal.core.fixed import C_TEMP
from acal.core import effects
from acal.core.gaussnewton import GaussNewton
from acal.paper.optimiser import Optimiser
PTS = array("i", %s)
AUX = array("i", %s)
CORNER = [20971520, 20971520, 20971520, 2097152, -2097152, 2097152, 4194304, -4194304, 4194304]
READ = array("i", [16383, -16383, 9000, -2049, 2048, 0, 1, -1, 7777] * 20)
out = array("i", [0] * len(READ))
cals = []
for r in (2, 4, 8, 16):
    c = Calibration(range_g=r)
    c.set(CORNER)
    cals.append(c)
TEMPS = (effects.TEMP_OFFSET, effects.TEMP_SCALE)
comp = Calibration(TEMPS, 16)
comp.set(CORNER + [effects.BOUNDS[k] for k in TEMPS for _ in range(3)])
fits = [(GaussNewton(72), None), (GaussNewton(72, (effects.TEMP_OFFSET, effects.DRIFT)), AUX)]
opt = Optimiser(18)
res = []


def work(res):
    for c in cals:
        for i in range(len(READ)):
            out[i] = READ[i]
        c.apply_samples(out, 0, len(READ) // 3)
        s = 0
        for i in range(len(out)):
            s = (s * 31 + out[i]) & 0xFFFFF
        res[0] += s
    comp.now[C_TEMP] = 1000
    comp.apply_samples(out, 0, len(READ) // 3, READ)
    for gn, aux in fits:
        gn.run(PTS, 72, 20, aux)
    opt.run(PTS, 18, 50)


acc = [0]
micropython.heap_lock()
try:
    work(acc)
    micropython.heap_unlock()
    print("OK", acc[0], out[0], out[1], out[2], " ".join(
        "%%d:%%d:%%d:%%d" %% (gn.status, gn.iterations, gn.rejected, gn.p[6]) for gn, _ in fits),
        opt.status, opt.iterations, opt.p[0])
except MemoryError:
    micropython.heap_unlock()
    print("ALLOCATED")
"""


def test_apply_and_fits_allocate_nothing_and_equal_cpython_on_rv32(board, rng):
    """With the heap locked on the board (any int past 2^30 or any object would raise): the
    apply at 2, 4, 8 and 16 g, a composed model's apply at a temperature past its clamp, the
    wear profile's Gauss-Newton fit (72 points, and with temperature offset and drift) and the
    paper's gradient descent (18 points): all the same integers as CPython's."""
    from accelcal import simulate
    truth = np.array([1.03, 0.98, 1.01, 0.02, -0.01, 0.015, 0.05, -0.03, 0.04])
    d = rng.normal(size=(72, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    v = simulate.uncorrect(truth, d) + rng.normal(scale=1e-3, size=(72, 3))
    v[5] *= 1.2                                          # an outlier: rejection runs too
    pts = [int(x) for x in np.round(v * 65536).astype(np.int64).ravel()]
    aux = []
    for _ in range(72):
        aux += [int(rng.integers(-160, 161)), int(rng.integers(-300000, 300001)), 0]
    script = HEAP % (pts, aux)
    got = rv32.run_script(script, timeout=300).split()
    assert got[0] == "OK", got
    assert got == on_cpython(script)


def test_a_script_that_raises_is_one_line_and_the_board_goes_on(board):
    from accelcal.errors import InterpreterFailed
    pid = rv32.board().proc.pid
    with pytest.raises(InterpreterFailed, match="rv32 failed .*ValueError: no such thing"):
        rv32.run_script("import acal.core.fixed\nraise ValueError('no such thing')\n")
    assert rv32.run_script("print(6 * 7)\n") == "42\n" and rv32.board().proc.pid == pid


def test_missing_qemu_is_one_line(monkeypatch, tmp_path):
    monkeypatch.setenv(rv32.QEMU_ENV, str(tmp_path / "no-qemu"))
    with pytest.raises(InputError, match="apt-get install qemu-system-misc"):
        runtime.check("rv32")
    assert "rv32" in runtime.RUNTIMES
