"""A GENEActiv .bin cut short: the pages it holds, read as the maker's readers read them.

A .bin is a text header ending in "Number of Pages:N", then N pages, each "Recorded Data", 8
field lines and one hex line of 300 samples (12 hex digits each: 3600 characters).  A file copied
off before the device finished writing, or cut in transfer, holds fewer pages than its header
declares (GGIR's own test file GENEActiv_testfile.bin declares 222 048 and holds 17, the 17th cut
mid-way).  GGIRread's GENEActivReader reads page after page until the file ends, whatever the
header says, and GENEAread reads the pages asked for that exist; here the same: every whole page
is kept, a page cut mid-way is dropped (its last sample could be half a sample), and both counts
go to the recording's quality record (`pages_missing`: declared but not in the file; `pages_cut`)
with one warning line.  actfast sizes its first allocation from the declared count, so it reads
a scratch copy whose header declares the whole pages it holds (files/devheaders.py says why)."""
from __future__ import annotations

import contextlib
import re
import tempfile
from pathlib import Path
from typing import NamedTuple

PAGE_HEX = 12 * 300     # a page's hex line: 300 samples of 12 hex digits


class BinPages(NamedTuple):
    """What check_bin counted: the header's declared pages, the pages that begin in the file
    (`found`), the whole ones among them, and the byte offsets where the first page begins and
    the last whole page ends."""
    declared: int
    found: int
    whole: int
    start: int      # the byte offset of the first page (the header's end)
    end: int

    @property
    def missing(self) -> int:
        """Pages the header declares that never begin in the file."""
        return max(0, self.declared - self.found)

    @property
    def cut(self) -> int:
        """Pages that begin in the file but end before their hex line does (dropped)."""
        return self.found - self.whole

    @property
    def short(self) -> bool:
        return self.missing > 0 or self.cut > 0

    def warning(self) -> str:
        return (f"a truncated file: the header declares {self.declared} pages, the file holds "
                f"{self.whole} whole page{'s' * (self.whole != 1)}"
                + (f" and {self.cut} cut mid-way (dropped)" if self.cut else "")
                + f"; {self.missing} declared pages missing")


@contextlib.contextmanager
def whole_pages(path: str, pages: BinPages):
    """A scratch copy of `path` holding its header (declaring `pages.whole` pages) and its whole
    pages only: what a reader that trusts the header may be given."""
    scratch = "/dev/shm" if Path("/dev/shm").is_dir() else None
    with open(path, "rb") as src, tempfile.NamedTemporaryFile(suffix=".bin", dir=scratch) as tmp:
        head = src.read(pages.start)
        tmp.write(re.sub(rb"Number of Pages:[^\r\n]*", b"Number of Pages:%d" % pages.whole,
                         head, count=1))
        left = pages.end - pages.start
        while left > 0:
            piece = src.read(min(left, 1 << 22))
            if not piece:
                break
            tmp.write(piece)
            left -= len(piece)
        tmp.flush()
        yield tmp.name


