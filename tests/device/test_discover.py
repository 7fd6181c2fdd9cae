"""The board's own model discovery (device/acal/discover/search.py, issue 29): a Processor started with
`base` and discover=True, fed a simulated stream (two days of rest postures at a daily
temperature cycle, a hidden temp_offset), adopts temp_offset and logs DISCOVERY, CAL and EFFECT
records that the real MicroPython reproduces byte for byte; on the same stream without the
effect it adopts nothing; the candidate fits and scores allocate nothing under heap_lock on the
unix and 32-bit ports, and the rule's products at the saturated errors stay small ints there.
A hidden shock inside a held-out block: the adopted step's time is placed between the held-out
points either side of it, allocating nothing either."""
import numpy as np
import pytest

from accelcal.bridge.boardlog import model_kinds
from accelcal import simulate
from accelcal.bridge import boardlog, runtime
from acal.discover import search
from acal.core import effects
from acal.logger import log
from acal.core.fixed import PARAM_NAMES
from posture_stream import STREAM

TRUTH = np.array([1.02, 0.98, 1.01, 0.004, -0.006, 0.003, 0.03, -0.02, 0.04])
C_TRUE = np.array([0.0009, -0.0007, 0.0006])    # g/degC: temp_offset, the LIS3DH's size
RATE = 10
GAP_SAMPLES = 4400            # 440 s between rest postures: 2 days in 384 postures


def postures(rng, c, n=384, drift=np.zeros(3)):
    """Per posture: the reading (Q10 g) of a sensor with errors TRUTH and temp_offset c at a
    daily temperature cycle (22-34 degC), and that temperature: x y z temp, flat; drift (g a
    day): a second hidden effect."""
    out = []
    d = simulate.unit_points(rng, n)
    for i in range(n):
        hours = i * (6 * 10 + 2 * 10 + GAP_SAMPLES) / RATE / 3600
        temp = int(round(28 + 6 * np.sin(2 * np.pi * hours / 24)))
        v = simulate.uncorrect(TRUTH, d[i][None, :])[0] + c * (temp - 28) + drift * hours / 24
        out += [int(round(x * 1024)) for x in v] + [temp]
    return out


def _stream(tmp_path, name, c, n=384, drift=np.zeros(3)):
    f = tmp_path / f"{name}.py"
    f.write_text(STREAM % (postures(np.random.default_rng(5), c, n, drift), GAP_SAMPLES))
    return f


def _run_cpython(script, out):
    import sys
    argv = sys.argv
    sys.argv = [str(script), str(out)]
    try:
        exec(compile(script.read_text(), str(script), "exec"), {"__name__": "stream"})
    finally:
        sys.argv = argv


def test_processor_adopts_the_hidden_effect_and_micropython_logs_the_same(tmp_path):
    script = _stream(tmp_path, "effect", C_TRUE)
    _run_cpython(script, tmp_path / "cpython.bin")
    runtime.run_micropython_script(str(script), str(tmp_path / "mp.bin"))
    ours = (tmp_path / "cpython.bin").read_bytes()
    assert ours == (tmp_path / "mp.bin").read_bytes()
    d = boardlog.decode(tmp_path / "cpython.bin")
    found = d.dicts(log.DISCOVERY)
    assert found, "no DISCOVERY record"
    last = found[-1]
    assert effects.NAMES[last["adopted"]] == "temp_offset", found
    assert all(f["adopted"] == 0 for f in found[:-1])
    assert last["heldout_after"] < 0.9 * last["heldout_before"]
    assert 10 * last["blocks_better"] >= 7 * last["blocks"]
    # the adopted calibration follows at once: a CAL and its EFFECT, the truth's signs
    eff = d.dicts(log.EFFECT)
    assert eff and eff[0]["index"] == last["index"] and eff[0]["effect"] == effects.TEMP_OFFSET
    p = np.array([eff[0][f"p{i}"] for i in range(3)]) / 2 ** 24 / 16   # g/degC (effects.py)
    assert np.all(np.sign(p) == np.sign(C_TRUE)) and np.all(np.abs(p - C_TRUE) < 3e-4), p
    # powered up again (the same store, still flashed with base and --discover): it goes on
    # with the adopted model and its stored parameters, not discovering again
    from acal.logger.processor import Processor
    cal = d.dicts(log.CAL)[-1]
    for f in ("cpython.bin", "mp.bin"):
        store = log.CalStore(str(tmp_path / f) + ".a", str(tmp_path / f) + ".b")
        again = Processor(log.Log(str(tmp_path / f"again-{f}")), 10, discover=True, store=store)
        assert again.kinds == (effects.TEMP_OFFSET,) and again.pipe.plug is None
        assert again.calibrations == cal["number"] and again.params[:9] == \
            [cal[n] for n in PARAM_NAMES] and again.params[9:] == [eff[-1][f"p{i}"] for i in range(3)]


