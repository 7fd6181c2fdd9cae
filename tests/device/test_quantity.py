"""A board quantity is a column of the conditions (issue 48: a new quantity in 5 files).

The conditions travel as one array a point, and the references as a second array with the same
columns: a quantity added where docs/model-discovery.md "How to add a board quantity" says (its
column, unit, least spread, source and reader rows in fixed.py; its effect's row in effects.py;
its reader function in the board file) is carried by the bins, the held-out set, the fit's
references, the calibration's block test and the app's block reads without another line.  And the
names of a quantity (the supply's) stay in the files that list allows."""
import os
import re
import shutil
import subprocess
import sys
import tokenize
from pathlib import Path

import numpy as np

from accelcal import simulate
from accelcal.bridge import runtime
from accelcal.locations import CHIP_DIR
from accelcal.simulate.stimulus import write_stimulus
from acal.logger.processor import BLOCK

ROOT = Path(__file__).resolve().parents[2]

# A run of the device code: points at three temperatures, seven postures, a fourth condition
# (here "humidity") varying from point to point; a composed pipeline (temp_offset) tracking every
# condition or only the model's (argv[1]: pipeline.track's every), its fit, its references, a
# Calibration set from them and its block test, and a held-out set's storage.
RUN = r'''
import sys
from acal.core import bins, effects, fixed
from acal.core.pipeline import Pipeline, track
from acal.core.calibration import Calibration
from acal.discover.heldout import HeldOut
H = getattr(fixed, "C_HUMIDITY", -1)
G = 65536
posture = [(G, 0, 0), (-G, 0, 0), (0, G, 0), (0, -G, 0), (0, 0, G), (0, 0, -G),
           (46341, 46341, 0), (0, 46341, 46341), (46341, 0, 46341)]
pipe = Pipeline(kinds=(effects.TEMP_OFFSET,), fit=1, max_count=4)
EVERY = sys.argv[1] == '1'
track(pipe.bins, pipe.kinds, EVERY)
n = 0
humid = []
for k in range(36):
    x, y, z = posture[k % 9]
    temp = (20 + 6 * (k // 9 % 3)) << fixed.TEMP_Q
    pipe.now[fixed.C_TEMP] = temp
    pipe.now[fixed.C_TIME] = 30 * k
    pipe.now[fixed.C_SUPPLY] = 3900
    if H >= 0:
        pipe.now[H] = 300 + 37 * ((5 * k) % 17)
    c = 150 * (temp >> fixed.TEMP_Q)       # a temperature offset, Q16 g
    if pipe.offer(x + c + (k % 5), y - c + (k % 3), z + 2 * c) >= 0 and H >= 0:
        humid.append(pipe.now[H])
held = [pipe.bins.condition(s, k) for s in range(9) for k in range(pipe.bins.counts[s])]
status = pipe.calibrate()
print("P", status, list(pipe.optimiser.p))
print("R", list(pipe.ref))
print("D", list(pipe.bins.differs), pipe.bins.span(H) if H >= 0 else -1)
if H >= 0 and EVERY:
    hs = [c[H] for c in held]
    assert pipe.ref[H] == (min(hs) + max(hs)) >> 1, (list(pipe.ref), hs)
    cal = Calibration(pipe.kinds, now=pipe.now)
    cal.set(pipe.optimiser.p, pipe.ref)
    assert cal.ref[H] == pipe.ref[H]
    buf = bins.int32s(3)
    buf[0] = 1024
    cal.apply_samples(buf, 0, 1)
    made = cal.terms_valid and cal.at[H] == pipe.now[H]
    pipe.now[H] += 1                       # only the fourth condition moves: new terms
    cal.terms_valid = True
    cal.apply_samples(buf, 0, 1)
    assert made and cal.at[H] == pipe.now[H]
    h = HeldOut()
    pipe.now[fixed.C_TIME] = 113          # a held-out block's time
    h.offer(G, 0, 0, pipe.now)
    assert h.cond[bins.COND * 0 + H] == pipe.now[H] and bins.COND == 4
    print("O K")
'''


