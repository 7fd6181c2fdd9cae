# The slice mechanism, written once (docs/method-and-formats.md "Sliced fit"): a computation
# that does a bounded piece of work a step, so the app runs one step between FIFO drains and
# the host runs every step at once, the same integers either way.
#
# A sliced class derives from Sliced and hands its slices (bound methods, in order) to
# sliced() once, at construction: a bound method made there is never made again, so a step
# allocates nothing.  Its phases are numbered by their place in that tuple, and the number
# after the last (the tuple's length: `ended`) means ended.  self.phase is the slice the next
# step() runs; a slice moves it on (or to `ended`) itself.  The first step() after begin runs
# the first slice: a slice's worst time is its own code's, the dispatch one tuple look-up.
#
# Why a table, not generators (docs/boards-and-logs.md "One slice machine"): a generator resumed with next() allocates nothing per step under heap_lock on
# the 32-bit WebAssembly port and the emulated Pico, nor in CircuitPython (gc.mem_free), but
# its frame is allocated when the generator is made, at every begin (64 B on the 32-bit
# ports, 128 B on the unix port), and the fits run whole, begin included, under heap_lock
# (tests/device/test_heap.py) and hours apart on a fragmenting heap.


class Sliced:
    """Base of every sliced computation: sliced(slices) once; step() runs self.phase's slice
    and says whether the computation has ended (phase == ended); finish() runs the rest."""

    def sliced(self, slices):
        """slices: the phases' bound methods, in phase order; the computation starts ended."""
        self.slices = slices
        self.ended = len(slices)
        self.phase = self.ended

    def step(self):
        """One slice; True when the computation has ended."""
        ph = self.phase
        if ph < self.ended:
            self.slices[ph]()
        return self.phase == self.ended

    def finish(self):
        """Every remaining slice at once."""
        while not self.step():
            pass
