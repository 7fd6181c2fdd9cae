"""`report PULLED_DIR`: a board's calibrations over time, from the logs `pull` copied off it."""
from __future__ import annotations

from pathlib import Path

from accelcal.bridge import boardlog
from accelcal.errors import InputError
from accelcal.files.outputs import check_output, write_text
from accelcal.pipeline.results import BoardReport


def board_report(*, pulled_dir: str, html: str | None = None, force: bool = False) -> BoardReport:
    """`accelcal report PULLED_DIR`: the board's calibrations over time (html: a page with
    their figure; force: replace it)."""
    d = Path(pulled_dir)
    if not (d / "log.bin").exists():
        raise InputError(f"{d}: a folder report reads is one `pull` wrote (no log.bin in it)")
    if html:
        check_output(html, [d / "log.bin"], force, "--html")
    summ = boardlog.summary(d)
    from accelcal.board.deploy import read_deployed
    deployed = read_deployed(d)     # what deploy recorded on the board (None: not recorded)
    if deployed is not None:
        summ["deployed"] = deployed
    boots = boardlog.decode(d / "log.bin").dicts(boardlog.log.BOOT)
    rate = boots[-1]["rate_hz"] if boots else (deployed or {}).get("app", {}).get("rate_hz")
    cals = summ["calibrations"]
    if html:
        import io

        import matplotlib.pyplot as plt

        from accelcal.report import pages
        from accelcal.report.figures import calibrations_figure
        pngs = {}
        if cals:
            fig = calibrations_figure(cals, rate)
            buf = io.BytesIO()
            fig.savefig(buf, format="png", dpi=80)
            plt.close(fig)
            pngs["calibrations.png"] = buf.getvalue()
        write_text(html, pages.board_page(str(d), summ, pngs, rate))
    return BoardReport(summary=summ, rate_hz=rate, report=html)
