# `accelcal bench` (studies/bench_chip.py, on the emulated RP2040): the longest step of the board
# discovery's block marking and block comparing (acal/discover/search.py's _BLOCKS and _BETTER phases)
# on a full held-out set: 144 points, 8 postures in each of 18 odd 2-hour blocks, a candidate
# better in a third of them; and (place()) an adopted step's placement among the held-out points
# of its gap at its largest (acal/discover/stepplace.py's gathering and placing), place(True) the same
# with the heap locked around each step; and (rounds()) a whole discovery, its first round and
# its second from the adopted effect, on a pipeline fed simulated rest means: each phase's
# longest step and the heap.  Prints "key value" lines (us, bytes, and the steps taken).
#
# Why the lock matters: MicroPython takes a call's frame (locals and stack) from the heap when
# it is larger than 11 words (py/objfun.c fun_bc_call, VM_MAX_STATE_ON_STACK) and frees it on
# return; under heap_lock the frame goes on the C stack.  The heap's allocator scans for a run of
# free blocks from the lowest free one (py/gc.c gc_alloc), so each such call costs more the more
# small holes lie before a run long enough: a step's time then moves with what the heap held,
# while gc.mem_alloc() is the same after it.
import gc
import time
from acal.discover import search
from acal.discover.heldout import HeldOut

