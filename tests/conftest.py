import contextlib
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
# tests/ mirrors the package in folders without __init__.py; a few modules share helpers by
# importing each other by name (import test_app), so every folder is importable from any other.
for _folder in sorted(Path(__file__).parent.iterdir()):
    if _folder.is_dir() and _folder.name not in ("data", "__pycache__"):
        sys.path.insert(0, str(_folder))


@pytest.fixture
def rng():
    return np.random.default_rng(12345)


@pytest.fixture(autouse=True)
def catalogue_restored():
    """Effects a test declares (--effects in-process, register()) leave the catalogue with it:
    the next test sees the built-in one."""
    from accelcal.model.effects import CATALOGUE
    before = dict(CATALOGUE)
    yield
    CATALOGUE.clear()
    CATALOGUE.update(before)


def simulate_wrists(folder, cases: dict, days, rate) -> dict:
    """Simulated wrist recordings, name -> (seed, hidden effects), made in parallel (both cores);
    name -> path.  Under xdist the two workers share them: the first to ask simulates, the other
    takes the same files (a module fixture on both workers made them twice, up to a minute)."""
    import shutil
    shared = next((p.parent for p in Path(folder).parents if p.name.startswith("popen-gw")), None)
    if shared is None:
        return _simulate_wrists(folder, cases, days, rate)
    with _first_worker(shared, ("wrists", sorted(cases.items()), str(days), str(rate))) as made:
        if not (made / "done").exists():
            _simulate_wrists(made, cases, days, rate)
            (made / "done").touch()
    Path(folder).mkdir(parents=True, exist_ok=True)
    for f in made.iterdir():
        if f.name != "done":
            shutil.copyfile(f, Path(folder) / f.name)
    return {name: Path(folder) / f"{name}.csv" for name in cases}


