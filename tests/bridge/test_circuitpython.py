"""The device package on real CircuitPython: Adafruit CircuitPython 10.2.1 for the Feather RP2040
(firmware/circuitpython-feather_rp2040) on the emulated RP2040, the package installed as .mpy
files from CircuitPython's own mpy-cross.  The same integers as CPython for both profiles and a
composed model; 0 bytes allocated per sample and per fit slice (measured with gc.disable() and
gc.mem_alloc(): CircuitPython has no heap_lock); the heap the app with the largest model leaves."""
import json
from pathlib import Path

import numpy as np
import pytest

from accelcal import simulate
from accelcal.bridge import protocol, rp2040, runtime
from accelcal.errors import InputError
from conftest import ROOT, emulated_chip, made_once, run_main
from test_runtimes import random_recording

FW = rp2040.CIRCUITPYTHON


@pytest.fixture(scope="session")
def chip():
    """The emulated Feather with the package installed; skipped, saying why, where Node or
    rp2040js is missing (make setup installs it; CI has both)."""
    return emulated_chip(FW)


@pytest.mark.slow   # a boot of CircuitPython: ~40 s of CPU (the default run proves the heap below)
def test_calibrate_on_circuitpython_equals_cpython(tmp_path, chip, capsys):
    """`accelcal calibrate --runtime circuitpython` (the paper's profile): the same record."""
    pts = tmp_path / "pts.csv"
    assert run_main(capsys, ["simulate", "paper", "--noise-mg", "1", "--scenarios", "1",
                             "--seed", "7", "-o", str(pts)])[0] == 0
    records = {}
    for rt in ("cpython", "circuitpython"):
        code, out, err = run_main(capsys, ["calibrate", str(pts), "--by", "device",
                                           "--runtime", rt, "--json"])
        assert code == 0, err
        rec = json.loads(out)
        assert rec.pop("runtime") == rt
        records[rt] = rec
    assert records["circuitpython"] == records["cpython"]
    assert records["cpython"]["points"] >= 18