def test_processor_adopts_a_second_effect_and_keeps_both(tmp_path):
    """Three days with temp_offset and drift hidden: the board adopts temp_offset, goes on
    discovering from base+temp_offset and adopts drift on top (a DISCOVERY record whose model
    code names both), the store keeps base+temp_offset+drift and a board powered up again takes
    it; MicroPython logs the same bytes."""
    script = _stream(tmp_path, "two", C_TRUE, 576, D_TRUE)
    _run_cpython(script, tmp_path / "cpython.bin")
    runtime.run_micropython_script(str(script), str(tmp_path / "mp.bin"))
    assert (tmp_path / "cpython.bin").read_bytes() == (tmp_path / "mp.bin").read_bytes()
    found = [f for f in boardlog.decode(tmp_path / "cpython.bin").dicts(log.DISCOVERY)
             if f["adopted"]]
    both = (effects.TEMP_OFFSET, effects.DRIFT)
    assert [model_kinds(f["adopted"]) for f in found] == [both[:1], both], found
    assert found[1]["heldout_after"] < 0.9 * found[1]["heldout_before"]
    # each DISCOVERY record carries the effect its round adopted and that effect's parameters:
    # the first round's temp_offset, the second's drift, as in the EFFECT records after it
    eff = boardlog.decode(tmp_path / "cpython.bin").dicts(log.EFFECT)
    for f, kind in zip(found, both):
        after = [e for e in eff if e["index"] == f["index"] and e["effect"] == kind]
        assert f["effect"] == kind and len(after) == 1, (f, eff)
        assert [f[f"p{i}"] for i in range(3)] == [after[0][f"p{i}"] for i in range(3)], (f, after)
    p = np.array([found[1][f"p{i}"] for i in range(3)])      # drift (effects.py): the hidden signs
    assert np.all(np.sign(p) == np.sign(D_TRUE)), p
    from accelcal.model.effects import CATALOGUE   # and `pull`/`report` tell them so
    told = boardlog._discovery(found[1], CATALOGUE)
    assert told["adopted"] == "temp_offset+drift" and told["params_effect"] == "drift", told
    from acal.logger.processor import Processor
    store = log.CalStore(str(tmp_path / "cpython.bin") + ".a", str(tmp_path / "cpython.bin") + ".b")
    again = Processor(log.Log(str(tmp_path / "again.bin")), 10, discover=True, store=store)
    assert again.kinds == both and again.pipe.plug is None


def test_processor_adopts_nothing_without_an_effect(tmp_path):
    script = _stream(tmp_path, "clean", np.zeros(3))
    _run_cpython(script, tmp_path / "clean.bin")
    found = boardlog.decode(tmp_path / "clean.bin").dicts(log.DISCOVERY)
    assert found and all(f["adopted"] == 0 for f in found), found
    assert not boardlog.decode(tmp_path / "clean.bin").of(log.EFFECT)
    # powered up again: base, discovering (its store holds a base calibration)
    from acal.logger.processor import Processor
    store = log.CalStore(str(tmp_path / "clean.bin") + ".a", str(tmp_path / "clean.bin") + ".b")
    again = Processor(log.Log(str(tmp_path / "again.bin")), 10, discover=True, store=store)
    assert again.kinds == () and again.pipe.plug is not None and again.calibrations >= 1


