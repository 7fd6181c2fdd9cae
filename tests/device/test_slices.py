"""The slice mechanism written once (device/acal/core/status.py; issue 48 part 2): every sliced
computation of the device package is a Sliced, its phases numbered by their slices' places
(its module's _DONE their count), and step() runs exactly the current slice."""
import importlib

from acal.core.status import Sliced


class _Two(Sliced):
    # two phases: the first counts to three a step at a time, the second once
    def __init__(self):
        self.log = []
        self.sliced()

    def begin(self):
        self.n = 0
        self.phase = 0

    def _count(self):
        self.n += 1
        self.log.append("c")
        if self.n == 3:
            self.phase = 1

    def _last(self):
        self.log.append("l")
        self.phase = 2

    SLICES = (_count, _last)


def test_a_step_runs_the_current_slice_and_says_when_it_has_ended():
    t = _Two()
    assert t.step() and t.log == []      # made ended: a step runs nothing
    t.begin()
    ends = [t.step() for _ in range(4)]
    assert ends == [False, False, False, True] and t.log == ["c", "c", "c", "l"]
    assert t.step() and t.log == ["c", "c", "c", "l"]   # ended: nothing more runs
    t.begin()
    t.finish()
    assert t.log == ["c"] * 3 + ["l"] + ["c"] * 3 + ["l"]


# every sliced computation of the device package, by module and class, and how to make one
SLICED = [("acal.core.gaussnewton", "GaussNewton", lambda c: c(18)),
          ("acal.core.changepoint", "ChangePoint", lambda c: c()),
          ("acal.paper.optimiser", "Optimiser", lambda c: c(18)),
          ("acal.discover.stepplace", "StepPlace", lambda c: c()),
          ("acal.core.pipeline", "Pipeline", lambda c: c(10))]


def test_every_sliced_computation_is_a_sliced_with_its_phases_numbered_by_the_table():
    for mod, name, make in SLICED:
        m = importlib.import_module(mod)
        obj = make(getattr(m, name))
        assert isinstance(obj, Sliced), name
        assert obj.ended == m._DONE == len(obj.slices) and obj.phase == obj.ended, name
        # the class's one tuple of its own functions: an instance allocates no bound method
        assert obj.slices is type(obj).SLICES, name
        assert all(vars(type(obj))[f.__name__] is f for f in obj.slices), name
        assert "step" not in vars(type(obj)), f"{name} writes its own step()"
    from acal.discover.heldout import HeldOut
    from acal.discover import search
    d = search.Discover(72, HeldOut())
    assert isinstance(d, Sliced) and d.ended == search._DONE == len(d.slices)
    assert d.slices is search.Discover.SLICES
    assert "step" not in vars(search.Discover)


def test_no_module_hand_rolls_a_phase_machine():
    """A module that moves a phase (self.phase = ...) does it on Sliced, and no module but
    status.py (its Sliced) dispatches on one (an `if ph == _X` chain)."""
    import pathlib
    import re
    root = pathlib.Path(__file__).parents[2] / "device" / "acal"
    for p in root.rglob("*.py"):
        text = p.read_text()
        if p.name == "status.py":
            continue
        if "self.phase = " in text:
            assert "(Sliced):" in text, p
        assert not re.search(r"\bph == _[A-Z]", text), p


def test_the_discovery_bench_names_each_phase_by_its_place():
    """mp_discover_bench.py times Discover's steps per phase, by phase number: its names in
    search.py's order (_BASE ... _DONE)."""
    import ast
    from accelcal.locations import SCRIPTS_DIR
    from acal.discover import search
    tree = ast.parse((SCRIPTS_DIR / "mp_discover_bench.py").read_text())
    names = [ast.literal_eval(n.value) for n in tree.body if isinstance(n, ast.Assign)
             and getattr(n.targets[0], "id", "") == "PHASES"][0]
    assert [getattr(search, "_" + name.upper()) for name in names] == list(range(len(names)))
    assert len(names) == search._DONE + 1