# CircuitPython has no ticks_us: monotonic_ns (as mp_paths_bench.py)
ticks = getattr(time, "ticks_us", None) or (lambda: time.monotonic_ns() // 1000)


def us(t0):
    t = ticks()
    return time.ticks_diff(t, t0) if hasattr(time, "ticks_diff") else t - t0


POSTURES = ((65536, 0, 0), (0, 65536, 0), (0, 0, 65536), (-65536, 0, 0), (0, -65536, 0),
            (0, 0, -65536), (46341, 46341, 0), (0, 46341, 46341))


def _phase(d, run):
    # every step of one phase: (steps, the longest in us)
    ph = d.phase
    steps = worst = 0
    while d.phase == ph:
        t = ticks()
        run()
        dt = us(t)
        steps += 1
        if dt > worst:
            worst = dt
    return steps, worst


def main():
    h = HeldOut()
    for b in range(18):
        for k in range(8):
            x, y, z = POSTURES[k]
            h.offer(x, y, z, (30, ((2 * b + 1) * 225 + 1) // 2 + k, 3300))
    d = search.Discover(72, h)
    s = d.score
    for i in range(h.count):
        s.err[i] = 120      # the base model's errors, kept as base while marking
    # the phases by their places (PHASES, in search.py's order: tests/device/test_slices.py)
    d._next = lambda i: setattr(d, "phase", PHASES.index("done"))   # the two phases alone
    d.phase = PHASES.index("blocks")
    s.firsts = 0
    steps, worst = _phase(d, d._count_blocks)
    print("discover_blocks", d.blocks)
    print("discover_mark_steps", steps)
    print("discover_mark_worst_us", worst)
    for i in range(h.count):
        s.err[i] = 100 + (i * 37) % 50 if (i // 8) % 3 else 60
    d.phase = PHASES.index("better")
    d.pos = 0
    steps, worst = _phase(d, d._compare_blocks)
    print("discover_better_blocks", d.betters[0])
    print("discover_compare_steps", steps)
    print("discover_compare_worst_us", worst)


def place(lock=False):
    """An adopted step's placement (acal/discover/stepplace.py, which search.py's _PLACE phase drives)
    at its largest: every held-out point of a full set in the step's gap, so GAP_MAX are kept
    (each insertion shifting the sorted gap), then each scored leave-one-out.  lock: each step
    under heap_lock (its calls' frames on the C stack; keys with _locked)."""
    import micropython
    from acal.core import effects
    from acal.discover import stepplace
    if lock and not hasattr(micropython, "heap_lock"):
        return
    tag = "_locked" if lock else ""
    h = HeldOut()
    for b in range(18):
        for k in range(8):
            x, y, z = POSTURES[k]
            h.offer(x, y, z, (30, ((2 * b + 1) * 225 + 1) // 2 + 7 * k, 3300))
    d = search.Discover(72, h)
    for k in range(3):
        d.params[k] = 1 << 24      # unit scale (kxx kyy kzz, Q24), no offsets
    d.params[9] = d.params[10] = d.params[11] = 134218   # the step's jumps: 8 mg in Q24 g
    fitted_time = 18 * 225          # after every held-out point
    d.score.begin(d.params, (effects.STEP,), h, (30, 0, 3300), fitted_time)
    pl = d.place
    pl.begin(d.score, h, 0, -1, fitted_time, 100000, search.BLOCK_SCAN)
    for name in ("gap", "place"):
        ph = pl.phase
        steps = worst = 0
        while pl.phase == ph:
            if lock:
                micropython.heap_lock()
            else:
                gc.collect()   # a collection is no step's (CircuitPython's clock makes garbage)
            t = ticks()
            pl.step()
            dt = us(t)
            if lock:
                micropython.heap_unlock()
            steps += 1
            if dt > worst:
                worst = dt
        if name == "gap":
            print("discover_gap%s_points" % tag, pl.n)
        print("discover_%s%s_steps" % (name, tag), steps)
        print("discover_%s%s_worst_us" % (name, tag), worst)
    print("discover_placed%s_time" % tag, pl.step_time)
    print("discover_place%s_heap_free" % tag, gc.mem_free())


PHASES = ("base", "fit", "search", "score", "blocks", "better", "place", "next", "begin",
          "done")   # discover's, in its phases' order (search.py: _BASE ... _DONE)

# rounds() keeps the collector off over a round and counts what each step allocates from the
# free heap before and after it, less what its timing allocates (clock_bytes); between steps it
# collects when the free heap falls below LOW_FREE.  On CircuitPython the timing itself makes
# garbage: time.monotonic_ns() returns a long int (past 2**30 ns 1.07 s after boot), an object
# on the heap, and ticks() divides it into another: 128 B a step, more than the heap holds over
# a round.  MicroPython's ticks_us is a small int (0 B).
LOW_FREE = 4096


def clock_bytes():
    """What a step's timing (ticks(), then us()) allocates, with the collector off (the second
    of two such pairs)."""
    b = 0
    for _ in range(2):
        f = gc.mem_free()
        us(ticks())
        b = f - gc.mem_free()
    return b


def rounds(pts, lock=False):
    """A discovering pipeline fed the rest means pts (x y z (Q16 g) temp (Q2 degC) time (64 s
    units) apiece, flat), calibrated, its discovery run (round 1), the adopted effect taken and
    the discovery run again from it (round 2), each step timed; per round and phase the steps
    and the longest (_round).  lock: each step under heap_lock (keys with _locked; nothing on
    CircuitPython, which has no heap_lock)."""
    import micropython
    from acal.discover import search
    from acal.core import profile
    from acal.core.pipeline import Pipeline
    from acal.core.fixed import C_TEMP, C_TIME
    from acal.discover.plug import Plug
    if lock and not hasattr(micropython, "heap_lock"):
        return
    tag = "_locked" if lock else ""
    pipe = Pipeline(10, plug=Plug(), **profile.settings(profile.WEAR))
    for i in range(len(pts) // 5):
        pipe.now[C_TEMP] = pts[5 * i + 3]
        pipe.now[C_TIME] = pts[5 * i + 4]
        pipe.offer(pts[5 * i], pts[5 * i + 1], pts[5 * i + 2])
    print("discover_calibrate_status", pipe.calibrate())
    d = pipe.plug.discovery
    for rnd in (1, 2):
        r = "discover_round%d%s_" % (rnd, tag)
        _round(d, pipe, lock, r)
        if not (d.adopted and search.more(d.kinds[d.chosen])):
            print("discover_no_second_round%s" % tag, 1)
            return
        adopt(pipe, r)


def _round(d, pipe, lock, r):
    """One round, its lines prefixed r: the free heap before begin(), after begin() and after
    the round, the least between steps (less the clock's garbage since the last collection),
    the bytes the round allocated (begin()'s effect tuples, and what its steps allocated, the
    clock's counted out), the clock's bytes a step and the collections made; per phase the
    steps and the longest.  A step that ends its phase also begins what follows (the next
    candidate's testability, its fit's begin, its search, its score): those are timed apart
    (_end_worst_us, the longest of them; _worst_us the longest of the others)."""
    import micropython
    steps = [0] * len(PHASES)
    worst = [0] * len(PHASES)
    end_worst = [0] * len(PHASES)
    gc.collect()
    gc.disable()
    clock = clock_bytes()
    gc.collect()
    free_before = gc.mem_free()
    d.begin(pipe)
    free = free_begun = least = gc.mem_free()
    allocated = free_before - free_begun
    collections = garbage = 0      # garbage: the clock's since the last collection
    done = False
    while not done:
        if free < LOW_FREE:
            gc.collect()
            collections += 1
            free = gc.mem_free()
            garbage = 0
        ph = d.phase
        if lock:
            micropython.heap_lock()
        t = ticks()
        done = d.step()
        dt = us(t)
        if lock:
            micropython.heap_unlock()
        steps[ph] += 1
        if d.phase != ph:
            if dt > end_worst[ph]:
                end_worst[ph] = dt
        elif dt > worst[ph]:
            worst[ph] = dt
        now = gc.mem_free()
        allocated += free - now - clock
        garbage += clock
        free = now
        if free + garbage < least:
            least = free + garbage
    gc.enable()
    print(r + "round", d.round)
    print(r + "adopted_kind", d.kind)
    print(r + "heap_free_before", free_before)
    print(r + "heap_free_begun", free_begun)
    print(r + "heap_free_least", least)
    print(r + "heap_free_after", free + garbage)
    print(r + "allocated_bytes", allocated)
    print(r + "clock_bytes", clock)
    print(r + "collections", collections)
    for k in range(len(PHASES)):
        if steps[k]:
            print(r + PHASES[k] + "_steps", steps[k])
            print(r + PHASES[k] + "_worst_us", worst[k])
            print(r + PHASES[k] + "_end_worst_us", end_worst[k])


def adopt(pipe, r):
    """pipe.plug.adopt(pipe) and what it costs the heap: the free heap before it (collected), right after
    it (what it took, unless it had to collect) and after a collection (what it keeps: its
    calibration's start; the bins grow to a composed model's points in the room they have from
    boot, acal/discover/plug.py), the points per subset after it."""
    gc.collect()
    free_before = gc.mem_free()
    pipe.plug.adopt(pipe)
    free_taken = gc.mem_free()
    gc.collect()
    print(r + "adopt_heap_free_before", free_before)
    print(r + "adopt_heap_free_taken", free_taken)
    print(r + "adopt_heap_free_after", gc.mem_free())
    print(r + "adopt_max_count", pipe.bins.max_count)