def test_a_stored_model_the_discovery_does_not_adopt_is_not_resumed(tmp_path):
    """A store left by a board flashed with base+temp_offset+drift+supply_offset (past the
    discovery's limit of two effects) or base+drift+drift: a board flashed with base and
    --discover starts afresh, discovering; base+temp_offset+drift (a second round's model) and
    drift alone (a first round's) are taken."""
    from acal.logger.processor import Processor
    store = log.CalStore(str(tmp_path / "a"), str(tmp_path / "b"))
    cal = (100, 3, 0, 5, 72, 0, 0) + (1 << 24, 1 << 24, 1 << 24, 0, 0, 0, 0, 0, 0)
    for kinds in ((effects.TEMP_OFFSET, effects.DRIFT, effects.SUPPLY_OFFSET),
                  (effects.DRIFT, effects.DRIFT)):
        store.save(cal, [(100, k, 28, 0, 0, 0, 0) for k in kinds])
        p = Processor(log.Log(str(tmp_path / "l.bin")), 10, discover=True, store=store)
        assert p.kinds == () and p.pipe.plug is not None and p.calibrations == 3
    cal = cal[:1] + (4,) + cal[2:]
    store.save(cal, [(100, effects.TEMP_OFFSET, 28, 0, 0, 0, 0), (100, effects.DRIFT, 28, 0, 0, 0, 0)])
    p = Processor(log.Log(str(tmp_path / "t.bin")), 10, discover=True, store=store)
    assert p.kinds == (effects.TEMP_OFFSET, effects.DRIFT) and p.pipe.plug is None
    cal = cal[:1] + (5,) + cal[2:]
    store.save(cal, [(100, effects.DRIFT, 28, 0, 0, 0, 0)])   # drift alone: a candidate
    p = Processor(log.Log(str(tmp_path / "m.bin")), 10, discover=True, store=store)
    assert p.kinds == (effects.DRIFT,) and p.pipe.plug is None and p.calibrations == 5
    assert p.params[:9] == list(cal[7:]) and p.calibration.kinds == (effects.DRIFT,)


# The points fed to a discovering pipeline, calibrated, its discovery begun: x y z (Q16 g) temp
# time per rest mean (a string: a list literal this long exhausts the 32-bit port's pystack)
FEED = r'''
from acal.core.fixed import C_TEMP, C_TIME
PTS = [int(v) for v in "%s".split()]
pipe = Pipeline(10, plug=Plug(), **profile.settings(profile.WEAR))
for i in range(len(PTS) // 5):
    pipe.now[C_TEMP] = PTS[5 * i + 3]
    pipe.now[C_TIME] = PTS[5 * i + 4]
    pipe.offer(PTS[5 * i], PTS[5 * i + 1], PTS[5 * i + 2])
status = pipe.calibrate()
d = pipe.plug.discovery
d.begin(pipe)
'''


HEAP = r'''
import micropython
from acal.core.pipeline import Pipeline
from acal.discover.plug import Plug
from acal.core import profile
from acal.discover import rule, search
from acal.core.bins import int32s

''' + FEED + r'''# the rule at its largest errors: every candidate saturated, one just below
errs = int32s(search.N_CANDIDATES)
betters = int32s(search.N_CANDIDATES)
out = int32s(4)


def work(d, errs, betters, out):
    while not d.step():
        pass
    for i in range(search.N_CANDIDATES):
        errs[i] = search.ERR_MAX - i
        betters[i] = 72
    out[0] = rule.best(d.kind_ids, errs, search.N_SINGLE)
    out[1] = 1 if rule.adopted(search.ERR_MAX, errs, betters, 72, out[0]) else 0
    errs[0] = 0
    out[2] = 1 if rule.adopted(search.ERR_MAX, errs, betters, 72, 0) else 0


micropython.heap_lock()
try:
    work(d, errs, betters, out)
    micropython.heap_unlock()
    print("OK", status, d.before, d.blocks, d.chosen, int(d.adopted), d.kind,
          " ".join(str(e) for e in d.errs), " ".join(str(b) for b in d.betters),
          " ".join(str(v) for v in out[:3]))
except MemoryError:
    micropython.heap_unlock()
    print("ALLOCATED")
'''


def _heap_script(tmp_path, name, drift=np.zeros(3), then=""):
    # drift: a second hidden effect's offsets (g a day); then: script text run after
    rng = np.random.default_rng(9)
    d = simulate.unit_points(rng, 420)
    pts = []
    for i in range(420):
        time = 7 * i                       # 64 s units: 2.2 days
        temp = int(round(4 * (28 + 6 * np.sin(2 * np.pi * time * 64 / 86400))))  # Q2 degC
        v = simulate.uncorrect(TRUTH, d[i][None, :])[0] + C_TRUE * (temp / 4 - 28)
        v += rng.normal(scale=0.001, size=3) + drift * (time * 64 / 86400)
        pts += [int(round(x * 65536)) for x in v] + [temp, time]
    f = tmp_path / name
    f.write_text(HEAP % " ".join(map(str, pts)) + then)
    return f


