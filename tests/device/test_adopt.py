"""A discovering board's adoption gives its bins a composed model's points (device/acal/discover/plug.py,
Pipeline.adopt; docs/model-discovery.md "Points for a composed model"): the wear bins go from 8 to
14 points per subset in the room they have from the start (the fit points and fits take 126
from the start too), every held point and its conditions kept in its subset and slot; fed the
same rest means from then on, the grown pipeline holds the same points and fits the same
parameters, bit for bit, as a pipeline booted fresh with the adopted model (its bins and fits
126 points from the start) that holds the same points at the adoption; more than 72 points are
then held and fitted.  The real MicroPython (unix and 32-bit ports) prints the same, the points
fed after the adoption under heap_lock (nothing allocated per point).  A Processor (the board's,
and the replay's) calibrates on 126 after its adoption, MicroPython logging the same bytes.  The
paper profile's fit keeps its counts."""
import numpy as np
import pytest

from accelcal.bridge.boardlog import model_kinds
from accelcal import simulate
from accelcal.bridge import boardlog, runtime
from acal.core import effects, profile
from acal.logger import log
from acal.core.bins import Bins
from acal.core.fixed import C_TEMP, C_TIME
from acal.discover.plug import grow_bins
from acal.core.pipeline import Pipeline
from acal.discover.plug import Plug

TRUTH = np.array([1.02, 0.98, 1.01, 0.004, -0.006, 0.003, 0.03, -0.02, 0.04])
C_TRUE = np.array([0.0009, -0.0007, 0.0006])    # g/degC: temp_offset
D_TRUE = np.array([0.002, -0.0025, 0.0015])     # g a day: drift


def rest_means(seed, first, n, drift):
    """n rest means (x y z Q16 g, temp Q2 degC, time 64 s units, flat) of a sensor with errors
    TRUTH, temp_offset C_TRUE and drift (g a day), one every 7 time units (7.5 min) from the
    first-th, at a daily temperature cycle (22-34 degC); tests/device/test_discover.py's stream."""
    rng = np.random.default_rng(seed)
    d = simulate.unit_points(rng, n)
    out = []
    for i in range(n):
        time = 7 * (first + i)
        temp = int(round(4 * (28 + 6 * np.sin(2 * np.pi * time * 64 / 86400))))
        v = simulate.uncorrect(TRUTH, d[i][None, :])[0] + C_TRUE * (temp / 4 - 28)
        v += rng.normal(scale=0.001, size=3) + drift * (time * 64 / 86400)
        out += [int(round(x * 65536)) for x in v] + [temp, time]
    return " ".join(map(str, out))