@pytest.mark.slow   # ~2 min of emulation (6 min wall on a loaded machine): make bench
def test_both_profiles_and_a_composed_model_bit_identical(rng, chip):
    """In one boot: the wear profile on points with outliers and on recordings (its noise gauge,
    rest detector, bins, Gauss-Newton with rejection), the paper's on recordings, and a
    composed wear model (temperature offset) on points: every record as CPython's."""
    from acal.core import effects
    pts = []
    for i in range(4):
        n = int(rng.integers(40, 200))
        _, v = simulate.paper_scenario(rng, n, float(rng.choice([1e-3, 5e-3])))
        v[rng.integers(0, n, n // 20)] *= rng.uniform(1.02, 1.1)  # outliers
        pts.append(runtime.Group(f"d{i}", points=v))
    xyz, gaps = random_recording(rng, 16, 25)
    recs = [runtime.Group("r", samples=xyz, gaps=gaps)]
    truth = np.array([1.02, 0.97, 1.01, 0.01, -0.02, 0.01, 0.04, -0.05, 0.03])
    n = 150
    temp = rng.uniform(20, 36, n)
    v = simulate.uncorrect(truth, simulate.unit_points(rng, n)) + \
        0.0008 * (temp - 28)[:, None] + rng.normal(scale=5e-4, size=(n, 3))
    composed = runtime.Group("c", points=v, temp=temp, t=np.arange(n) * 300.0)
    wear = runtime.Config.for_profile("wear")
    jobs = [(pts, wear), (recs, runtime.Config.for_profile("wear", rate_hz=25, seconds=2)),
            (recs, runtime.Config(rate_hz=25, seconds=2)),
            ([composed], runtime.Config.for_profile("wear", composed=True,
                                                    kinds=(effects.TEMP_OFFSET,)))]
    want, lines = [], []
    for groups, cfg in jobs:
        want += runtime.run(groups, cfg, "cpython")
        lines += protocol.protocol_lines(groups, cfg)
    got = protocol.parse(chip.run_protocol(lines, FW).out.splitlines())
    assert got == want
    assert sum(r.status == 0 for r in want[:4]) >= 3
    assert sum(r.kept is not None and 0 in r.kept for r in want[:4]) >= 1   # rejections too
    assert min(len(r.rest_int) for r in want[4:6]) >= 5
    assert want[-1].status == 0 and want[-1].params_int[9] != 0               # the effect fitted


def test_both_profiles_bit_identical_small(rng, chip):
    """The default suite's cut of the above, in one boot (~25 s of CPU): one device's points
    with outliers and one recording with gaps and clipping, each under both profiles (the wear
    profile's noise gauge, rest detector, bins and Gauss-Newton with rejection; the paper's rest
    detector, bins and gradient descent): every record as CPython's."""
    n = 48
    _, v = simulate.paper_scenario(rng, n, 1e-3)
    v[rng.integers(0, n, n // 10)] *= rng.uniform(1.02, 1.1)  # outliers
    pts = [runtime.Group("d", points=v)]
    xyz, gaps = random_recording(rng, 6, 25)
    recs = [runtime.Group("r", samples=xyz, gaps=gaps)]
    jobs = [(pts, runtime.Config.for_profile("wear")), (pts, runtime.Config()),
            (recs, runtime.Config.for_profile("wear", rate_hz=25, seconds=2)),
            (recs, runtime.Config(rate_hz=25, seconds=2))]
    want, lines = [], []
    for groups, cfg in jobs:
        want += runtime.run(groups, cfg, "cpython")
        lines += protocol.protocol_lines(groups, cfg)
    got = protocol.parse(chip.run_protocol(lines, FW).out.splitlines())
    assert got == want
    assert want[0].status == want[1].status == 0 and want[0].params_int != want[1].params_int
    assert 0 in want[0].kept                                  # the wear fit rejected outliers
    assert len(want[3].rest_int) >= 2                         # the paper's detector found rests


def test_missing_emulator_is_one_line(monkeypatch, tmp_path):
    monkeypatch.setenv("ACCELCAL_RP2040JS", str(tmp_path / "nowhere.js"))
    with pytest.raises(InputError, match="rp2040js is not installed"):
        rp2040.emulator_index()
    assert "circuitpython" in runtime.RUNTIMES


def test_circuitpythons_mpy_cross_compiles_every_device_module(tmp_path):
    """CircuitPython's own mpy-cross (committed with its firmware; make build uses it) compiles
    the package; its .mpy files say CircuitPython ('C', version 6) where MicroPython's say 'M'
    (which CircuitPython refuses)."""
    from accelcal.locations import DEVICE_PACKAGE
    sources = sorted(DEVICE_PACKAGE.rglob("*.py"))
    assert len(sources) >= 10
    for src in sources:
        name = src.relative_to(DEVICE_PACKAGE).with_suffix("").as_posix().replace("/", "_")
        cp, mp = tmp_path / f"{name}.cp.mpy", tmp_path / f"{name}.mp.mpy"
        rp2040.mpy_cross(src, cp, None, FW)
        rp2040.mpy_cross(src, mp, None)
        assert cp.read_bytes()[:2] == b"C\x06" and mp.read_bytes()[:2] == b"M\x06"


@pytest.fixture(scope="module")
def cp_bench(chip, tmp_path_factory):
    """bridge/scripts/cp_bench.py's figures on the chip (the fit timed slice by slice only),
    measured once for both workers."""
    from accelcal.studies import bench_circuitpython
    return made_once(tmp_path_factory, "cp_bench", lambda: bench_circuitpython.run(whole=False))


def test_deploy_gives_a_circuitpython_board_circuitpythons_mpy(tmp_path):
    """`accelcal deploy` to the Feather (RUNTIME circuitpython, no ARCH) writes .mpy from
    CircuitPython's mpy-cross ('C'), the Pico's from MicroPython's ('M'), the virtual board's
    the sources; every module the board needs, the CircuitPython driver only on the Feather."""
    from accelcal.board import deploy
    for board, head in (("feather_rp2040", b"C\x06"), ("pico", b"M\x06"), ("virtual", None)):
        info = deploy.board_info(board)
        cp = info["RUNTIME"] == "circuitpython"
        modules = list(deploy.APP_MODULES) + (list(deploy.CIRCUITPYTHON_ONLY) if cp else [])
        pkg = tmp_path / board
        pkg.mkdir()
        files, what = deploy.package_files(info, modules, pkg)
        assert [f"{f.relative_to(pkg).with_suffix('').as_posix()}.py" for f in files] == modules
        assert ("logger/lis3dh_cp.py" in modules) == cp
        if head is None:
            assert what == "sources" and all(f.suffix == ".py" for f in files)
        else:
            assert all(f.suffix == ".mpy" and f.read_bytes()[:2] == head for f in files), what


def test_deploy_writes_boot_py_to_a_circuitpython_board_only(tmp_path):
    """Beside the package `deploy` copies the board file and main.py (unless --no-main), and to
    a CircuitPython board a boot.py remounting its drive writable to code (the app logs there;
    the Feather end to end above runs with this very file) unless the board holds a boot.py of
    its own, which stays; one deploy wrote is written again."""
    from accelcal.board import deploy
    settings = {"fifo": True, "profile": 0}

    def files(board, write_main=True, head=None):
        dest = tmp_path / f"{board}-{write_main}-{head}"
        dest.mkdir()
        out = deploy.board_files(deploy.board_info(board), settings, write_main, dest, head)
        return {remote: Path(local).read_text() for local, remote in out}

    feather = files("feather_rp2040")
    assert sorted(feather) == ["acal_board.py", "boot.py", "main.py"]
    assert feather["acal_board.py"] == (ROOT / "boards" / "feather_rp2040.py").read_text()
    assert feather["main.py"] == deploy.main_py(settings)
    assert "acal.logger.app.main(fifo=True, profile=0)" in feather["main.py"]
    boot = feather["boot.py"]
    compile(boot, "boot.py", "exec")
    assert boot.splitlines()[0] == deploy.BOOT_PY_HEAD
    assert [ln for ln in boot.splitlines() if not ln.startswith("#")] == \
        ["import storage", 'storage.remount("/", readonly=False)']
    assert sorted(files("feather_rp2040", head=deploy.BOOT_PY_HEAD)) == sorted(feather)
    assert sorted(files("feather_rp2040", head="import storage  # mine")) == ["acal_board.py", "main.py"]
    assert sorted(files("feather_rp2040", write_main=False)) == ["acal_board.py", "boot.py"]
    for board in ("pico", "virtual"):
        assert sorted(files(board)) == ["acal_board.py", "main.py"]
        assert sorted(files(board, write_main=False)) == ["acal_board.py"]


def test_nothing_allocated_per_sample_or_per_fit_slice_and_the_largest_model_fits(cp_bench):
    """CircuitPython has no heap_lock: with the collector off, gc.mem_alloc() before and after
    (bridge/scripts/cp_bench.py).  Both profiles' rest detectors over 1000 samples, the apply at
    every full scale (readings past it, parameters at the bounds' corner), and the default
    (wear) fit of 72 points with outlier rejection, slice by slice as the app runs it: 0 bytes.
    A list shows the counting sees an allocation.  Memory: after `import acal.logger.app` and a
    Processor of each of the largest models (four effects, a step among them), the heap keeps
    room for the app (its buffers, log and bus: ~10 kB)."""
    from accelcal.studies import bench_circuitpython
    r = cp_bench
    assert r["bytes_control_list"] > 0
    for k in ("bytes_rest_paper", "bytes_rest_wear", "bytes_apply", "bytes_fit_begin",
              "bytes_fit_worst_slice", "bytes_fit_all_slices"):
        assert r[k] == 0, (k, r)
    assert r["rest_segments"] == "2 2"                         # the detectors saw the rests
    status, iterations, rejected = map(int, r["fit_wear_status"].split())
    assert status == 0 and rejected >= 2 and r["fit_wear_slices"] > 100
    from acal.core.gaussnewton import GaussNewton
    host = GaussNewton(72)
    host.run(bench_circuitpython.fit_points(), 72)
    assert r["fit_wear_params"] == " ".join(map(str, host.p[:9]))   # what CPython fits
    largest = [v for k, v in r.items() if k.startswith("free_with_processor_")]
    assert len(largest) == 2 and min(largest) > 40000
    print({k: v for k, v in r.items() if k.startswith("free")})


def test_the_bench_puts_circuitpythons_figures_beside_micropythons(cp_bench):
    """`accelcal bench --runtime rp2040|circuitpython`: cp_bench.py's figures become the chip
    table's CircuitPython column and its JSON keys: the rest detectors per sample in their rows
    (no MicroPython figure given here: '-'), the default fit converged with 0 bytes in its worst
    slice, 0 bytes per sample and fit while the control list's allocation is seen, and the heap
    with the largest model below the heap after the import."""
    from accelcal.studies import bench_chip, bench_circuitpython
    m = bench_circuitpython.cp_figures(cp_bench)
    cp = bench_chip.CP
    assert all(k.startswith(cp) for k in m)
    assert m[cp + "default_fit_status"] == 0 and m[cp + "default_fit_slices"] == cp_bench["fit_wear_slices"]
    assert m[cp + "default_fit_worst_slice_bytes"] == 0
    assert m[cp + "bytes_per_sample_and_fit"] == 0 < m[cp + "bytes_control_list"]
    assert 0 < m[cp + "free_with_processor_largest_bytes"] < m[cp + "free_after_import_app_bytes"]
    rows = {name: (unix, mp, v) for name, unix, mp, v, _ in bench_chip.rows(m)}
    assert set(rows) == {"rest detector, paper profile, per sample",
                         "rest detector, wear profile, per sample"}
    assert rows["rest detector, paper profile, per sample"][2] * 1000 == cp_bench["rest_paper_ns_per_sample"]
    assert all(unix is None and mp is None and v > 0 for unix, mp, v in rows.values())
    table = bench_chip.format_chip(m).splitlines()
    assert "CircuitPython" in table[2] and "MicroPython" in table[2]
    line = next(ln for ln in table if ln.startswith("rest detector, wear profile"))
    assert line.split()[-3:] == [f"{rows['rest detector, wear profile, per sample'][2]:.4g}", "us", "-"]
    assert any(ln.endswith("bytes per sample and fit slice 0 (gc.disable(), gc.mem_alloc())")
               for ln in table)
    assert json.loads(json.dumps(m)) == m   # --json carries them
    print(table)


def test_bench_says_in_one_line_when_circuitpython_is_missing(monkeypatch, capsys):
    """Beside MicroPython's (--runtime rp2040) a missing CircuitPython firmware or mpy-cross is
    one line and the bench goes on; asked for alone (--runtime circuitpython), exit 2, one line."""
    import dataclasses
    from accelcal.studies import bench
    try:
        rp2040.check(rp2040.MICROPYTHON)
    except InputError as e:
        pytest.skip(f"emulated RP2040 not available: {e}")
    monkeypatch.setattr(rp2040, "CIRCUITPYTHON", dataclasses.replace(FW, compiler="no-mpy-cross"))
    monkeypatch.setattr(rp2040, "flash_image", lambda fw: None)   # MicroPython's: not the point
    chips, missing = bench.chip_firmwares("rp2040")
    assert chips == [rp2040.MICROPYTHON] and "no-mpy-cross is missing" in missing
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("CircuitPython not measured:")
    code, out, err = run_main(capsys, ["bench", "--runtime", "circuitpython"])
    assert code == 2 and out == "" and len(err.strip().splitlines()) == 1, err
    assert "no-mpy-cross is missing" in err



# The paper's profile with 1 s rest segments (a setting the app takes): the dance's 2 s poses
# fill the nine subsets twice in ~70 emulated s (the wear profile judges no segment still before
# 80 s of quiet ones).  The app is started as main() starts it, with the rest window given.
FEATHER_APP = """import board, time, supervisor, adafruit_lis3dh, acal_board
# the real driver finds the chip, on the busio.I2C (400 kHz) the board file keeps for the app
lis = adafruit_lis3dh.LIS3DH_I2C(acal_board.i2c_bus(), address=0x18)
time.sleep(0.02)   # its first conversion at 400 Hz (the datasheet's turn-on time: 1/ODR + 1 ms)
print('ADAFRUIT', lis.range, round(sum(v * v for v in lis.acceleration) ** 0.5))
import acal.logger.app, acal_board
ms = supervisor.ticks_ms()
app = acal.logger.app.App(acal_board, rate_hz=100, fifo=True, capture_bytes=300000, profile=0, seconds=1)
app.run({seconds})
print('ACAL_DONE', app.samples, app.lost, app.fifo_overruns, app.bus_errors, app.proc.calibrations,
      ms, supervisor.ticks_ms())
"""


def site_package(name):
    import importlib.util
    spec = importlib.util.find_spec(name)
    root = Path(spec.origin)
    return [root] if root.name != "__init__.py" else sorted(root.parent.glob("*.py"))


# slow (~70-160 s). In stop 37 and after 5a6019c it did not end on some images and code (22 min): the
# emulated core slept in a WFI with CircuitPython's TIMER interrupt already pending (the alarm
# fired between its arming and the WFI, interrupts off), which rp2040js slept through for good;
# bridge/scripts/rp2040.mjs lets such a WFI run on, as the hardware does (docs/boards-and-logs.md).
@pytest.mark.slow
def test_the_app_on_the_feather_calibrates_and_its_log_replays(tmp_path, chip):
    """boards/feather_rp2040.py and the app, unchanged, on CircuitPython on the emulated chip,
    the LIS3DH model on I2C1 (GP2/GP3, its pull-ups seen): the real adafruit_lis3dh (from the
    package in .venv, into /lib), on the board file's busio.I2C, finds the chip; the app reads its FIFO through busio
    for 74 emulated seconds at 100 Hz while the board is turned through a calibration dance
    (three rounds of six faces and six edges, 2 s still each), logs to the drive (writable to it
    after a power-up with boot.py, nothing remounted from the REPL), calibrates near the
    sensor's truth, and its capture replays on the host into the board's very log, the CAL
    record too.  Nothing is lost: every sample is the chip's next conversion.  The run crosses
    the wrap of supervisor.ticks_ms() (2^29 ms, which CircuitPython starts 65 s before it)."""
    from accelcal.board import deploy, emulated
    from accelcal.bridge import boardlog
    from accelcal.simulate.stimulus import calibration_dance
    from acal.core import fixed
    from acal.logger import log
    from test_pico_lis3dh import RATE, TRUTH, fifo_q10
    xyz = calibration_dance(tmp_path / "stim.bin", RATE, TRUTH, seed=6, rounds=3, rest_s=2,
                            move_s=0.5)
    puts = {"acal_board.py": (ROOT / "boards" / "feather_rp2040.py").read_bytes(),
            "boot.py": deploy.boot_py().encode()}   # what deploy writes
    for f in site_package("adafruit_lis3dh"):
        puts[f"/lib/{f.name}"] = f.read_bytes()
    for f in site_package("adafruit_bus_device"):
        puts[f"/lib/adafruit_bus_device/{f.name}"] = f.read_bytes()
    image = tmp_path / "feather.bin"   # installed, then powered up again: boot.py remounts
    emulated.run(["print(1)"], puts=puts, flash_out=image, fw=FW)
    r = emulated.run([FEATHER_APP.format(seconds=74)], stimulus=tmp_path / "stim.bin",
                     gets=["log.bin", "capture.bin"], flash_in=image, fw=FW, i2c="1,2,3")
    rng_code, norm = map(int, r.out.split("ADAFRUIT")[1].split()[:2])
    assert rng_code == 0 and 5 <= norm <= 15, r.out   # RANGE_2_G; |a| of gravity's order, m/s^2
    done = r.out.split("ACAL_DONE")[1].split()
    samples, lost, overruns, bus_errors, calibrations, ms0, ms1 = map(int, done[:7])
    chip_truth = r.report["lis3dh"]
    assert lost == overruns == chip_truth["dropped"] == 0
    assert bus_errors == chip_truth["faults"] == 0 and calibrations == 1
    assert ms1 < ms0   # supervisor.ticks_ms() wrapped during the run
    for f in ("log.bin", "capture.bin"):
        (tmp_path / f).write_bytes(r.files[f])
    # the samples, in the order the FIFO gave them, are the chip's conversions 1, 2, ... of the
    # last ODR start, each reading the stimulus at its time
    got = np.concatenate([b[3] for b in boardlog.read_capture(tmp_path).blocks if b[0] == "samples"])
    s, us = chip_truth["starts"][-1]
    k = (s * 1_000_000 + us + np.arange(1, samples + 1) * 10_000) * RATE // 1_000_000
    assert len(got) == samples >= 74 * RATE and np.array_equal(got, fifo_q10(xyz[k]))
    cal = boardlog.decode(tmp_path / "log.bin").dicts(log.CAL)
    assert len(cal) == 1 and cal[0]["status"] == 0 and cal[0]["points"] == 18
    p = np.array([cal[0][n] for n in fixed.PARAM_NAMES]) / 2 ** 24
    print(f"\nFeather, CircuitPython: {samples} samples, calibrated at sample {cal[0]['index']}, "
          f"largest parameter error {np.abs(p - TRUTH).max():.4f}; {r.report['scripts'][0]}")
    assert np.abs(p - TRUTH).max() < 0.01
    rep = boardlog.replay(tmp_path)
    assert rep["identical"] and rep["samples_replayed"] == samples
    assert rep["cal"]["board"] == 1 and rep["rest"]["board"] >= 18, rep
    # deploy's look at the drive, run on this board (its boot.py found) and on one without a
    # boot.py (read-only to code: deploy stops in one line)
    assert deploy.circuitpython_drive(ChipRemote(image), True) == deploy.BOOT_PY_HEAD
    with pytest.raises(InputError, match="read-only to code") as e:
        deploy.circuitpython_drive(ChipRemote(rp2040.flash_image(FW)), False)
    assert len(str(e.value).splitlines()) == 1


class ChipRemote:
    """deploy.Remote's exec on the emulated Feather booted from a flash image."""
    port = "the emulated Feather"

    def __init__(self, image):
        self.image = image

    def exec(self, code, **_):
        from accelcal.board import emulated
        return emulated.run([code], flash_in=self.image, fw=FW).out


CP_FIFO_SCRIPT = r'''
from array import array
from acal.logger.lis3dh_cp import FifoTables
b = bytes(%r)
for so_mg in (1, 2, 4, 12):
    for mid in (0, 3):
        so = so_mg * 16777
        t = FifoTables(mid, so, %d)
        out = array("i", [7] * 1026)
        nxt = t.convert(b, 0, 1023, out, 1, 16000)
        print(" ".join(str(v) for v in out), nxt)
'''


def test_the_fifo_tables_on_circuitpython_give_the_documented_values(rng, chip):
    """On CircuitPython (no emitters) the driver converts the FIFO through its tables (where the
    board file says FIFO_TABLES, as the Feather's does: tests/board/test_nothing_lost.py): there,
    every 10-bit code at every range, HR or not, from the dither 16000 on, gives CPython's
    fifo_codes_q10 values (held to test_lis3dh.fifo_to_q10, the documented conversion) and the
    same next dither."""
    from acal.core.fixed import SAMPLE_MAX
    from acal.logger import lis3dh
    from test_lis3dh import fifo_codes_every_value
    _, data = fifo_codes_every_value(rng)
    r = rp2040.run_script(CP_FIFO_SCRIPT % (data, SAMPLE_MAX), fw=FW)
    lines = r.out.strip().splitlines()
    want = []
    for so_mg in (1, 2, 4, 12):
        for mid in (0, 3):
            out = [7] * 1026
            nxt = lis3dh.fifo_codes_q10(data, 0, 1023, out, 1, mid, so_mg * 16777, SAMPLE_MAX, 16000)
            want.append(out + [nxt])
    assert [list(map(int, line.split())) for line in lines] == want