@contextlib.contextmanager
def _first_worker(session_dir: Path, what):
    """A folder for `what` in the session's folder that the xdist workers share, held under a
    lock: the first worker makes what goes in it, the others wait and take it."""
    import fcntl
    import hashlib
    key = hashlib.sha256(repr(what).encode()).hexdigest()[:16]
    folder = session_dir / "shared" / key
    folder.mkdir(parents=True, exist_ok=True)
    with open(folder.with_suffix(".lock"), "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        yield folder


def made_once(tmp_path_factory, what, make):
    """make()'s JSON result, made once per test session (by one of the xdist workers)."""
    base = tmp_path_factory.getbasetemp()
    if not base.name.startswith("popen-gw"):
        return make()
    with _first_worker(base.parent, what) as folder:
        f = folder / "result.json"
        if not f.exists():
            f.write_text(json.dumps(make()))
        return json.loads(f.read_text())


def _simulate_wrists(folder, cases: dict, days, rate) -> dict:
    out, procs = {}, []
    for name, (seed, effects) in cases.items():
        path = folder / f"{name}.csv"
        args = ["simulate", "wrist", "--days", days, "--rate", rate, "--seed", seed, "-o", path]
        for e in effects:
            args += ["--effect", e]
        procs.append(subprocess.Popen([sys.executable, "-m", "accelcal.cli", *map(str, args)],
                                      stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True))
        out[name] = path
    for pr in procs:
        assert pr.wait() == 0, pr.stderr.read()
    return out


def run_main(capsys, argv):
    """The CLI's main(argv) in this process (bad-input corpora: hundreds of cases in seconds):
    (exit status, stdout, stderr)."""
    from accelcal import cli
    try:
        code = cli.main([str(a) for a in argv])
    except SystemExit as e:   # argparse exits
        code = e.code
    out, err = capsys.readouterr()
    return code, out, err


def calibrate_both(capsys, runtime, *argv, codes=(0, 2)):
    """The same `calibrate ARGV --json` under CPython and under runtime (an emulated chip's):
    (CPython's record, the runtime's), each without its runtime field; both exit with the same
    status, one of codes."""
    records, status = {}, {}
    for rt in ("cpython", runtime):
        code, out, err = run_main(capsys, ["calibrate", *map(str, argv), "--runtime", rt, "--json"])
        assert code in codes and out, err
        rec = json.loads(out)
        assert rec.pop("runtime") == rt
        records[rt], status[rt] = rec, code
    assert status[runtime] == status["cpython"]
    return records["cpython"], records[runtime]


@pytest.fixture(scope="module")
def paper_points(tmp_path_factory):
    """A points file of one paper scenario (1 mg noise, seed 7): what the chips' tests fit."""
    from accelcal import cli
    pts = tmp_path_factory.mktemp("paper") / "pts.csv"
    assert cli.main(["simulate", "paper", "--noise-mg", "1", "--scenarios", "1", "--seed", "7",
                     "-o", str(pts)]) == 0
    return pts


def temp_offset_points(folder: Path) -> Path:
    """Every 32nd rest point (x,y,z,t,temp) of a simulated wrist day at 10 Hz with a temperature
    offset (seed 17): what the chips fit base+temp_offset on (bins spread in temperature and time,
    the base fit, the composed fit) in seconds of emulated time."""
    from accelcal import cli
    from accelcal.pipeline.restpoints import rest_points
    rec = folder / "day.csv"
    assert cli.main(["simulate", "wrist", "--days", "1", "--rate", "10", "--seed", "17",
                     "--effect", "temp_offset", "-o", str(rec)]) == 0
    p = rest_points(str(rec))
    pts = folder / "points.csv"
    np.savetxt(pts, np.column_stack([p.v, p.t, p.temp])[::32], delimiter=",", fmt="%.6f",
               header="x,y,z,t,temp", comments="")
    return pts


def true_heldout_error(rec, effects_file=None) -> float:
    """The true sensor on diagnose's held-out points of a simulated recording: each hidden effect
    removed with its true values and its own true reference (a curve's vertex, a step's time, a
    column's reference), then the true 9 parameters - independent of how the fitted models are
    parametrised.  effects_file: the declarations the simulator hid an effect of."""
    import numpy as np
    from accelcal.pipeline.restpoints import rest_points, split, usable
    _, test, _ = split(usable(rest_points(str(rec))))
    a = true_corrected(rec, test.v, test.temp, test.t, test.cols, effects_file)
    return float(np.mean(np.abs(np.linalg.norm(a, axis=1) - 1)) * 1e3)


def true_corrected(rec, v, temp, t, cols, effects_file=None):
    """Measurements v (g) with conditions temp (degC), t (s), cols (columns by name) corrected
    by a simulated recording's true sensor model (true_heldout_error's way)."""
    import json
    import numpy as np
    from acal.core.fixed import PARAM_NAMES
    from accelcal.methods import correct as base_correct
    from accelcal.model.declared import register
    from accelcal.model.effects import CATALOGUE
    register(str(effects_file) if effects_file else None)
    truth = json.loads(rec.with_suffix(".truth.json").read_text())
    w = np.asarray(v, dtype=np.float64)
    for e in reversed(truth["effects"]):
        w = CATALOGUE[e["effect"]].correct(w, np.array(list(e["params"].values())), temp, t,
                                           e["reference"], cols)
    return base_correct(np.array([truth["params"][n] for n in PARAM_NAMES]), w)


def wear_on_virtual_board(tmp_path, stim, model, rate, hours=48):
    """deploy MODEL to the virtual board (the MicroPython unix port on a pty, an RP2040-sized
    240 kB heap, the Pico firmware's) with the real mpremote, acquire `hours` of the stimulus, pull: (the pulled
    summary, its folder)."""
    import json
    from accelcal.board import virtual
    with virtual.Running(tmp_path / "flash", stim, "--heap", "240k") as b:
        app = ["--rate", rate, "--capture-kb", 12000, "--model", model, "--recal-hours", 6]
        r = run_cli("deploy", "--port", b.port, *app)
        assert r.returncode == 0, r.stderr
        r = run_cli("acquire", "--port", b.port, "--hours", hours, *app)
        assert r.returncode == 0, r.stderr
        out = tmp_path / "pulled"
        r = run_cli("pull", "--port", b.port, "-o", out, "--json")
        assert r.returncode == 0, r.stderr
    return json.loads(r.stdout), out


def mpremote(port, *args, timeout=300, cwd=None):
    """The real mpremote on a board's port (`connect PORT ARGS...`), as a user runs it; its
    stdout, the test failing with its stderr when it fails."""
    p = subprocess.run([sys.executable, "-m", "mpremote", "connect", port, *args],
                       capture_output=True, text=True, timeout=timeout, cwd=cwd)
    assert p.returncode == 0, p.stderr
    return p.stdout


def run_cli(*args, cwd=None):
    """Run the installed CLI as a user does; returns CompletedProcess."""
    return subprocess.run([sys.executable, "-m", "accelcal.cli", *map(str, args)],
                          capture_output=True, text=True, cwd=cwd)


# A deterministic int generator for scripts that run under both CPython and MicroPython.
MP_RANDOM = r'''
_seed = [12345]
def rnd(m):
    """An int in [-m, m], the same sequence on CPython and MicroPython."""
    _seed[0] = (_seed[0] * 1103515245 + 12345) & 0x7FFFFFFF
    return (_seed[0] >> 8) % (2 * m + 1) - m
try:  # the real one (heap_lock); CPython may have Adafruit Blinka's module of that name
    import micropython
    if not hasattr(micropython, "heap_lock"):
        micropython = None
except ImportError:
    micropython = None
'''


@pytest.fixture(scope="session")
def mp32():
    """The 32-bit MicroPython (make setup installs it); a test that needs it is skipped, saying
    why, where it or Node is missing (CI has both)."""
    from accelcal.bridge import runtime
    from accelcal.errors import InputError
    try:
        runtime.micropython32_module()
    except InputError as e:
        pytest.skip(f"32-bit MicroPython not available: {e}")
    return runtime.run_micropython32_script


@pytest.fixture(params=["micropython", "micropython32"])
def mp(request):
    """Each real MicroPython in turn: the 64-bit unix port, the 32-bit WebAssembly port."""
    if request.param == "micropython32":
        request.getfixturevalue("mp32")
    return request.param


def heap_locked(call, report=""):
    """A MicroPython script's last lines: `call` run with the heap locked, then "OK" and
    `report` (expressions printed after it), or "ALLOCATED" where the call allocated."""
    return ("micropython.heap_lock()\ntry:\n    %s\n    micropython.heap_unlock()\n"
            "    print(\"OK\"%s)\nexcept MemoryError:\n    micropython.heap_unlock()\n"
            "    print(\"ALLOCATED\")\n") % (call, ", " + report if report else "")


def run_both(script, tmp_path, micropython="micropython"):
    """Stdout of the script (MP_RANDOM prepended) under a real MicroPython (the unix port, or
    "micropython32") and under CPython."""
    import contextlib
    import io

    from accelcal.bridge import runtime
    text = MP_RANDOM + script
    f = tmp_path / "both.py"
    f.write_text(text)
    run = runtime.run_micropython_script if micropython == "micropython" else runtime.run_micropython32_script
    mp = run(str(f))
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        exec(compile(text, str(f), "exec"), {"__name__": "both"})
    return mp, buf.getvalue()


def effect_orders():
    """The compositions of the device's effects a worst case runs over: every order of every
    subset of the five specific forms (kinds 1-5), and every ordered pair that holds a generic
    offset (kinds 6-11).  Each effect's output is clamped to +-2.048 g before the next, so an
    effect meets at worst a clamped reading whatever came before it: the pairs cover all a
    generic offset can meet or hand on."""
    import itertools
    from acal.core import effects
    specific = [k for k in effects.NAMES if k not in effects.SHAPES]
    orders = [o for n in range(1, len(specific) + 1) for o in itertools.permutations(specific, n)]
    orders += [o for o in itertools.permutations(effects.NAMES, 2)
               if o[0] in effects.SHAPES or o[1] in effects.SHAPES]
    orders += [(k,) for k in effects.SHAPES]
    return orders


def emulated_chip(firmware=None):
    """bridge/rp2040 with the firmware's flash image made (MicroPython's by default); the test is
    skipped, saying why, where Node, rp2040js or the firmware is missing (make setup installs
    rp2040js; CI has all three)."""
    from accelcal.bridge import rp2040
    from accelcal.errors import InputError
    fw = firmware or rp2040.MICROPYTHON
    try:
        rp2040.check(fw)
        rp2040.flash_image(fw)
    except InputError as e:
        pytest.skip(f"emulated RP2040 not available: {e}")
    return rp2040


def good_inputs(d: Path):
    """Small valid inputs in folder d (a points file, a recording, saved parameters), so that
    in a bad-input case the bad part is the one reported: the CLI's and the API's corpora."""
    rng = np.random.default_rng(5)
    v = rng.normal(size=(300, 3))
    v /= np.linalg.norm(v, axis=1)[:, None]
    pts = d / "pts.csv"
    pts.write_text("x,y,z\n" + "\n".join(",".join(f"{c:.6f}" for c in r) for r in v) + "\n")
    rec = d / "rec.csv"
    rec.write_text("t,x,y,z,temp\n" + "\n".join(
        f"{i / 10:.1f},0.01,0.02,0.99,25.0" for i in range(3000)) + "\n")
    params = d / "p.json"
    params.write_text(json.dumps({"model": "base", "params_int": {
        n: (1 << 24 if i < 3 else 0) for i, n in enumerate(
            ["kxx", "kyy", "kzz", "kxy", "kxz", "kyz", "ox", "oy", "oz"])}}))
    return pts, rec, params


def relative(n, dT=0, dt=0, dV=0):
    """(n, COND) relative conditions (the device's now - ref by column, fixed.C_*: dT Q2 degC,
    dt 64 s units, dV mV of the supply) for bridge/twin.apply_params."""
    from acal.core.bins import COND
    from acal.core.fixed import C_SUPPLY, C_TEMP, C_TIME
    rel = np.zeros((n, COND), np.int64)
    rel[:, C_TEMP], rel[:, C_TIME], rel[:, C_SUPPLY] = dT, dt, dV
    return rel
