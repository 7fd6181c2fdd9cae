"""Where a command writes: every output path checked before any work, and written whole or not
at all.

check_output() refuses (InputError: exit 2, one line) an output that is one of the command's
inputs (resolved, links followed), a folder, in a folder that does not exist, or that exists
without --force; atomic() writes to a temporary file in the output's folder and renames it into
place only when the writer finished, so a killed or failed run leaves the old file or none, never
a partial one that looks whole.
"""
from __future__ import annotations

import contextlib
import os
from pathlib import Path

from accelcal.errors import InputError

FORCE_HELP = "replace outputs that exist (without it an existing output is an error)"


def _same(a: Path, b: Path) -> bool:
    try:
        if a.exists() and b.exists():
            return os.path.samefile(a, b)
    except OSError:
        pass
    return a.resolve() == b.resolve()


def check_output(path, inputs=(), force: bool = False, option: str = "output") -> Path:
    """The output path, checked: not an input, not a folder, its folder there, and new unless
    force.  inputs: the paths the command reads."""
    p = Path(path)
    if str(path) == "" or p.name in ("", ".", ".."):
        raise InputError(f"{option} {path!r}: expected a file name")
    for inp in inputs:
        if inp is not None and _same(p, Path(inp)):
            raise InputError(f"{path}: is the input {inp}; refusing to overwrite an input "
                             f"(choose another {option})")
    if p.is_dir():
        raise InputError(f"{path}: is a folder; {option} expects a file")
    parent = p.parent if str(p.parent) else Path(".")
    if not parent.is_dir():
        raise InputError(f"{path}: folder {parent} does not exist")
    if p.exists() and not force:
        raise InputError(f"{path}: exists; add --force to replace it")
    if not os.access(parent, os.W_OK):
        raise InputError(f"{path}: folder {parent} is not writable")
    return p


def check_output_dir(path, inputs=(), option: str = "output folder") -> Path:
    """An output folder: not an input, not a file; made (with its parents) if missing."""
    p = Path(path)
    for inp in inputs:
        if inp is not None and _same(p, Path(inp)):
            raise InputError(f"{path}: is the input {inp}; choose another {option}")
    if p.exists() and not p.is_dir():
        raise InputError(f"{path}: is a file; {option} expects a folder")
    try:
        p.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise InputError(f"{path}: cannot make the folder ({e.strerror})") from None
    if not os.access(p, os.W_OK):
        raise InputError(f"{path}: folder is not writable")
    return p


def _tmp_for(p: Path) -> Path:
    return p.with_name(f".{p.name}.{os.getpid()}.partial")


@contextlib.contextmanager
def atomic(path, mode: str = "w", **kw):
    """open() for writing into a temporary file beside path, renamed onto path when the block
    ends without an exception (and removed when it does not)."""
    p = Path(path)
    tmp = _tmp_for(p)
    try:
        fh = open(tmp, mode, **kw)
    except OSError as e:
        raise InputError(f"{path}: cannot write ({e.strerror})") from None
    try:
        with fh:
            yield fh
        os.replace(tmp, p)
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise


def write_text(path, text: str) -> None:
    with atomic(path) as fh:
        fh.write(text)


def save_figure(fig, path, **kw) -> None:
    """fig.savefig(path), atomically."""
    p = Path(path)
    with atomic(p, "wb") as fh:
        fig.savefig(fh, format=p.suffix.lstrip(".") or "png", **kw)