# PTS: the stream up to the calibration the discovery follows; MORE: the stream after the
# adoption; ROUNDS: the adoptions (2: the discovery ends with the second, as a fresh pipeline of
# that model runs without one; 1: it goes on, the fresh pipeline takes the points at the end).
SCRIPT = r'''
from acal.core import profile
from acal.core.bins import N_SUBSETS
from acal.core.fixed import C_TEMP, C_TIME
from acal.core.pipeline import Pipeline
from acal.discover.plug import Plug
try:
    from micropython import heap_lock, heap_unlock
except ImportError:   # CPython
    def heap_lock():
        pass

    def heap_unlock():
        pass

PTS = [int(v) for v in "%s".split()]
MORE = [int(v) for v in "%s".split()]
ROUNDS = %d


def feed(pipe, pts):
    for i in range(len(pts) // 5):
        pipe.now[C_TEMP] = pts[5 * i + 3]
        pipe.now[C_TIME] = pts[5 * i + 4]
        pipe.offer(pts[5 * i], pts[5 * i + 1], pts[5 * i + 2])


def held(b):
    out = []
    for s in range(N_SUBSETS):
        for k in range(b.counts[s]):
            out.append(b.point(s, k) + b.condition(s, k))
    return out


def seed(dst, src):
    # dst's bins hold src's points, each in its subset and slot, with its conditions
    m = dst.max_count
    for s in range(N_SUBSETS):
        for k in range(src.counts[s]):
            j = s * m + k
            x, y, z = src.point(s, k)
            t, u, v = src.condition(s, k)
            dst.xyz[3 * j] = x
            dst.xyz[3 * j + 1] = y
            dst.xyz[3 * j + 2] = z
            dst.cond[3 * j] = t
            dst.cond[3 * j + 1] = u
            dst.cond[3 * j + 2] = v
        dst.counts[s] = src.counts[s]
    dst.changes += 1


def show(tag, pipe, status):
    o = pipe.optimiser
    print(tag, status, o.n_given, o.n, " ".join(str(v) for v in o.p[:o.n_params]))


pipe = Pipeline(10, plug=Plug(), **profile.settings(profile.WEAR))
feed(pipe, PTS)
print("BASE", pipe.calibrate(), pipe.n_fit, max(pipe.bins.counts))
d = pipe.plug.discovery
for rnd in range(ROUNDS):
    d.run(pipe)
    before = held(pipe.bins)
    if d.adopted:
        pipe.plug.adopt(pipe)
    print("ADOPTED", d.kind, pipe.bins.max_count, pipe.optimiser.max_points,
          pipe.base_fit.max_points, 1 if held(pipe.bins) == before else 0)
fresh = Pipeline(10, kinds=pipe.kinds, **profile.settings(profile.WEAR, True))
if ROUNDS == 2:
    seed(fresh.bins, pipe.bins)
heap_lock()
try:
    feed(pipe, MORE)
    if ROUNDS == 2:
        feed(fresh, MORE)
    heap_unlock()
except MemoryError:
    heap_unlock()
    print("ALLOCATED")
if ROUNDS == 1:
    seed(fresh.bins, pipe.bins)
print("HELD", 1 if held(pipe.bins) == held(fresh.bins) else 0, pipe.bins.total(),
      " ".join(str(c) for c in pipe.bins.counts))
show("GROWN", pipe, pipe.calibrate())
show("FRESH", fresh, fresh.calibrate())
if ROUNDS == 1:   # the discovery's next round, on more than 72 fit points
    d.run(pipe)
    print("ROUND2", d.kind, d.chosen, " ".join(str(e) for e in d.errs))
'''


def _script(tmp_path, rounds, drift):
    f = tmp_path / f"adopt{rounds}.py"
    f.write_text(SCRIPT % (rest_means(9, 0, 420, drift), rest_means(10, 420, 300, drift), rounds))
    return f


def _cpython(f):
    import contextlib
    import io
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        exec(compile(f.read_text(), str(f), "exec"), {"__name__": "adopt"})
    return buf.getvalue()


def _lines(out):
    return {line.split()[0]: line.split()[1:] for line in out.splitlines()}


@pytest.mark.parametrize("rounds", [2, 1])
def test_adopted_bins_take_a_composed_models_points_as_a_fresh_pipeline(tmp_path, mp32, rounds):
    """rounds 2: temp_offset and drift hidden, both adopted (the first adoption grows, the second
    ends the discovery), then 300 rest means more fed to the grown pipeline and to a fresh
    base+temp_offset+drift pipeline holding the same points: the same points held, the same
    fit.  rounds 1: temp_offset alone, adopted, the discovery going on; the points held after
    300 more fitted alike by the grown pipeline and a fresh base+temp_offset one, and the next
    round runs on them."""
    f = _script(tmp_path, rounds, D_TRUE if rounds == 2 else np.zeros(3))
    want = _cpython(f)
    for out in (runtime.run_micropython_script(str(f)), mp32(str(f))):
        assert out == want
    v = _lines(want)
    assert "ALLOCATED" not in v, want
    assert v["BASE"][:3] == ["0", "72", "8"], want    # the base fit on the base model's 72 points
    kind, count, fit_points, base_points, kept = map(int, v["ADOPTED"])
    want_kinds = (effects.TEMP_OFFSET, effects.DRIFT) if rounds == 2 else (effects.TEMP_OFFSET,)
    assert set(model_kinds(kind)) == set(want_kinds), want
    # grown to the wear profile's composed count, every held point kept in its subset and slot
    assert count == profile.WEAR_COMPOSED_MAX_COUNT and fit_points == base_points == 126
    assert kept == 1
    same, total, *counts = map(int, v["HELD"])
    assert same == 1 and total > 72 and max(counts) > 8, want
    grown, new = v["GROWN"], v["FRESH"]
    assert grown == new and grown[0] == "0" and int(grown[1]) == total, want
    if rounds == 1:
        assert int(v["ROUND2"][1]) >= 0, want     # candidates fitted on the grown points


