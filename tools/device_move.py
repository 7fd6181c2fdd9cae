#!/usr/bin/env python3
"""Rewrite the device package's old flat module names (acal.bins, acal/bins.py...) to the feature
packages they moved to (issue 48: acal.core, acal.paper, acal.discover, acal.logger).

    python3 tools/device_move.py            rewrite every text file of the tree (git ls-files)
    python3 tools/device_move.py FILE...    rewrite only these files
    python3 tools/device_move.py --check    list the files still using an old name (exit 1 if any)

Idempotent: a rewritten file is left as it is by a second run.  What it rewrites, in code, in
strings sent to MicroPython and in docs alike:
    from acal import bins, log          -> from acal.core import bins / from acal.logger import log
    from acal import discover           -> from acal.discover import search as discover
    from acal.bins import COND          -> from acal.core.bins import COND
    import acal.app / acal.app.main()   -> import acal.logger.app / acal.logger.app.main()
    "acal/bins.py", device/acal/log.py  -> "acal/core/bins.py", device/acal/logger/log.py
    heldscore.py (a renamed file, bare) -> score.py
The old module acal.discover became the package acal.discover (its class is acal.discover.search):
`acal.discover.X` is read as old unless X is one of the new package's modules, and
`from acal import discover` / `import acal.discover` as old (new code imports the package's
modules, never the package itself); `acal.discover` named otherwise (a package list) is the package.
"""
import argparse
import re
import subprocess
import sys
from pathlib import Path

# old flat module -> (feature package, new module name)
MOVES = {
    # core: formats, arithmetic, rest detection, bins, the model and its effects, the wear fit,
    # the paper profile's switch (profile), the pipeline that runs them, the apply
    "fixed": ("core", "fixed"), "wide": ("core", "wide"), "emit": ("core", "emit"),
    "status": ("core", "status"), "rest": ("core", "rest"), "bins": ("core", "bins"),
    "hemisphere": ("core", "hemisphere"), "model": ("core", "model"),
    "effects": ("core", "effects"), "reference": ("core", "reference"),
    "calibration": ("core", "calibration"), "solve": ("core", "solve"),
    "normal_sums": ("core", "normal_sums"), "gaussnewton": ("core", "gaussnewton"),
    "changepoint": ("core", "changepoint"), "pipeline": ("core", "pipeline"),
    "profile": ("core", "profile"),
    # paper: the paper profile's optimiser and its objective
    "optimiser": ("paper", "optimiser"), "objective": ("paper", "objective"),
    # discover: the board's own model discovery
    "discover": ("discover", "search"), "discovery": ("discover", "rule"),
    "heldout": ("discover", "heldout"), "heldscore": ("discover", "score"),
    "candidates": ("discover", "rule"), "stepplace": ("discover", "stepplace"),
    "grow": ("discover", "plug"),
    # logger: the sensor drivers, the log on flash, the app and its processor
    "lis3dh": ("logger", "lis3dh"), "lis3dh_cp": ("logger", "lis3dh_cp"),
    "log": ("logger", "log"), "app": ("logger", "app"), "processor": ("logger", "processor"),
}
PACKAGES = sorted({pkg for pkg, _ in MOVES.values()})
NEW_MODULES = {pkg: {new for p, new in MOVES.values() if p == pkg} for pkg in PACKAGES}
# Bare file names (no acal/ before them) of the modules whose name changed.
RENAMED = {f"{old}.py": f"{new}.py" for old, (_, new) in MOVES.items() if old != new}

_OLD = "|".join(sorted(MOVES, key=len, reverse=True))
# `from acal import a, b as c` (the names up to the end of the statement on its line)
FROM_ACAL = re.compile(r"(?P<lead>^[ \t]*)?from acal import (?P<names>[A-Za-z_][\w]*(?:[ \t]+as[ \t]+\w+)?"
                       r"(?:[ \t]*,[ \t]*[A-Za-z_]\w*(?:[ \t]+as[ \t]+\w+)?)*)", re.M)
# `from acal.discover import ...`: the old module's names, or the new package's modules
FROM_PKG = re.compile(r"(?<![\w.])from acal\.(?P<old>" + "|".join(p for p in PACKAGES if p in MOVES)
                      + r") import (?P<names>\w+(?:[ \t]+as[ \t]+\w+)?(?:[ \t]*,[ \t]*\w+(?:[ \t]+as[ \t]+\w+)?)*)")
