"""A board quantity is a column of the conditions (issue 48: a new quantity in few files).

The conditions travel as one array a point, and the references as a second array with the same
columns: a quantity added where docs/model-discovery.md "Adding a quantity the board reads" says
(its column in fixed.py, COND and its least spread in bins.py) is carried by the bins, the held-out
set, the fit's references and the calibration's block test without another line.  And the names of
a quantity (the supply's) stay in the files that list allows."""
import os
import re
import shutil
import subprocess
import sys
import tokenize
from pathlib import Path

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


def add_humidity(tree: Path) -> None:
    """The quantity added as the docs' list says, in its files and nowhere else: its column
    (fixed.py), one condition more and its least spread (bins.py)."""
    fixed = tree / "acal/core/fixed.py"
    text = fixed.read_text()
    anchor = "C_SUPPLY = const(2)"
    assert anchor in text
    fixed.write_text(text.replace(anchor, anchor + "\nC_HUMIDITY = const(3)  # 0.1 %RH"))
    b = tree / "acal/core/bins.py"
    text = b.read_text()
    for old, new in (("COND = const(3)", "COND = const(4)"),
                     ("DIFFERS = (TEMP_DIFFER, TIME_DIFFER, SUPPLY_DIFFER)",
                      "HUMIDITY_DIFFER = 50\nDIFFERS = (TEMP_DIFFER, TIME_DIFFER, SUPPLY_DIFFER, "
                      "HUMIDITY_DIFFER)")):
        assert old in text
        text = text.replace(old, new)
    b.write_text(text)


def run(tree: Path, every: bool) -> dict:
    env = dict(os.environ, PYTHONPATH=str(tree))
    out = subprocess.run([sys.executable, "-c", RUN, "1" if every else "0"], capture_output=True,
                         text=True, env=env,
                         cwd=tree, timeout=300)
    assert out.returncode == 0, out.stderr[-3000:]
    return {line[0]: line[2:] for line in out.stdout.splitlines() if line}


def test_a_fourth_condition_travels_as_a_column_and_changes_nothing_else(tmp_path):
    """With a fourth condition added in fixed.py and bins.py alone: untracked (no effect reads
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


# Where the supply's names (identifiers containing "supply", not comments or strings) may stand,
# and why.  A file outside this list that names it means a quantity is named again where the
# conditions' columns should carry it.
SUPPLY_NAMED = {
    # device: the docs' list
    "device/acal/core/fixed.py": "its column C_SUPPLY",
    "device/acal/core/bins.py": "its least spread SUPPLY_DIFFER in DIFFERS",
    "device/acal/core/effects.py": "its source, regressor scale (SUPPLY_MAX) and effect row",
    "device/acal/logger/app.py": "the board's reader (board.supply_mv) writing now[C_SUPPLY]",
    # device: left (docs/model-discovery.md): the effects' regressors take dT, dt, dV by name
    "device/acal/core/calibration.py": "the block terms' dV for effects.block_terms",
    "device/acal/discover/score.py": "the held-out points' dV for model.remove_effects",
    "device/acal/discover/search.py": "the discovery's candidate list (SUPPLY_OFFSET)",
    "device/acal/logger/log.py": "the SUPPLY capture record (a log format)",
    "device/acal/logger/processor.py": "writes the SUPPLY capture record when it changes",
    # host
    "host/accelcal/fixedpoint.py": "its QUANTITIES row",
    "host/accelcal/model/effects.py": "its CATALOGUE effect and recording column",
    "host/accelcal/bridge/boardlog.py": "decodes the SUPPLY record and the EFFECT reference",
    "host/accelcal/bridge/twin.py": "the vectorised apply's regressor of its source",
    "host/accelcal/pipeline/apply.py": "the difference from its reference handed to the twin",
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
    # the core's conditions path names no quantity: the references and the offers are columns
    for f in ("device/acal/core/pipeline.py", "device/acal/core/reference.py",
              "device/acal/discover/heldout.py", "device/acal/discover/plug.py",
              "host/accelcal/bridge/protocol.py", "host/accelcal/bridge/scripts/mp_runner.py"):
        assert not names_supply(ROOT / f), f