# A Processor (the app's, as a board runs it and `replay` re-runs a capture) started with `base`
# and discover=True, given the same rest means: its first calibration (the held-out points then
# leave the bins), its second with the discovery, which adopts, then the rest means after it and
# a third calibration.
PROCESSOR = r'''
import sys
from acal.logger import log
from acal.logger.processor import Processor
from acal.core.fixed import C_TEMP, C_TIME

PTS = [int(v) for v in "%s".split()]
MORE = [int(v) for v in "%s".split()]


def feed(p, pts):
    for i in range(len(pts) // 5):
        p.pipe.now[C_TEMP] = pts[5 * i + 3]
        p.pipe.now[C_TIME] = pts[5 * i + 4]
        p.pipe.offer(pts[5 * i], pts[5 * i + 1], pts[5 * i + 2])


lg = log.Log(sys.argv[1])
p = Processor(lg, 10, discover=True)
count = p.pipe.bins.max_count
feed(p, PTS)
p.calibrate()
p.calibrate()
adopted = p.pipe.bins.max_count
feed(p, MORE)
p.calibrate()
lg.close()
print(count, adopted, len(p.kinds), max(p.pipe.bins.counts))
'''


def test_a_processor_calibrates_on_more_than_72_points_after_adopting(tmp_path):
    """The Processor's adoption (Processor._discovered -> Pipeline.adopt) grows its bins: 8 a
    subset before, 14 after, its calibration after the adoption on more than 72 points; the
    real MicroPython logs the same bytes."""
    f = tmp_path / "processor.py"
    f.write_text(PROCESSOR % (rest_means(9, 0, 420, np.zeros(3)), rest_means(10, 420, 300,
                                                                           np.zeros(3))))
    import sys
    argv = sys.argv
    sys.argv = [str(f), str(tmp_path / "cpython.bin")]
    try:
        out = _cpython(f).split()
    finally:
        sys.argv = argv
    assert runtime.run_micropython_script(str(f), str(tmp_path / "mp.bin")).split() == out
    assert (tmp_path / "cpython.bin").read_bytes() == (tmp_path / "mp.bin").read_bytes()
    assert out[:3] == ["8", "14", "1"] and int(out[3]) > 8, out
    d = boardlog.decode(tmp_path / "cpython.bin")
    found = d.dicts(log.DISCOVERY)     # the second calibration's, then the third's (round 2)
    assert found[0]["adopted"] == effects.model_code((effects.TEMP_OFFSET,)), found
    cals = d.dicts(log.CAL)            # the first two, the adopted one, the third
    assert max(c["points"] for c in cals[:-1]) <= 72 < cals[-1]["points"], cals


