"""A diagnose history: one JSON line per model step (model, held-out error, noise floor, the
effect named next), appended whole by `diagnose --history`, read back checked line by line, and
shown by `report HISTORY` as a table, a figure and a page."""
from __future__ import annotations

import json
import math
from pathlib import Path

from accelcal.errors import InputError
from accelcal.files.outputs import check_output, save_figure, write_text
from accelcal.pipeline.results import StepsResult


HISTORY_MAX_BYTES = 16 << 20    # a history is one short line per model step
LINE_MAX = 64 * 1024


def check_history(path) -> None:
    """diagnose --history FILE, before the analysis: FILE is missing, empty or a history (every
    line one); anything else (a parameters JSON, a recording) is refused, never appended to."""
    p = Path(path)
    if not p.exists():
        return
    read_history(path, what="refusing to append to it")


def append_history(path: str, step: dict) -> None:
    """Append one step (DiagnoseResult.history_step) to the history at path: one line written at
    the end of the file under an exclusive lock (fcntl.flock), after the file was checked under
    the same lock to be a history.  Concurrent writers each add their line; none is lost."""
    import fcntl
    line = (json.dumps(step) + "\n").encode()
    try:
        fh = open(path, "a+b")
    except OSError as e:
        raise InputError(f"{path}: cannot append to the history ({e.strerror})") from None
    with fh:
        fcntl.flock(fh, fcntl.LOCK_EX)    # released when the file closes
        read_history(path, what="refusing to append to it")
        fh.seek(0, 2)
        if fh.tell():
            fh.seek(-1, 2)
            if fh.read(1) != b"\n":
                line = b"\n" + line
        fh.write(line)
        fh.flush()


def _history_step(path, i, line):
    # One line of a diagnose history, checked: model, held-out and floor mg, named, input.
    bad = f"{path}:{i}: not a diagnose history line"
    try:
        rec = json.loads(line, parse_constant=lambda c: float("nan"))
    except (ValueError, RecursionError):   # RecursionError: nested deeper than Python's stack
        raise InputError(bad + " (not JSON)") from None
    if not isinstance(rec, dict):
        raise InputError(bad + " (not a JSON object)")
    model = rec.get("model")
    if not isinstance(model, str) or not model:
        raise InputError(f"{path}:{i}: 'model' must be a model name, found {model!r:.40}")
    vals = []
    for k, lo in (("heldout_error_mg", 0.0), ("noise_floor_mg", 0.0)):
        v = rec.get(k)
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) \
                or v < lo or (k == "heldout_error_mg" and v == 0):
            raise InputError(f"{path}:{i}: {k} must be a finite number of mg"
                             + (" above 0" if k == "heldout_error_mg" else " >= 0")
                             + f", found {v!r:.40}")
        vals.append(float(v))
    named = rec.get("missing_effect")
    if named is not None and not isinstance(named, str):
        raise InputError(f"{path}:{i}: missing_effect must be an effect name or null")
    return {"model": model, "heldout_error_mg": vals[0], "noise_floor_mg": vals[1],
            "missing_effect": named, "input": str(rec.get("input", ""))}


def read_history(path, what: str = "") -> list[dict]:
    """The steps of a diagnose history, each line checked (_history_step); at most
    HISTORY_MAX_BYTES, lines of at most LINE_MAX."""
    from accelcal.files.outputs import check_regular
    check_regular(path)
    why = f"; {what}" if what else ""
    size = Path(path).stat().st_size
    if size > HISTORY_MAX_BYTES:
        raise InputError(f"{path}: not a diagnose history ({size >> 20} MB; a history is at most "
                         f"{HISTORY_MAX_BYTES >> 20} MB){why}")
    try:
        lines = Path(path).read_bytes().decode("utf-8").splitlines()
    except OSError as e:
        raise InputError(f"{path}: cannot read ({e.strerror})") from None
    except UnicodeDecodeError:
        raise InputError(f"{path}: not a diagnose history (not UTF-8 text){why}") from None
    steps = []
    for i, line in enumerate(lines, 1):
        if len(line) > LINE_MAX:
            raise InputError(f"{path}:{i}: not a diagnose history line (longer than "
                             f"{LINE_MAX // 1024} KiB){why}")
        if line.strip():
            try:
                steps.append(_history_step(path, i, line))
            except InputError as e:
                raise InputError(f"{e}{why}") from None
    return steps


def history_report(*, history: str, plot: str | None = None, html: str | None = None,
                   force: bool = False) -> StepsResult:
    """`accelcal report HISTORY`: each model step with its held-out error; plot: the steps as
    a PNG (replaced); html: a page (force: replace it)."""
    if html:
        check_output(html, [history], force, "--html")
    steps = read_history(history)
    if not steps:
        raise InputError(f"{history}: no steps (run diagnose --history {history})")
    out = StepsResult(steps=steps, plot=plot, report=html)
    if plot or html:
        import io

        import matplotlib.pyplot as plt

        from accelcal.report.figures import steps_figure
        fig = steps_figure(steps)
        if plot:
            save_figure(fig, plot, dpi=90)
        if html:
            from accelcal.report import pages
            buf = io.BytesIO()
            fig.savefig(buf, format="png", dpi=80)
            write_text(html, pages.history_page(history, steps, {"steps.png": buf.getvalue()}))
        plt.close(fig)
    return out
