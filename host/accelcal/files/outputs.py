"""Where a command writes: every output path checked before any work, and written whole or not
at all.

check_output() refuses (InputError: exit 2, one line) an output that is one of the command's
inputs (resolved, links followed), a folder, in a folder that does not exist, or that exists
without --force; atomic() writes to a temporary file in the output's folder and renames it into
place only when the writer finished, so a killed or failed run leaves the old file or none, never
a partial one that looks whole.

Every file a command reads is an input: the readers note it (note_input), and both check_output
and atomic() refuse to write over a noted file, --force or not.  An output checked as new (no
--force) is put in place without replacing (a hard link): a second run that wrote it meanwhile
makes this one fail, one line, instead of both reporting success with one result lost.  A
temporary file a killed run left (.NAME.PID.partial, its PID no longer running) is removed at the
next write of that output.
"""
from __future__ import annotations

import contextlib
import os
import stat
from pathlib import Path

from accelcal.errors import InputError

FORCE_HELP = "replace outputs that exist (without it an existing output is an error)"


_READ: set[str] = set()    # what this command has read (real paths): never an output
_NEW: set[str] = set()     # outputs checked without --force: put in place without replacing


def note_input(path) -> None:
    """A file the command reads: no output of the command may replace it."""
    _READ.add(os.path.realpath(path))


def forget_inputs() -> None:
    """A new command starts (the CLI's main): nothing read yet."""
    _READ.clear()
    _NEW.clear()


def check_regular(path) -> None:
    """A regular file (links followed): a device, FIFO or folder is refused before it is read.
    The file is an input of the command from here on (files/outputs.py note_input)."""
    note_input(path)
    try:
        st = os.stat(path)
    except OSError as e:
        raise InputError(f"{path}: cannot open ({e.strerror})") from None
    if not stat.S_ISREG(st.st_mode):
        what = "a folder" if stat.S_ISDIR(st.st_mode) else "not a regular file (a device or FIFO)"
        raise InputError(f"{path}: {what}; expected a file")


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
    for inp in [*inputs, *sorted(_READ)]:
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
    (_NEW.discard if force else _NEW.add)(os.path.realpath(p))
    remove_stale(p)
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


def pid_running(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:   # another user's process: alive
        return True
    return True


def remove_stale(p: Path) -> None:
    """The temporary files of p that killed runs left: .NAME.PID.partial whose PID is gone."""
    prefix = f".{p.name}."
    try:
        names = os.listdir(p.parent if str(p.parent) else ".")
    except OSError:
        return
    for n in names:
        pid = n[len(prefix):-len(".partial")]
        if n.startswith(prefix) and n.endswith(".partial") and pid.isdigit() and \
                int(pid) != os.getpid() and not pid_running(int(pid)):
            with contextlib.suppress(OSError):
                os.unlink(p.with_name(n))


def _put(tmp: Path, p: Path) -> None:
    """tmp onto p: replacing p, or (an output checked as new) only if nothing made p since."""
    real = os.path.realpath(p)
    if real not in _NEW:
        os.replace(tmp, p)
        return
    try:
        os.link(tmp, p)
    except FileExistsError:
        raise InputError(f"{p}: was written by another run meanwhile; this run's result is not "
                         "put in its place (add --force to replace it)") from None
    except OSError:   # a file system without hard links: replace, as with --force
        os.replace(tmp, p)
        return
    _NEW.discard(real)
    os.unlink(tmp)


@contextlib.contextmanager
def atomic(path, mode: str = "w", **kw):
    """open() for writing into a temporary file beside path, renamed onto path when the block
    ends without an exception (and removed when it does not)."""
    p = Path(path)
    if os.path.realpath(p) in _READ:
        raise InputError(f"{path}: is one of this command's inputs; refusing to overwrite it")
    remove_stale(p)
    tmp = _tmp_for(p)
    try:
        fh = open(tmp, mode, **kw)
    except OSError as e:
        raise InputError(f"{path}: cannot write ({e.strerror})") from None
    try:
        with fh:
            yield fh
        _put(tmp, p)
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise


FIGURE_FORMATS = (".png", ".svg", ".pdf")


def check_figure_name(path, option: str) -> None:
    """A figure's file name says its format: .png, .svg or .pdf (a .csv is no figure)."""
    if Path(path).suffix.lower() not in FIGURE_FORMATS:
        raise InputError(f"{path}: {option} writes a figure: name it .png, .svg or .pdf")


def write_text(path, text: str) -> None:
    with atomic(path) as fh:
        fh.write(text)


def save_figure(fig, path, **kw) -> None:
    """fig.savefig(path), atomically."""
    p = Path(path)
    with atomic(p, "wb") as fh:
        fig.savefig(fh, format=p.suffix.lstrip(".").lower() or "png", **kw)
