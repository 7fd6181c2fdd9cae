"""`accelcal bench --runtime rp2040`'s discovery figures (bridge/scripts/mp_discover_bench.py,
studies/bench_chip.py), here on the unix port, where its script runs unchanged: rounds() on the
second-round stream adopts temp_offset and then the drift beside it, as the device code does on
CPython; its steps allocate nothing (the least free heap between steps is the heap after
begin()), the second round's begin() only its effect tuples; under heap_lock the same rounds,
steps and placements; and bench_chip turns the lines into its keys."""
from accelcal.bridge import runtime
from accelcal.locations import script
from accelcal.studies import bench_chip
from acal.discover import search
from acal.core import effects, profile
from acal.core.pipeline import Pipeline
from acal.core.fixed import C_TEMP, C_TIME
from acal.discover.plug import Plug


def _run(tmp_path, call):
    f = tmp_path / "discover_bench.py"
    f.write_text(bench_chip.discovery_points() + open(script("mp_discover_bench.py")).read()
                 + "\n" + call + "\n")
    return runtime.run_micropython_script(str(f))


def _cpython_kinds():
    # the same feed and rounds on CPython: the kinds adopted per round
    ns = {}
    exec(bench_chip.discovery_points(), ns)
    pts = ns["PTS"]
    pipe = Pipeline(10, plug=Plug(), **profile.settings(profile.WEAR))
    for i in range(len(pts) // 5):
        pipe.now[C_TEMP] = pts[5 * i + 3]
        pipe.now[C_TIME] = pts[5 * i + 4]
        pipe.offer(pts[5 * i], pts[5 * i + 1], pts[5 * i + 2])
    pipe.calibrate()
    d = pipe.plug.discovery
    kinds = []
    for _ in range(2):
        d.run(pipe)
        kinds.append(d.kind)
        if not (d.adopted and search.more(d.kinds[d.chosen])):
            break
        pipe.plug.adopt(pipe)
    return kinds


def test_the_discovery_bench_runs_both_rounds_allocating_only_at_begin(tmp_path):
    out = _run(tmp_path, "rounds(PTS)\nrounds(PTS, True)\nplace()\nplace(True)")
    kv = bench_chip._kv(out)
    first = effects.model_code((effects.TEMP_OFFSET,))
    second = effects.model_code((effects.TEMP_OFFSET, effects.DRIFT))
    assert _cpython_kinds() == [first, second]
    for tag in ("", "_locked"):
        r1, r2 = f"discover_round1{tag}_", f"discover_round2{tag}_"
        assert (kv[r1 + "adopted_kind"], kv[r2 + "adopted_kind"]) == (first, second)
        assert kv[r1 + "round"] == 1 and kv[r2 + "round"] == 2
        for r in (r1, r2):
            assert kv[r + "heap_free_least"] == kv[r + "heap_free_after"] == kv[r + "heap_free_begun"]
        assert kv[r1 + "allocated_bytes"] == 0
        # the unix port's ticks_us is a small int: the timing allocates nothing, and nothing
        # fills the heap to the point of a collection
        for r in (r1, r2):
            assert kv[r + "clock_bytes"] == 0 and kv[r + "collections"] == 0
        assert 0 < kv[r2 + "allocated_bytes"] == kv[r2 + "heap_free_before"] - kv[r2 + "heap_free_begun"]
        # the step's search and placement ran in both rounds (the step is a candidate in each)
        for r in (r1, r2):
            assert kv[r + "search_steps"] > 0 and kv[r + "place_steps"] > 0
    for k in kv:   # locked or not, the same steps
        if k.startswith("discover_round") and k.endswith("_steps") and "_locked" not in k:
            rnd = k[:len("discover_round1")]
            assert kv[k] == kv[rnd + "_locked" + k[len(rnd):]], k
    assert kv["discover_placed_time"] == kv["discover_placed_locked_time"]
    assert kv["discover_gap_steps"] == kv["discover_gap_locked_steps"] == 144
    keys = bench_chip.round_keys(out, "e_")
    assert keys["e_discover_round2_fit_worst_step_ms"] == kv["discover_round2_fit_worst_us"] / 1000
    assert keys["e_discover_round2_fit_end_step_ms"] == kv["discover_round2_fit_end_worst_us"] / 1000
    assert keys["e_discover_round1_heap_free_least_bytes"] == kv["discover_round1_heap_free_least"]
    assert keys["e_discover_round2_allocated_bytes"] == kv["discover_round2_allocated_bytes"]


def _steps(kv, r):
    return sum(v for k, v in kv.items() if k.startswith(r) and k.endswith("_steps"))


def test_the_rounds_count_what_steps_allocate_across_collections(tmp_path):
    """Collecting before every step (LOW_FREE above any heap), as rounds() does on CircuitPython
    when its clock's garbage fills the heap: the same bytes counted; and with each step made to
    allocate a 100-byte array (dropped at the next, so collected), at least those bytes."""
    every = "LOW_FREE = 1 << 40\n"
    control = ("from acal.discover import search\nKEPT = [None]\n_step = search.Discover.step\n"
               "def _allocating(self):\n    KEPT[0] = bytearray(100)\n    return _step(self)\n"
               "search.Discover.step = _allocating\n")
    plain = bench_chip._kv(_run(tmp_path, "rounds(PTS)"))
    collected = bench_chip._kv(_run(tmp_path, every + "rounds(PTS)"))
    allocating = bench_chip._kv(_run(tmp_path, every + control + "rounds(PTS)"))
    for rnd in (1, 2):
        r = f"discover_round{rnd}_"
        steps = _steps(plain, r)
        assert collected[r + "collections"] == allocating[r + "collections"] == steps
        assert collected[r + "allocated_bytes"] == plain[r + "allocated_bytes"]
        assert collected[r + "adopted_kind"] == allocating[r + "adopted_kind"] == plain[r + "adopted_kind"]
        assert _steps(allocating, r) == steps
        assert allocating[r + "allocated_bytes"] >= plain[r + "allocated_bytes"] + 100 * steps


def test_the_block_phases_alone_run_on_micropython(tmp_path):
    """main(): the block marking and comparing alone on a full held-out set, its phases set by
    their places in PHASES: 18 odd blocks held out, and the candidate better in the third of
    them it was made better in."""
    out = runtime_kv(_run(tmp_path, "main()"))
    assert out["discover_blocks"] == 18 and out["discover_better_blocks"] == 6, out
    assert out["discover_mark_steps"] > 0 and out["discover_compare_steps"] > 0


def runtime_kv(out):
    return {k: int(v) for k, v in (line.split()[:2] for line in out.splitlines() if line.strip())}
