"""device/ is integer-only, proved by reading the code (its AST), and compiles for the boards."""
import ast
from pathlib import Path

import pytest

from conftest import ROOT

DEVICE = ROOT / "device"
FILES = sorted(DEVICE.rglob("*.py"))


def float_constructs(tree):
    found = []
    for node in ast.walk(tree):
        line = getattr(node, "lineno", 0)
        if isinstance(node, ast.Constant) and isinstance(node.value, (float, complex)):
            found.append((line, f"float literal {node.value!r}"))
        elif isinstance(node, (ast.BinOp, ast.AugAssign)) and isinstance(node.op, ast.Div):
            found.append((line, "true division /"))
        elif isinstance(node, ast.BinOp) and isinstance(node.op, ast.Pow):
            e = node.right
            if not (isinstance(e, ast.Constant) and isinstance(e.value, int) and e.value >= 0):
                found.append((line, "** with a non-constant or negative exponent"))
        elif isinstance(node, ast.Call):
            name = getattr(node.func, "id", getattr(node.func, "attr", ""))
            if name in ("float", "sqrt", "isqrt", "complex", "round"):
                found.append((line, f"call to {name}()"))
        elif isinstance(node, (ast.Import, ast.ImportFrom)):
            mods = [a.name for a in node.names] if isinstance(node, ast.Import) else [node.module or ""]
            for m in mods:
                if m.split(".")[0] in ("math", "cmath", "ulab", "numpy", "decimal", "fractions"):
                    found.append((line, f"import of {m}"))
    return found


def test_device_has_modules():
    names = {f.stem for f in FILES}
    assert {"fixed", "rest", "bins", "optimiser", "model", "pipeline"} <= names


@pytest.mark.parametrize("path", FILES, ids=lambda p: p.name)
def test_no_float_constructs(path):
    found = float_constructs(ast.parse(path.read_text(), filename=str(path)))
    assert found == [], f"{path.name}: " + "; ".join(f"line {n}: {w}" for n, w in found)


def test_the_audit_catches_floats():
    # The reader must see what it is meant to see, or the test above proves nothing.
    bad = "import math\nx = 1.5\ny = a / b\nz = float(3)\nw = sqrt(4)\nv = 2 ** -1\nq //= 2\n"
    kinds = {w.split()[0] for _, w in float_constructs(ast.parse(bad))}
    assert kinds == {"import", "float", "true", "call", "**"}
    assert float_constructs(ast.parse("q = a // b\nr = a >> 3\n")) == []


@pytest.mark.parametrize("arch", ["armv6m", "xtensawin"])
def test_mpy_cross_compiles_every_device_module(arch, tmp_path):
    # As the builds compile them (make build, deploy, the emulated RP2040): the hot loops marked
    # @viper (acal/emit.py) as viper code for these targets.
    from accelcal.bridge.rp2040 import emitted_source, mpy_cross
    marked = 0
    for f in FILES:
        out = tmp_path / (f.stem + ".mpy")
        mpy_cross(f, out, arch)
        assert out.stat().st_size > 0
        if emitted_source(f.read_text()) != f.read_text():
            marked += 1
            assert "@micropython.viper" in emitted_source(f.read_text())
    assert marked >= 1