# acal.<old> (import paths, attribute uses): not part of a longer dotted name before it, nor the
# package part of `from acal.discover import` (FROM_PKG's)
DOTTED = re.compile(r"(?<![\w.])acal\.(?P<old>" + _OLD + r")(?![\w])(?P<rest>\.\w+)?")
# acal/<old>.py, acal/<old>.mpy, acal/<old> as a path (not a folder: no / after it)
PATH = re.compile(r"(?<![\w.])acal/(?P<old>" + _OLD + r")(?P<ext>\.m?py)?(?![\w/])")
BARE = re.compile(r"(?<![\w/.-])(?P<name>" + "|".join(re.escape(k) for k in RENAMED) + r")(?![\w])")


def _from_acal(m: re.Match) -> str:
    parts = [p.strip() for p in m.group("names").split(",")]
    groups: dict[str, list[str]] = {}
    order = []
    for part in parts:
        name, alias = (re.split(r"[ \t]+as[ \t]+", part) + [None])[:2]
        if name not in MOVES:                           # a new package, or not a device module
            target, text = "acal", part
        else:
            pkg, new = MOVES[name]
            target = f"acal.{pkg}"
            text = new if alias is None and new == name else f"{new} as {alias or name}"
        if target not in groups:
            groups[target] = []
            order.append(target)
        groups[target].append(text)
    lines = [f"from {t} import {', '.join(groups[t])}" for t in order]
    lead = m.group("lead")
    if lead is not None:
        return lead + ("\n" + lead).join(lines)
    return "; ".join(lines)


def _dotted(m: re.Match) -> str:
    old, rest = m.group("old"), m.group("rest") or ""
    if old in PACKAGES and (rest[1:] in NEW_MODULES[old] or not rest and not re.search(
            r"\bimport[ \t]+(?:[\w.]+[ \t]*,[ \t]*)*$", m.string[max(0, m.start() - 200):m.start()])):
        return m.group(0)       # new: acal.discover.search, or the package named, not imported
    pkg, new = MOVES[old]
    return f"acal.{pkg}.{new}{rest}"


def _from_pkg(m: re.Match) -> str:
    old = m.group("old")
    names = [re.split(r"[ \t]+as[ \t]+", p.strip())[0] for p in m.group("names").split(",")]
    if all(n in NEW_MODULES[old] for n in names):
        return m.group(0)                               # already new: its modules
    pkg, new = MOVES[old]
    return f"from acal.{pkg}.{new} import {m.group('names')}"


def _path(m: re.Match) -> str:
    if m.group("old") in PACKAGES and not m.group("ext"):
        return m.group(0)                               # the new package's folder
    pkg, new = MOVES[m.group("old")]
    return f"acal/{pkg}/{new}{m.group('ext') or ''}"


def rewrite(text: str) -> str:
    text = FROM_ACAL.sub(_from_acal, text)
    text = FROM_PKG.sub(_from_pkg, text)
    text = DOTTED.sub(_dotted, text)
    text = PATH.sub(_path, text)
    return BARE.sub(lambda m: RENAMED[m.group("name")], text)


def tree_files(root: Path) -> list[Path]:
    out = subprocess.run(["git", "ls-files", "-z"], cwd=root, capture_output=True, check=True)
    files = [root / f for f in out.stdout.decode().split("\0") if f]
    return [f for f in files if f.is_file() and f.suffix in
            {".py", ".md", ".mjs", ".js", ".json", ".toml", ".cfg", ".txt", ".sh", ".yml", ".yaml"}
            or f.name == "Makefile"]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter,
                                 epilog=__doc__.split("\n\n", 1)[1])
    ap.add_argument("files", nargs="*", type=Path, help="files to rewrite (default: the git tree)")
    ap.add_argument("--check", action="store_true",
                    help="only list the files still using an old name; exit 1 if any")
    a = ap.parse_args(argv)
    root = Path(__file__).resolve().parent.parent
    files = a.files or tree_files(root)
    # this tool and its test hold the old names on purpose
    own = {root / "tools" / "device_move.py", root / "tests" / "test_device_move.py"}
    texts = {}
    for f in files:                                     # every file read before any is written
        if f.resolve() in own:
            continue
        try:
            texts[f] = f.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as e:
            print(f"device_move: {f}: {e.strerror if isinstance(e, OSError) else e}",
                  file=sys.stderr)
            return 2
    stale = []
    for f, text in texts.items():
        new = rewrite(text)
        if new != text:
            stale.append(f)
            if not a.check:
                tmp = f.with_name(f.name + ".device_move.tmp")
                tmp.write_text(new, encoding="utf-8")
                tmp.replace(f)                          # whole or not at all
    for f in stale:
        print(f"{'old names' if a.check else 'rewrote'}: {f}")
    return 1 if a.check and stale else 0


if __name__ == "__main__":
    sys.exit(main())
