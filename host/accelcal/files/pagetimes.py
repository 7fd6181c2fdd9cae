"""Page times that overlap, resolved as the device makers' own readers do.

A GENEActiv .bin holds 300 samples a page, each page with its own `Page Time`; a reader (actfast)
places a page's samples at that time plus i / frequency.  Page times are the device clock's,
written at a coarse step (half or whole seconds), so on some devices and rates (a 66.7 Hz
recording: 300 samples are 4.498 s) a page can be stamped before the previous page's last
sample: the samples' times then go back, and a reader that requires time to increase refused the
whole file.  The maker's own readers never see it: GENEAread (ActivInsights' R package,
`read.bin`) times every sample from the first page's time at the file's frequency, ignoring later
page times, and GGIRread's `GENEActivReader` counts each page on from the previous page's last
sample.  Here a page stamped at or before the previous page's last sample is placed as they place
it, one sample period after that sample (its own spacing kept), and every other page keeps its
own time, so files without overlaps read exactly as before (and a page that starts late is
still a gap).  The count of pages so placed goes to the recording's quality record."""
from __future__ import annotations

import numpy as np

GENEACTIV_PAGE = 300   # samples a page


def resolve_overlaps(t: np.ndarray, page: int = GENEACTIV_PAGE) -> int:
    """Shift, in place, each page of t (page samples each, the last may be shorter) whose first
    time is at or before the previous page's last one, to one sample period after it; returns
    how many pages were shifted.  The period is the page's own step (its second sample minus
    its first; the previous page's for a one-sample page)."""
    starts = np.arange(page, len(t), page)
    if not len(starts) or (t[starts] > t[starts - 1]).all():
        return 0
    ends = np.minimum(starts + page, len(t))
    first = t[starts].tolist()
    last = t[ends - 1].tolist()
    prev_last = float(t[page - 1])
    period = float(t[1] - t[0]) if page > 1 and len(t) > 1 else 0.0
    shifts = np.zeros(len(starts))
    moved = 0
    for k, (a, b) in enumerate(zip(first, last)):
        s = starts[k]
        if ends[k] - s > 1:
            period = float(t[s + 1] - t[s])
        if a <= prev_last:
            shifts[k] = prev_last + period - a
            moved += 1
        prev_last = b + shifts[k]
    if moved:
        t[page:] += np.repeat(shifts, ends - starts)
    return moved