def test_grown_bins_keep_every_point_and_then_fill_as_fresh_ones():
    """Bins of 8 a subset with room for 14, full, with a temperature and time spread tracked,
    grown to 14: each held point and its conditions in its subset and slot; then offered the
    same points as fresh bins of 14 seeded alike, they keep and replace the same, past 8 a
    subset.  Bins without the room refuse to grow."""
    rng = np.random.default_rng(3)
    pts = simulate.unit_points(rng, 400)
    temps = np.random.default_rng(4).integers(80, 140, 400)

    def offer(bins, i):
        x, y, z = (int(round(c * 65536)) for c in pts[i])
        bins.offer(x, y, z, (int(temps[i]), 50 * i, 3300))

    b = Bins(2, 8, differs=(12, 675, 0), coverage=True, room=14)
    for i in range(200):
        offer(b, i)
    held = {(s, k): (b.point(s, k), b.condition(s, k)) for s in range(9) for k in range(b.counts[s])}
    assert max(b.counts) == 8
    counts = list(b.counts)
    grow_bins(b, 14)
    assert b.max_count == 14 and b.counts == counts
    assert {(s, k): (b.point(s, k), b.condition(s, k))
            for s in range(9) for k in range(b.counts[s])} == held
    fresh = Bins(2, 14, differs=(12, 675, 0), coverage=True)
    for (s, k), (p, c) in held.items():
        j = s * 14 + k
        fresh.xyz[3 * j:3 * j + 3] = type(fresh.xyz)("i", p)
        fresh.cond[3 * j:3 * j + 3] = type(fresh.cond)("i", c)
    fresh.counts[:] = counts
    for i in range(200, 400):
        offer(b, i)
        offer(fresh, i)
    assert b.counts == fresh.counts and max(b.counts) > 8
    assert [b.point(s, k) + b.condition(s, k) for s in range(9) for k in range(b.counts[s])] == \
        [fresh.point(s, k) + fresh.condition(s, k) for s in range(9) for k in range(b.counts[s])]
    with pytest.raises(ValueError):
        grow_bins(Bins(2, 8), 14)


def test_a_discovering_pipeline_has_the_room_from_the_start():
    """Made with a Plug (discovery), a wear-profile pipeline's bins take 8 points a subset (what its
    BOOT record says) in room for 14, and its fit points and fits (the model's, the
    discovery's two) take 126: nothing is allocated when it adopts."""
    pipe = Pipeline(10, plug=Plug(), **profile.settings(profile.WEAR))
    assert pipe.bins.max_count == 8 and pipe.plug.count == 14
    assert len(pipe.bins.xyz) == len(pipe.bins.cond) == 3 * 126
    assert len(pipe.points) == len(pipe.aux) == 3 * 126
    d = pipe.plug.discovery
    assert pipe.optimiser.max_points == d.fit.max_points == d.spare.max_points == 126
    plain = Pipeline(10, **profile.settings(profile.WEAR))   # not discovering: as it was
    assert plain.plug is None and len(plain.bins.xyz) == len(plain.points) == 3 * 72
    assert plain.optimiser.max_points == 72


def test_the_paper_profiles_fit_keeps_its_counts():
    """profile.adopted_max_count: the wear fit takes the composed count (never fewer than it
    has), the paper's gradient descent, which never discovers, keeps its own."""
    wear = profile.settings(profile.WEAR)
    assert profile.adopted_max_count(wear["fit"], wear["max_count"]) == \
        profile.settings(profile.WEAR, True)["max_count"] == 14
    assert profile.adopted_max_count(profile.NEWTON, 14) == 14
    paper = profile.settings(profile.PAPER)
    assert profile.adopted_max_count(paper["fit"], paper["max_count"]) == paper["max_count"]
    assert len(Pipeline(10, **paper).bins.xyz) == 3 * 9 * paper["max_count"]


def test_the_core_pipeline_holds_no_discovery_state():
    """Discovery plugs in through one reference (Pipeline's plug, acal/discover/plug.py): a
    discovering pipeline has the same attributes as a base one, and no module of acal.core
    imports acal.discover (a board without discovery loads none of it: test_install_units)."""
    import pathlib
    settings = profile.settings(profile.WEAR)
    plain = Pipeline(10, **settings)
    found = Pipeline(10, plug=Plug(), **settings)
    assert sorted(vars(plain)) == sorted(vars(found))
    assert plain.plug is None and isinstance(found.plug, Plug)
    core = pathlib.Path(__file__).parents[2] / "device" / "acal" / "core"
    assert [p.name for p in core.glob("*.py") if "acal.discover" in p.read_text()] == []
