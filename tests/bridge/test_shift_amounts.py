"""bridge/ranges.py's shift-amount check (issue 49): a viper shift by 32 or more is caught, one
in 0..31 passes, bytecode shifts are Python's on every port and not checked; and the viper
functions' constant shift amounts are all in 0..31 (the traced runs of tests/device/
test_ranges.py check the computed ones)."""
import ast
import sys

import pytest

from accelcal.bridge.ranges import (SHIFT_MAX, Tracer, device_viper_functions, traced,
                                     viper_functions)
from accelcal.locations import DEVICE_PACKAGE

PLANTED = '''
from acal.core.emit import viper


@viper
def planted(a: int, s: int) -> int:
    return (a >> 15) >> (s - 15)       # unbounded: s = 47 shifts by 32 (a on Xtensa and RV32)


def plain(a: int, s: int) -> int:
    return a >> s                      # bytecode: Python's answer everywhere
'''


def test_a_planted_shift_by_32_is_caught(tmp_path, monkeypatch):
    f = tmp_path / "planted_shift.py"
    f.write_text(PLANTED)
    monkeypatch.syspath_prepend(str(tmp_path))
    import planted_shift
    marked = viper_functions(f, "planted_shift")
    assert list(marked.values()) == ["planted_shift.planted"]
    tr = Tracer(marked)
    T = traced(tr)
    for s in (16, 30, 46):
        planted_shift.planted(T(1000 << 15), T(s))
    planted_shift.plain(T(1000), T(40))
    assert tr.wild_shifts() == []                      # amounts 15 and 1..31; plain unchecked
    planted_shift.planted(T(1000 << 15), T(47))
    assert tr.wild_shifts() == ["planted_shift.planted line 7: 1..32"]
    tr2 = Tracer(marked)
    with pytest.raises(ValueError):                    # CPython refuses it; viper would not
        planted_shift.planted(traced(tr2)(7 << 15), 10)
    assert tr2.wild_shifts() == ["planted_shift.planted line 7: -5..15"]
    del sys.modules["planted_shift"]


def _shifts(fn):
    for node in ast.walk(fn):
        if isinstance(node, ast.BinOp) and isinstance(node.op, (ast.LShift, ast.RShift)):
            yield node.right
        elif isinstance(node, ast.AugAssign) and isinstance(node.op, (ast.LShift, ast.RShift)):
            yield node.value


def test_constant_viper_shift_amounts_are_below_32():
    """Every shift by a constant inside a @viper function: 0..31.  (`<< w >> w`, the 64-bit
    ports' sign extension, is dropped from the 32-bit builds: bridge/rp2040.py.)"""
    names = set(device_viper_functions().values())
    assert len(names) >= 25 and "acal.core.wide.mul_shift" in names
    constants = 0
    for path in sorted(DEVICE_PACKAGE.rglob("*.py")):
        for node in ast.parse(path.read_text()).body:
            if not (isinstance(node, ast.FunctionDef) and
                    any(getattr(d, "id", None) == "viper" for d in node.decorator_list)):
                continue
            for amount in _shifts(node):
                if isinstance(amount, ast.Constant):
                    constants += 1
                    assert 0 <= amount.value <= SHIFT_MAX, (path.name, node.name, amount.value)
    assert constants > 50