def _cpython_heap_result(f):
    import contextlib
    import io
    text = f.read_text().replace("import micropython\n", "").replace(
        "micropython.heap_lock()", "").replace("micropython.heap_unlock()", "")
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        exec(compile(text, str(f), "exec"), {"__name__": "heap"})
    return buf.getvalue().split()


def test_candidate_fits_and_scores_allocate_nothing(tmp_path):
    """Every candidate's fit (the step's search too) and every score, then the rule at the
    saturated errors, under heap_lock on the unix port: the same integers as CPython."""
    out = runtime.run_micropython_script(str(_heap_script(tmp_path, "heap.py"))).split()
    assert out[0] == "OK", out
    want = _cpython_heap_result(tmp_path / "heap.py")
    assert out == want
    assert int(out[6]) == effects.TEMP_OFFSET, out      # adopted: the hidden effect
    # at the saturated errors: the lowest is the step's, which gives way to the plain effect
    # next to it (index 5), not adopted (no gain); a zero error against ERR_MAX is adopted
    assert out[-3:] == ["5", "0", "1"]


def test_candidate_fits_and_scores_allocate_nothing_on_the_32_bit_port(tmp_path, mp32):
    """The same on the 32-bit port, where an int past 2**30 would allocate."""
    out = mp32(str(_heap_script(tmp_path, "heap32.py"))).split()
    assert out[0] == "OK", out
    assert out == _cpython_heap_result(tmp_path / "heap32.py")


# A second round (issue 29: "it may repeat, up to the model's limit"): after the first
# adoption, the discovery runs again from the adopted model on the same points, every other
# single effect added to it (the change-point search too), heap-locked after its begin (which
# makes the round's effect tuples, once).
ROUND2 = r'''
if d.adopted and search.more(d.kinds[d.chosen]):
    pipe.plug.adopt(pipe)
    d.begin(pipe)
    micropython.heap_lock()
    try:
        while not d.step():
            pass
        micropython.heap_unlock()
        print("ROUND2", d.round, d.before, d.blocks, d.chosen, int(d.adopted), d.kind,
              " ".join(str(e) for e in d.errs), " ".join(str(b) for b in d.betters),
              " ".join(str(v) for v in d.params))
    except MemoryError:
        micropython.heap_unlock()
        print("ALLOCATED")
'''
D_TRUE = np.array([0.002, -0.0025, 0.0015])   # a hidden drift beside C_TRUE (g a day)


@pytest.mark.parametrize("drift", ["two", "one"])
def test_a_second_round_adds_the_second_effect_and_allocates_nothing(tmp_path, mp32, drift):
    """With temp_offset and drift hidden, the first round adopts one and the second (from it)
    the other, the model then base + both (the model's limit); with temp_offset alone the second
    round adopts nothing.  Every second-round candidate fit and score under heap_lock on the
    unix and 32-bit ports, the same integers as CPython."""
    f = _heap_script(tmp_path, "round2.py", D_TRUE if drift == "two" else np.zeros(3), ROUND2)
    want = _cpython_heap_result(f)
    for out in (runtime.run_micropython_script(str(f)).split(), mp32(str(f)).split()):
        assert out == want
    assert want[0] == "OK" and "ROUND2" in want, want
    r = want.index("ROUND2")
    first = int(want[6])
    rnd, before, blocks, chosen, adopted, kind = map(int, want[r + 1:r + 7])
    errs = list(map(int, want[r + 7:r + 7 + search.N_CANDIDATES]))
    assert rnd == 2 and before > 0 and blocks >= search.MIN_BLOCKS, want
    # tried: every single effect but the adopted one (no curve pair: the limit)
    tried = [i for i in range(search.N_CANDIDATES) if errs[i] >= 0]
    assert search.PAIR not in tried and first not in [search.KINDS[i][0] for i in tried]
    assert len(tried) >= 5, errs
    if drift == "two":
        assert {first} | set(model_kinds(kind)) == {effects.TEMP_OFFSET, effects.DRIFT}
        assert adopted == 1 and model_kinds(kind)[0] == first, want
        assert 0 <= errs[chosen] < 0.9 * before
    else:
        assert first == effects.TEMP_OFFSET and adopted == 0 and kind == 0, want


