# A sliced computation (docs/method-and-formats.md "Sliced fit"): the slice machine every one
# runs on (Sliced) and the status codes its fits end with.  One module, not two: the app loads
# both with its first fit, and on a board's littlefs every module file costs its import time
# whatever its size (docs/notes/boards-and-logs.md "Import time and the file system").
#
# The slice machine, written once: a computation that does a bounded piece of work a step, so
# the app runs one step between FIFO drains and the host runs every step at once, the same
# integers either way.
#
# A sliced class derives from Sliced, lists its slices (its own methods, in order) in a tuple
# in its class body (SLICES) and calls sliced() at construction; step() calls the current one
# with the instance, so a step allocates nothing, and neither does an instance: a tuple of
# bound methods per instance cost 80 to 192 B each, 1.2 kB on a discovering board's
# heap (docs/notes/boards-and-logs.md "The discovering board's heap").  Its phases are
# numbered by their place in that tuple, and the number after the last (the tuple's length:
# `ended`) means ended.  self.phase is the slice the next
# step() runs; a slice moves it on (or to `ended`) itself.  The first step() after begin runs
# the first slice: a slice's worst time is its own code's, the dispatch one tuple look-up.
#
# Why a table, not generators (docs/boards-and-logs.md "One slice machine"): a generator resumed with next() allocates nothing per step under heap_lock on
# the 32-bit WebAssembly port and the emulated Pico, nor in CircuitPython (gc.mem_free), but
# its frame is allocated when the generator is made, at every begin (64 B on the 32-bit
# ports, 128 B on the unix port), and the fits run whole, begin included, under heap_lock
# (tests/device/test_heap.py) and hours apart on a fragmenting heap.


# The fits' status codes, shared by the paper's gradient descent (acal/paper/optimiser.py), the default
# profile's Gauss-Newton (acal/core/gaussnewton.py), the pipeline and the app's log.  Failure is
# reported, never returned as parameters.
OK = 0
DIVERGED = 1        # a parameter left the fit region, or the objective ended above its start
#                     (or a point lay past +-16 g, outside the exact objective's domain)
TOO_FEW = 2         # fewer points than parameters
OUT_OF_BOUNDS = 3   # converged outside the calibration bounds (fixed.py): not a sensor we trust
UNDETERMINED = 4    # the points do not pin every parameter (acal/core/gaussnewton.py)
# A composed model's fit that failed, or ended worse than the base fit of the same points (by
# mean squared residual over the points each kept): the base calibration is kept, with the
# effects at zero (acal/core/pipeline.py, the wear profile).
BASE_KEPT_FAILED = 5
BASE_KEPT_WORSE = 6
# (their names: the host's alone, accelcal/bridge/boardlog.py STATUS_NAMES; a board keeps no
# string of them)


def usable(status):
    """True when the fit's parameters may be applied (OK, or a base calibration kept)."""
    return status == OK or status == BASE_KEPT_FAILED or status == BASE_KEPT_WORSE


class Sliced:
    """Base of every sliced computation: sliced() once; step() runs self.phase's slice
    and says whether the computation has ended (phase == ended); finish() runs the rest."""

    def sliced(self):
        """The computation starts ended: self.slices is its class's SLICES (the phases'
        functions, in phase order, each called with the instance), self.ended their count.
        Instance attributes, not the class's: on the emulated Pico a step that read them from
        the class took 18 us more (3 misses in the instance's table), one reading them from the
        instance 1 us less than a bound method's call."""
        self.slices = self.SLICES
        self.ended = len(self.SLICES)
        self.phase = self.ended

    def step(self):
        """One slice; True when the computation has ended."""
        ph = self.phase
        if ph < self.ended:
            self.slices[ph](self)
        return self.phase == self.ended

    def finish(self):
        """Every remaining slice at once."""
        while not self.step():
            pass