# The quantity's facts in the device's one file for them, fixed.py "conditions" (the docs' list):
# its column and unit, one column more, its least spread, its source (a SOURCE_ id and its
# SOURCES row: column, shift into Q16, clamp) and its reader (BOARD_READERS: the board file's
# function, the clamps).
HUMIDITY_IN_FIXED = (
    ("C_SUPPLY = const(2)", "C_SUPPLY = const(2)\nC_HUMIDITY = const(3)  # 0.1 %RH"),
    ("COND = const(3)", "COND = const(4)"),
    ("    100,            # C_SUPPLY: mV\n",
     "    100,            # C_SUPPLY: mV\n    50,             # C_HUMIDITY: 5 %RH\n"),
    ("SOURCE_SUPPLY = const(4)", "SOURCE_SUPPLY = const(4)\nSOURCE_HUMIDITY = const(5)"),
    ("    SOURCE_SUPPLY: (C_SUPPLY, 6, 1024),",
     "    SOURCE_SUPPLY: (C_SUPPLY, 6, 1024),\n    SOURCE_HUMIDITY: (C_HUMIDITY, 6, 1024),"),
    ("    (C_SUPPLY, \"supply_mv\", 0, 65535),",
     "    (C_SUPPLY, \"supply_mv\", 0, 65535),\n    (C_HUMIDITY, \"humidity_dmrh\", 0, 1000),"),
)


def edit(path: Path, edits) -> None:
    text = path.read_text()
    for old, new in edits:
        assert text.count(old) == 1, old
        text = text.replace(old, new)
    path.write_text(text)


def add_humidity(tree: Path) -> None:
    """The quantity added as the docs' list says, in fixed.py and nowhere else on the device."""
    edit(tree / "acal/core/fixed.py", HUMIDITY_IN_FIXED)


def run(tree: Path, every: bool) -> dict:
    env = dict(os.environ, PYTHONPATH=str(tree))
    out = subprocess.run([sys.executable, "-c", RUN, "1" if every else "0"], capture_output=True,
                         text=True, env=env,
                         cwd=tree, timeout=300)
    assert out.returncode == 0, out.stderr[-3000:]
    return {line[0]: line[2:] for line in out.stdout.splitlines() if line}


