"""Each install unit's import time and free heap on the emulated Pico, an older revision's device
package and this checkout's in one run (issue 48's 5 % bars, "before and after in the same run").

    python tools/units_at.py [REV] [--cases base,discover,paper]    # REV: de6b2b0 by default
    python tools/units_at.py [REV] --modules    # each module's own heap instead

Each tree's package is installed on its own flash image (REV's from `git archive`, nothing
checked out) and host/accelcal/bridge/scripts/mp_units_bench.py, this checkout's, runs main(case)
on a fresh boot per tree and case, as `accelcal bench --runtime rp2040` does for its units_ rows.
The emulator's clock is the chip's cycles: a tree gives the same figures on every run.  Prints
one line a figure: `units_{case}_{figure} REV_value this_value change_percent`.  With --modules,
each module of the package (lis3dh_cp, CircuitPython's, left out) imported alone on one fresh
boot a tree, after the modules it imports (MODULES): the heap it takes (the qstr area's chunks
counted apart, its own qstrs' text in), one
line a module, `module_{name} REV_bytes this_bytes change_bytes` (- where a tree has none).
"""
import argparse
import ast
import io
import re
import shutil
import subprocess
import sys
import tarfile
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path[:0] = [str(ROOT / "host"), str(ROOT / "device")]

from accelcal.bridge import rp2040  # noqa: E402
from accelcal.locations import DEVICE_PACKAGE, script  # noqa: E402

FIGURES = ("import_app_us", "free_after_import_bytes", "free_with_processor_bytes", "modules")


def old_package(rev: str, into: Path) -> Path:
    """REV's device/acal extracted under into; SystemExit(2) with one line when REV is not a
    commit of this checkout or has no device package."""
    p = subprocess.run(["git", "-C", str(ROOT), "archive", "--format=tar", rev, "device/acal"],
                       capture_output=True)
    if p.returncode != 0:
        sys.exit(f"units_at: {rev!r} is not a revision of {ROOT} with device/acal: "
                 + (p.stderr.decode(errors="replace").strip().splitlines() or ["git failed"])[-1])
    with tarfile.open(fileobj=io.BytesIO(p.stdout)) as tar:
        tar.extractall(into, filter="data")
    return into / "device" / "acal"


def units(image: Path, case: str) -> dict:
    """mp_units_bench.py main(case) on a fresh boot of image: its units_{case}_ figures."""
    code = Path(script("mp_units_bench.py")).read_text() + f"\nmain({case!r})\n"
    out = rp2040.run_script(code, image=image).out
    kv = dict(line.split()[:2] for line in out.splitlines() if line.startswith("units_"))
    return {k: int(kv[f"units_{case}_{k}"]) for k in FIGURES}


def import_order(root: Path) -> list[str]:
    """The package's modules under root (acal/), each after every acal module it imports at its
    top (ast: import statements outside functions), its packages (folders) first; lis3dh_cp
    (CircuitPython's busio) left out."""
    files = {".".join(("acal", *p.relative_to(root).with_suffix("").parts)).removesuffix(".__init__"): p
             for p in sorted(root.rglob("*.py")) if p.name != "lis3dh_cp.py"}
    order: list[str] = []

    def top_imports(tree: ast.Module) -> list[str]:
        out, todo = [], list(tree.body)
        while todo:
            n = todo.pop(0)
            if isinstance(n, ast.Import):
                out += [a.name for a in n.names]
            elif isinstance(n, ast.ImportFrom) and n.module:
                out += [f"{n.module}.{a.name}" if f"{n.module}.{a.name}" in files else n.module
                        for a in n.names]
            elif isinstance(n, (ast.If, ast.Try)):
                todo += n.body + n.orelse + [s for h in getattr(n, "handlers", []) for s in h.body]
        return [m for m in out if m in files]

    seen: set[str] = set()

    def visit(name: str) -> None:
        if name in seen:     # done, or on the way (an import cycle: the package has none)
            return
        seen.add(name)
        parts = name.split(".")
        for i in range(1, len(parts)):
            visit(".".join(parts[:i]))
        for m in top_imports(ast.parse(files[name].read_text())) if name in files else ():
            visit(m)     # a folder without __init__.py (a namespace package) imports nothing
        order.append(name)

    for name in files:
        visit(name)
    return order


# each module imported alone (the modules it imports already loaded), collected before and after,
# with the qstr area after it (micropython.qstr_info(): its pools grow in chunks, each chunk
# allocated by whichever import fills the last); on the chip, its own script (mp_units_bench.py's
# text is in the heap while it runs: a longer one would move every units_ figure)
MODULES = """import gc, micropython
micropython.qstr_info()
for name in ORDER:
    gc.collect()
    free = gc.mem_free()
    __import__(name)
    gc.collect()
    print("module_%s %d" % (name, free - gc.mem_free()))
    micropython.qstr_info()
"""
_QSTR = re.compile(r"n_str_data_bytes=(\d+), n_total_bytes=(\d+)")


def module_heap(image: Path, root: Path) -> dict:
    """MODULES on a fresh boot of image, in import_order(root): each module's own heap, bytes -
    what its import took less the qstr area's growth, plus its new qstrs' text (the area's
    chunks land on whichever import fills the last: its growth is not the module's)."""
    code = f"ORDER = {import_order(root)!r}\n" + MODULES
    out = rp2040.run_script(code, image=image).out
    res, last, name = {}, None, None
    for line in out.splitlines():
        if line.startswith("module_"):
            name, took = line.split()[:2]
            res[name[len("module_"):]] = int(took)
        elif m := _QSTR.search(line):
            text, area = int(m[1]), int(m[2])
            if name is not None:
                res[name[len("module_"):]] += -(area - last[1]) + (text - last[0])
            last, name = (text, area), None
    return res


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("rev", nargs="?", default="de6b2b0")
    ap.add_argument("--cases", default="base,discover,paper",
                    help="mp_units_bench.py's cases, comma-separated (base, paper, discover, all)")
    ap.add_argument("--modules", action="store_true", help="each module's own heap instead")
    a = ap.parse_args(argv)
    cases = a.cases.split(",")
    bad = [c for c in cases if c not in ("base", "paper", "discover", "all")]
    if bad:
        print(f"units_at: no case {bad[0]!r} (base, paper, discover, all)", file=sys.stderr)
        return 2
    with tempfile.TemporaryDirectory() as tmp:
        try:
            old = old_package(a.rev, Path(tmp))
        except SystemExit as e:
            print(e.code, file=sys.stderr)
            return 2
        images = {}
        # the older tree's first: flash_image keeps only its newest image, and this checkout's
        # is then the one left in build/rp2040 for the other runs
        for name, root in (("old", old), ("new", DEVICE_PACKAGE)):
            images[name] = Path(tmp) / f"{name}.bin"
            shutil.copyfile(rp2040.flash_image(rp2040.MICROPYTHON, root), images[name])
        if a.modules:
            before, after = module_heap(images["old"], old), module_heap(images["new"], DEVICE_PACKAGE)
            for m in before | after:
                b, n = before.get(m), after.get(m)
                change = "-" if b is None or n is None else f"{n - b:+d}"
                print(f"module_{m} {'-' if b is None else b} {'-' if n is None else n} {change}",
                      flush=True)
            return 0
        for case in cases:
            before, after = units(images["old"], case), units(images["new"], case)
            for k in FIGURES:
                change = 100 * (after[k] - before[k]) / before[k]
                print(f"units_{case}_{k} {before[k]} {after[k]} {change:+.1f}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
