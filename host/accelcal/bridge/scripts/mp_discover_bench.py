# `accelcal bench` (studies/bench_chip.py, on the emulated RP2040): the longest step of the board
# discovery's block marking and block comparing (acal/discover.py's _BLOCKS and _BETTER phases)
# on a full held-out set: 144 points, 8 postures in each of 18 odd 2-hour blocks, a candidate
# better in a third of them; and (place()) an adopted step's placement among the held-out points
# of its gap at its largest (acal/stepplace.py's gathering and placing).  Prints "key value" lines (us, and the steps
# taken).
import time
from acal import discover
from acal.heldout import HeldOut

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
            h.offer(x, y, z, 30, ((2 * b + 1) * 225 + 1) // 2 + k, 3300)
    d = discover.Discover(72, h)
    s = d.score
    for i in range(h.count):
        s.err[i] = 120      # the base model's errors, kept as base while marking
    d._next = lambda i: setattr(d, "phase", discover._DONE)   # the two phases alone
    d.phase = discover._BLOCKS
    s.firsts = 0
    steps, worst = _phase(d, d._count_blocks)
    print("discover_blocks", d.blocks)
    print("discover_mark_steps", steps)
    print("discover_mark_worst_us", worst)
    for i in range(h.count):
        s.err[i] = 100 + (i * 37) % 50 if (i // 8) % 3 else 60
    d.phase = discover._BETTER
    d.pos = 0
    steps, worst = _phase(d, d._compare_blocks)
    print("discover_better_blocks", d.betters[0])
    print("discover_compare_steps", steps)
    print("discover_compare_worst_us", worst)


def place():
    """An adopted step's placement (acal/stepplace.py, which discover.py's _PLACE phase drives)
    at its largest: every held-out point of a full set in the step's gap, so GAP_MAX are kept
    (each insertion shifting the sorted gap), then each scored leave-one-out."""
    from acal import effects, stepplace
    h = HeldOut()
    for b in range(18):
        for k in range(8):
            x, y, z = POSTURES[k]
            h.offer(x, y, z, 30, ((2 * b + 1) * 225 + 1) // 2 + 7 * k, 3300)
    d = discover.Discover(72, h)
    for k in range(3):
        d.params[k] = 1 << 24      # unit scale (kxx kyy kzz, Q24), no offsets
    d.params[9] = d.params[10] = d.params[11] = 134218   # the step's jumps: 8 mg in Q24 g
    fitted_time = 18 * 225          # after every held-out point
    d.score.begin(d.params, (effects.STEP,), h, 30, 0, 3300, fitted_time)
    pl = d.place
    pl.begin(d.score, h, 0, -1, fitted_time, 100000, discover.BLOCK_SCAN)
    for name in ("gap", "place"):
        ph = pl.phase
        steps = worst = 0
        while pl.phase == ph:
            t = ticks()
            pl.step()
            dt = us(t)
            steps += 1
            if dt > worst:
                worst = dt
        if name == "gap":
            print("discover_gap_points", pl.n)
        print("discover_%s_steps" % name, steps)
        print("discover_%s_worst_us" % name, worst)
    print("discover_placed_time", pl.step_time)