def test_a_fourth_condition_travels_as_a_column_and_changes_nothing_else(tmp_path):
    """With a fourth condition added in fixed.py alone: untracked (no effect reads
    it), the fit's parameters and the other references are the very integers of the
    three-column device on the same points; tracked (every condition, as a discovering
    board's bins), the bins hold its least spread in `differs`, the fit's references have it
    (the middle of the held points'), the calibration takes it and makes its terms again when
    it alone moves, and the held-out set keeps it."""
    plain = tmp_path / "plain"
    four = tmp_path / "four"
    shutil.copytree(ROOT / "device", plain, ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copytree(ROOT / "device", four, ignore=shutil.ignore_patterns("__pycache__"))
    add_humidity(four)
    # the model's own conditions tracked (temperature): the fourth carried, untouched
    a, b = run(plain, False), run(four, False)
    assert a["P"] == b["P"] and a["P"].split()[0] == "0"     # status OK, the same integers
    ra, rb = eval(a["R"]), eval(b["R"])
    assert len(ra) == 3 and len(rb) == 4 and rb[:3] == ra and rb[3] == 0   # not tracked
    # every condition tracked (a discovering board's bins): the fourth's checks in RUN
    c = run(four, True)
    assert "O" in c and "O" not in b and c["P"].split()[0] == "0"
    differs, span = c["D"].rsplit(" ", 1)
    assert eval(differs) == [12, 675, 100, 50] and int(span) >= 50


# The fourth condition read by an effect: an offset linear in it (the quantity's EFFECTS row
# and its SOURCES row in effects.py, add_humidity_effect).  Rest means of an ideal sensor at nine
# postures, each with that offset at its humidity; a pipeline fits it (its reference the middle of
# the held points'), and a Calibration set from the fit applies samples at two humidities.
FIT = r"""
from acal.core import effects, fixed
from acal.core.pipeline import Pipeline
from acal.core.calibration import Calibration
H = fixed.C_HUMIDITY
THETA = (2621, -1966, 1311)          # the offset, Q16 g per (dH / 1024): 0.04, -0.03, 0.02 g
G = 65536
posture = [(G, 0, 0), (-G, 0, 0), (0, G, 0), (0, -G, 0), (0, 0, G), (0, 0, -G),
           (46341, 46341, 0), (0, 46341, 46341), (46341, 0, 46341)]
pipe = Pipeline(kinds=(effects.HUMIDITY_OFFSET,), fit=1, max_count=4)
for k in range(36):
    x, y, z = posture[k % 9]
    h = 100 + 29 * ((7 * k) % 36)                # 0.1 %RH: 10 .. 111.5 %RH
    pipe.now[fixed.C_TIME] = 30 * k
    pipe.now[H] = h
    o = [(t * (h - 600)) // 1024 for t in THETA]
    pipe.offer(x + o[0] + (k % 5), y + o[1] - (k % 3), z + o[2])
status = pipe.calibrate()
p = list(pipe.optimiser.p)
print("P", status, p[9:12], pipe.ref[H])
cal = Calibration(pipe.kinds, now=pipe.now)
cal.set(p, pipe.ref)
for h in (150, 1050):                            # a sample at rest on x at two humidities
    cal.now[H] = h
    o = [(t * (h - 600)) // 1024 for t in THETA]  # Q16 g
    cal.apply(1024 + (o[0] >> 6), o[1] >> 6, o[2] >> 6)
    print("A", h, cal.x, cal.y, cal.z, cal.out_q)
"""


def add_humidity_effect(tree: Path) -> None:
    """The quantity's effect, as the docs' list says, in effects.py alone: its kind and its
    EFFECTS row, an offset linear in the source that fixed.py declares."""
    edit(tree / "acal/core/effects.py", (
        ("                             SOURCE_SUPPLY)\n",
         "                             SOURCE_SUPPLY, SOURCE_HUMIDITY)\n"),
        ("SUPPLY_OFFSET = const(12)", "SUPPLY_OFFSET = const(12)\nHUMIDITY_OFFSET = const(13)"),
        ("EFFECTS = {\n", "EFFECTS = {\n    HUMIDITY_OFFSET: (\"humidity_offset\", SOURCE_HUMIDITY, 1, "
         "FORM_OFFSET, 0, 8, 4, 0, GENERIC_BOUND),\n")))


def test_an_effect_of_a_new_quantity_is_fitted_and_applied(tmp_path):
    """The fourth condition with an offset linear in it, added in the list's device files alone
    (fixed.py, effects.py): the device (CPython and the real MicroPython, the same
    integers) fits its coefficient from simulated points (against the simulated offset) and the
    apply removes it (the same posture at two
    humidities 90 %RH apart calibrates to the same g, and to the posture)."""
    tree = tmp_path / "four"
    shutil.copytree(ROOT / "device", tree, ignore=shutil.ignore_patterns("__pycache__"))
    add_humidity(tree)
    add_humidity_effect(tree)
    env = dict(os.environ, PYTHONPATH=str(tree))
    out = subprocess.run([sys.executable, "-c", FIT], capture_output=True, text=True, env=env,
                         cwd=tree, timeout=300)
    assert out.returncode == 0, out.stderr[-3000:]
    # the real MicroPython (its viper fit: the new source's column read by correct_kinds) too
    real = subprocess.run([runtime.micropython_path(), "-c", FIT], capture_output=True,
                          text=True, env=dict(os.environ, MICROPYPATH=str(tree)), cwd=tree,
                          timeout=300)
    assert real.stdout == out.stdout, real.stderr[-3000:]
    lines = [line.split() for line in out.stdout.splitlines()]
    status, rest = lines[0][1], " ".join(lines[0][2:])
    assert status == "0", out.stdout
    coeffs, ref = eval(rest.rsplit(" ", 1)[0]), int(rest.rsplit(" ", 1)[1])
    want = (0.04, -0.03, 0.02)            # g per (dH / 1024); the fit's p: Q24 per unit
    assert 100 <= ref <= 1115
    for c, w in zip(coeffs, want):
        assert abs(c / 2 ** 24 - w) < 0.002, (coeffs, want)
    (_, h1, *a1), (_, h2, *a2) = lines[1], lines[2]
    q = int(a1[3])
    g1 = [int(v) / 2 ** q for v in a1[:3]]
    g2 = [int(v) / 2 ** q for v in a2[:3]]
    # the raw samples differ by up to 35 mg; calibrated, under 1.5 mg, and both at (1, 0, 0) g
    assert max(abs(a - b) for a, b in zip(g1, g2)) < 0.0015, (g1, g2)
    assert max(abs(a - b) for a, b in zip(g1, (1, 0, 0))) < 0.003, g1


# The app on a board whose board file reads the new quantity (HUMIDITY_IN_FIXED's reader row:
# humidity_dmrh(), 0.1 %RH, clamped to 0..1000): the simulated chip behind its bus and a reader
# that ramps from -10 %RH past 100 %RH (there past int32, which the conditions' array cannot
# hold unclamped), every 7th read failing.  A model with the quantity's
# effect is refused on a board file without the reader; with it, the app runs the stimulus.
APP = r"""
import sys
from simboard import SimBoard
from acal.core import fixed
from acal.logger.app import App
H = fixed.C_HUMIDITY


class Plain:
    # a board file without the reader
    def __init__(self, stim):
        self.sim = SimBoard(stim)
        self.clock, self.I2C_ADDRESS = self.sim.clock, self.sim.I2C_ADDRESS

    def i2c(self):
        return self.sim.i2c()

    def exhausted(self):
        return self.sim.exhausted()


class Humid(Plain):
    # with the reader
    reads = 0

    def humidity_dmrh(self):
        self.reads += 1
        if self.reads % 7 == 0:
            raise OSError(5)
        v = (37 * self.reads) % 1200 - 100
        return v if v <= 1000 else v << 32   # past 1000, past int32 too: clamped before stored


try:
    App(Plain(sys.argv[1]), rate_hz=25, model="base+humidity_offset")
    print("E none")
except ValueError as e:
    print("E", e)
b = Humid(sys.argv[1])
app = App(b, rate_hz=25, model="base+humidity_offset")
app.run()
bins = app.proc.pipe.bins
held = [bins.condition(s, k)[H] for s in range(9) for k in range(bins.counts[s])]
print("N", app.samples, b.reads, app.bus_errors, app.now[H], bins.differs[H])
print("H", sorted(held))
if sys.argv[2] == "lock":    # MicroPython: a block's condition reads allocate nothing
    import micropython
    while (b.reads + 1) % 7 == 0:
        app._read_conditions()
    micropython.heap_lock()
    app._read_conditions()
    micropython.heap_unlock()
    print("L", b.reads, app.now[H])
"""


def rest_stimulus(path: Path) -> int:
    """24 postures held 8 s, moves of 2 s between them, 25 Hz, 30 degC: its samples."""
    rng = np.random.default_rng(48)
    parts = []
    for d in simulate.unit_points(rng, 24):
        parts.append(d + rng.normal(scale=0.0016, size=(25 * 8, 3)))
        parts.append(d + rng.normal(scale=0.3, size=(25 * 2, 3)))
    xyz = np.clip(np.concatenate(parts), -1.9, 1.9)
    write_stimulus(path, 25, xyz, np.full(len(xyz), 30.0))
    return len(xyz)


def test_the_app_reads_a_new_quantity_from_the_board_file(tmp_path):
    """The quantity and its effect added in fixed.py and effects.py alone, its reader in the
    board file: the app (CPython and the real MicroPython, the same output) refuses the model
    on a board file without the reader, in one line naming it; with it, reads it once a block
    (a read per block fed), clamped to the row's 0..1000, a failed read counted as a bus error
    and keeping the last value; the bins track it (its least spread) and hold the values read;
    and a block's reads allocate nothing (MicroPython, heap locked)."""
    tree = tmp_path / "four"
    shutil.copytree(ROOT / "device", tree, ignore=shutil.ignore_patterns("__pycache__"))
    add_humidity(tree)
    add_humidity_effect(tree)
    stim = tmp_path / "stim.bin"
    n = rest_stimulus(stim)
    (tmp_path / "cp").mkdir()
    (tmp_path / "mp").mkdir()
    out = subprocess.run([sys.executable, "-c", APP, str(stim), "-"], capture_output=True,
                         text=True, cwd=tmp_path / "cp", timeout=300,
                         env=dict(os.environ, PYTHONPATH=f"{tree}:{CHIP_DIR}"))
    assert out.returncode == 0, out.stderr[-3000:]
    real = subprocess.run([runtime.micropython_path(), "-c", APP, str(stim), "lock"],
                          capture_output=True, text=True, cwd=tmp_path / "mp", timeout=300,
                          env=dict(os.environ, MICROPYPATH=f"{tree}:{CHIP_DIR}"))
    assert real.returncode == 0, real.stderr[-3000:]
    lines = out.stdout.splitlines()
    assert real.stdout.splitlines()[:3] == lines, (real.stdout, out.stdout)
    assert lines[0] == ("E model's humidity_offset follows a column the board reads: its board "
                        "file needs humidity_dmrh()")
    samples, reads, errors, now, differ = map(int, lines[1].split()[1:])
    assert samples == n and reads == -(-n // BLOCK)           # one read a block fed
    assert errors == reads // 7 and differ == 50               # the bus's own: none
    ok = [min(1000, max(0, (37 * i) % 1200 - 100)) for i in range(1, reads + 1) if i % 7]
    assert now == ok[-1]                                       # the last good read, clamped
    held = eval(lines[2][2:])
    assert held and set(held) <= set(ok) and max(held) - min(held) >= 50, held
    lock = real.stdout.splitlines()[3].split()
    assert lock[0] == "L" and int(lock[2]) == min(1000, max(0, (37 * int(lock[1])) % 1200 - 100))


# The host's side: the quantity's QUANTITIES row added in fixedpoint.py alone (on a copy of the
# host package beside the edited device tree).  Its built-in effect, the conditions' column and the
# twin's apply follow from the row: the twin applies samples at moving humidities as the device's
# Calibration does.
HUMIDITY_IN_QUANTITIES = (
    ("\n)\n# the ones read from a recording's further columns",
     """
    Quantity("humidity", "humidity_dmrh", fixed.DIFFERS[fixed.C_HUMIDITY], None,
             ("{} dmRH of humidity_dmrh", "{}"), kind=deff.HUMIDITY_OFFSET,
             per=fixed.SOURCES[fixed.SOURCE_HUMIDITY][2], unit="dmRH",
             effect=("h", 1e6, "mg/kdmRH", "The zero-g level follows the humidity.")),
)
# the ones read from a recording's further columns"""),
)
HOST = r"""
import numpy as np
import accelcal
from acal.core import effects as deff, fixed
from acal.core.calibration import Calibration
from accelcal.fixedpoint import QUANTITIES, device_conditions
from accelcal.model.effects import CATALOGUE, ModelSpec, device_effects
from accelcal.bridge import twin
print("F", accelcal.__file__)
e = CATALOGUE["humidity_offset"]
q = QUANTITIES[fixed.C_HUMIDITY]
print("Q", q.name, e.quantity is q, e.kind, e.needs, e.column, e.unit, e.int_scale / 2 ** 24,
      round(e.bound * 1024 / 0.05, 6), "humidity_offset" in device_effects(),
      [x.name for x in ModelSpec.parse("base+humidity_offset").parts])
h = np.array([120.0, 480.4, 999.6])
print("C", device_conditions(np.array([20.0] * 3), np.zeros(3), 0.0, 3, humidity=h)[:, 3].tolist())
rng = np.random.default_rng(5)
p = [16777216 + 20000, 16777216 - 15000, 16777216 + 9000, 3000, -2000, 1000, 70000, -50000,
     30000] + e.to_int([0.03 / 1024, -0.02 / 1024, 0.01 / 1024])
ref = [0, 0, 0, 500]
cal = Calibration((deff.HUMIDITY_OFFSET,))
cal.set(p, ref)
samples = rng.integers(-1500, 1500, (40, 3))
hs = rng.integers(0, 1001, 40)
dev, at_ref = [], []
for (x, y, z), hv in zip(samples.tolist(), hs.tolist()):
    for now, out in ((hv, dev), (ref[fixed.C_HUMIDITY], at_ref)):
        cal.now[fixed.C_HUMIDITY] = now
        cal.apply(x, y, z)
        out.append([cal.x, cal.y, cal.z])
rel = np.zeros((40, fixed.COND), dtype=np.int64)
rel[:, fixed.C_HUMIDITY] = hs - ref[fixed.C_HUMIDITY]
host = twin.apply_params(p, samples, (deff.HUMIDITY_OFFSET,), rel)
print("T", host.tolist() == dev, int(np.abs(np.array(dev) - np.array(at_ref)).max()))
"""


def test_the_host_takes_a_new_quantity_from_its_quantities_row(tmp_path):
    """The quantity added in the list's files (device: fixed.py, effects.py; host: its
    QUANTITIES row in fixedpoint.py alone): the host's catalogue has its built-in effect (the
    device's kind and name, Q24 per 1024 units, 0.05 g per 1024 units), a model names it, the
    host's conditions carry its column, and the twin applies it as the device's Calibration
    does (the same integers, samples at moving humidities)."""
    tree = tmp_path / "device"
    shutil.copytree(ROOT / "device", tree, ignore=shutil.ignore_patterns("__pycache__"))
    add_humidity(tree)
    add_humidity_effect(tree)
    host = tmp_path / "host"
    shutil.copytree(ROOT / "host", host, ignore=shutil.ignore_patterns("__pycache__"))
    edit(host / "accelcal/fixedpoint.py", HUMIDITY_IN_QUANTITIES)
    out = subprocess.run([sys.executable, "-c", HOST], capture_output=True, text=True,
                         cwd=tmp_path, timeout=300,
                         env=dict(os.environ, PYTHONPATH=f"{tree}:{host}"))
    assert out.returncode == 0, out.stderr[-3000:]
    lines = {line[0]: line[2:] for line in out.stdout.splitlines()}
    assert lines["F"].startswith(str(host)), lines["F"]            # the edited copy
    assert lines["Q"].split() == ["humidity", "True", "13", "col", "humidity_dmrh",
                                  "g/dmRH", "1024.0", "1.0", "True", "['humidity_offset']"]
    assert eval(lines["C"]) == [120, 480, 1000]
    same, moved = lines["T"].split()
    # 0.03 g per 1024 units, up to 500 units from the reference: up to 120 LSB of Q13 g
    assert same == "True" and 60 < int(moved) <= 125, lines["T"]


# Where the supply's names (identifiers containing "supply", not comments or strings) may stand,
# and why.  A file outside this list that names it means a quantity is named again where the
# conditions' columns should carry it.
SUPPLY_NAMED = {
    # device: the docs' list
    "device/acal/core/fixed.py": "its column, least spread, source and reader rows",
    "device/acal/core/effects.py": "its effect's EFFECTS row (SUPPLY_OFFSET from SOURCE_SUPPLY)",
    # device: left (docs/model-discovery.md)
    "device/acal/discover/search.py": "the discovery's candidate list (SUPPLY_OFFSET)",
    "device/acal/logger/log.py": "the SUPPLY capture record (a log format)",
    "device/acal/logger/processor.py": "writes the SUPPLY capture record when it changes",
    # host
    "host/accelcal/fixedpoint.py": "its QUANTITIES row",
    "host/accelcal/model/effects.py": "its CATALOGUE effect and recording column",
    "host/accelcal/bridge/boardlog.py": "decodes the SUPPLY record and the EFFECT reference",
    "host/accelcal/pipeline/discovered.py": "a discovered supply effect's report",
    "host/accelcal/simulate/chip/simboard.py": "the simulated board's supply_mv",
    "host/accelcal/simulate/chip/vlis3dh.py": "the simulated chip's board supply",
    "host/accelcal/simulate/stimulus.py": "the simulated supply over a day",
    "host/accelcal/simulate/wearer.py": "the simulated recording's supply column",
}


def names_supply(path: Path) -> bool:
    with open(path, "rb") as f:
        return any(t.type == tokenize.NAME and re.search("supply", t.string, re.I)
                   for t in tokenize.tokenize(f.readline))


def test_the_supply_is_named_only_where_the_list_allows():
    named = {str(p.relative_to(ROOT)) for folder in ("device/acal", "host/accelcal")
             for p in (ROOT / folder).rglob("*.py") if names_supply(p)}
    assert named <= set(SUPPLY_NAMED), sorted(named - set(SUPPLY_NAMED))
    # the core's conditions path names no quantity: the references and the offers are columns,
    # and the effect code reads its source's column from the relative conditions (SOURCES)
    for f in ("device/acal/core/pipeline.py", "device/acal/core/reference.py",
              "device/acal/core/bins.py", "device/acal/logger/app.py",
              "device/acal/discover/heldout.py", "device/acal/discover/plug.py",
              "device/acal/core/calibration.py", "device/acal/discover/score.py",
              "device/acal/core/model.py", "device/acal/core/normal_sums.py",
              "host/accelcal/bridge/twin.py", "host/accelcal/pipeline/apply.py",
              "host/accelcal/bridge/protocol.py", "host/accelcal/bridge/scripts/mp_runner.py"):
        assert not names_supply(ROOT / f), f