# A hidden shock (effects.STEP: the offsets jump once) inside a held-out 2-hour block: the fit's
# step time is the first fit point after it, and the discovery places it among the held-out
# points in between before the choice (acal/discover/stepplace.py), and is chosen on its placed error.
# The offsets' jump (g): at 6, -8, 5 mg with the shock at 1700 or 1740 the change-point search
# split at 1470 on these points, and drift, within 1.5x of that step, was adopted.
J_TRUE = np.array([0.010, -0.012, 0.008])
SHOCK = 1760                # 64 s units: inside held-out block 15 (1687.5 .. 1800)

STEP_HEAP = r'''
import micropython
from acal.core.pipeline import Pipeline
from acal.discover.plug import Plug
from acal.core import profile
from acal.core.bins import COND

''' + FEED + r'''SHOCK = %d


def work(d):
    while not d.step():
        pass


micropython.heap_lock()
try:
    work(d)
    micropython.heap_unlock()
    # the held-out points either side of the shock (the ones that bracket it)
    h = d.held
    lo = -1
    hi = 1 << 29
    for j in range(h.count):
        t = h.cond[COND * j + 1]
        if lo < t < SHOCK:
            lo = t
        if SHOCK <= t < hi:
            hi = t
    r = pipe.ref[1]   # C_TIME
    print("OK", status, d.kind, int(d.adopted), d.before, d.step_unplaced, d.fitted_time + r,
          d.step_time + r, d.gap_n, d.placed_insample, d.placed_loo, lo, hi,
          " ".join(str(v) for v in d.params), d.errs[6])
except MemoryError:
    micropython.heap_unlock()
    print("ALLOCATED")
'''


def _step_script(tmp_path, name):
    rng = np.random.default_rng(19)
    d = simulate.unit_points(rng, 420)
    pts = []
    for i in range(420):
        time = 7 * i                       # 64 s units: 2.2 days
        temp = int(round(4 * (28 + 6 * np.sin(2 * np.pi * time * 64 / 86400))))   # Q2 degC
        v = simulate.uncorrect(TRUTH, d[i][None, :])[0] + (J_TRUE if time >= SHOCK else 0)
        v += rng.normal(scale=0.001, size=3)
        pts += [int(round(x * 65536)) for x in v] + [temp, time]
    f = tmp_path / name
    f.write_text(STEP_HEAP % (" ".join(map(str, pts)), SHOCK))
    return f


def _check_placed(out):
    assert out[0] == "OK", out
    status, kind, adopted = map(int, out[1:4])
    fitted, placed, gap_n, insample, loo, lo, hi = map(int, out[6:13])
    assert status == 0 and kind == effects.STEP and adopted == 1, out
    # the placed time lies within the held-out points that bracket the true shock, and nearer
    # to it than the fit's time; the jumps are the fit's (the truth's within 1 mg)
    assert lo < SHOCK <= hi and lo < placed <= hi, out
    assert abs(placed - SHOCK) < abs(fitted - SHOCK) and gap_n > 0, out
    j = np.array(list(map(int, out[13 + 9:13 + 12]))) / 2 ** 24
    assert np.abs(j - J_TRUE).max() < 0.001, j
    # scored leave-one-out over the gap's points the placed model still beats the unplaced
    # one; in-sample (every gap point on the time it helped place) claims no more error than
    # leave-one-out (never more in 200 000 random gaps of up to 5 points tried by brute force);
    # the step is chosen on its placed error
    before, unplaced = int(out[4]), int(out[5])
    assert 0 <= insample <= loo < unplaced < before and int(out[-1]) == loo, out


def test_an_adopted_step_is_placed_among_the_held_out_points(tmp_path):
    """A shock inside a held-out block: the discovery adopts the step and places its time
    between the held-out points either side of the shock, allocating nothing under heap_lock
    on the unix port, the same integers as CPython."""
    f = _step_script(tmp_path, "step.py")
    out = runtime.run_micropython_script(str(f)).split()
    assert out == _cpython_heap_result(f)
    _check_placed(out)


def test_an_adopted_step_is_placed_without_allocating_on_the_32_bit_port(tmp_path, mp32):
    f = _step_script(tmp_path, "step32.py")
    out = mp32(str(f)).split()
    assert out == _cpython_heap_result(f)
    _check_placed(out)
