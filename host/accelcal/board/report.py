"""`report PULLED_DIR`: a board's calibrations over time, from the logs `pull` copied off it."""
from __future__ import annotations

import json
import sys
from pathlib import Path

from accelcal.bridge import boardlog
from accelcal.errors import InputError
from accelcal.files.outputs import check_output, write_text


def board_report(*, pulled_dir: str, html: str | None, force: bool = False,
                 as_json: bool = False) -> int:
    """`accelcal report PULLED_DIR`: the board's calibrations over time (table; --html a page
    with their figure; --json the summary)."""
    d = Path(pulled_dir)
    if not (d / "log.bin").exists():
        raise InputError(f"{d}: a folder report reads is one `pull` wrote (no log.bin in it)")
    if html:
        check_output(html, [d / "log.bin"], force, "--html")
    summ = boardlog.summary(d)
    boots = boardlog.decode(d / "log.bin").dicts(boardlog.log.BOOT)
    rate = boots[-1]["rate_hz"] if boots else None
    cals = summ["calibrations"]
    if as_json:
        print(json.dumps(summ))
    else:
        print(f"{'number':>6} {'hours':>7} {'status':<34} {'points':>6}  kxx      kyy      kzz      "
              "ox mg   oy mg   oz mg")
        for c in cals:
            h = f"{c['index'] / rate / 3600:7.2f}" if rate else "      -"
            print(f"{c['number']:>6} {h} {c['status']:<34} {c['points']:>6}  {c['kxx']:.5f}  "
                  f"{c['kyy']:.5f}  {c['kzz']:.5f}  {c['ox'] * 1e3:6.2f}  {c['oy'] * 1e3:6.2f}  "
                  f"{c['oz'] * 1e3:6.2f}")
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
        print(f"report: {html}", file=sys.stderr)
    return 0
