"""docs/ is two things (issue 48 part 4): the reference pages (docs/*.md and the README) say what
is true now, with no dates and no commit hashes; the dated notebook (docs/notes/) keeps the
measurements and their history, and the reference links it where it quotes a figure."""
import re
import shutil
import subprocess

import pytest

from conftest import ROOT

REFERENCE = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
NOTES = sorted((ROOT / "docs" / "notes").glob("*.md"))
MONTHS = ("January|February|March|April|May|June|July|August|September|October|November|"
          "December|Jan|Feb|Mar|Apr|Jun|Jul|Aug|Sep|Sept|Oct|Nov|Dec")
DATE = re.compile(rf"\b\d{{4}}-[01]\d-[0-3]\d\b|\b[0-3]?\d(?:st|nd|rd|th)? (?:{MONTHS})\b"
                  rf"|\b(?:{MONTHS}) [0-3]?\d(?:st|nd|rd|th)?\b|\b(?:{MONTHS}) (?:19|20)\d\d\b")
HEX = re.compile(r"(?<![\w.])[0-9a-f]{7,40}(?![\w.])")


def commits(words: set[str]) -> set[str]:
    """The words that name a commit of this repository (hex constants such as 0x2F or a count
    like 1347053 that is no commit are not caught)."""
    words = sorted(words)
    out = subprocess.run(["git", "-C", str(ROOT), "cat-file", "--batch-check"],
                         input="".join(f"{w}^{{commit}}\n" for w in words),
                         capture_output=True, text=True, check=True).stdout.splitlines()
    return {w for w, line in zip(words, out) if not line.endswith("missing")
            and not line.endswith("ambiguous")}


def test_the_date_pattern_finds_dates_and_leaves_figures():
    for text in ("measured 26 November", "on 2026-11-28", "November 2026", "Nov 3rd"):
        assert DATE.search(text), text
    for text in ("14 days at 100 Hz", "1 MB", "0x2F", "12 mg", "issue 48", "may be"):
        assert not DATE.search(text), text


@pytest.mark.skipif(not (ROOT / ".git").exists() or not shutil.which("git"),
                    reason="a checkout's history is needed to tell a commit from a number")
def test_the_reference_names_no_commit():
    head = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short=7", "HEAD"],
                          capture_output=True, text=True, check=True).stdout.strip()
    assert commits({head}) == {head}    # the check does find a commit when one is named
    bad = []
    for page in REFERENCE:
        found = commits(set(HEX.findall(page.read_text())))
        bad += [f"{page.relative_to(ROOT)}: {h}" for h in sorted(found)]
    assert not bad, "commit hashes belong in docs/notes/: " + ", ".join(bad)


@pytest.mark.parametrize("page", REFERENCE, ids=lambda p: p.name)
def test_the_reference_is_undated(page):
    bad = [f"{page.name}:{n}: {m.group(0)}" for n, line in enumerate(page.read_text().splitlines(), 1)
           for m in DATE.finditer(line)]
    assert not bad, "dated notes belong in docs/notes/: " + "; ".join(bad)


def test_the_notebook_is_dated_and_linked():
    """Each notebook page is dated (in its name or its sections) and some reference page links it,
    so a figure quoted in the reference leads to its history."""
    assert NOTES, "docs/notes/ holds the measurements"
    linked = "\n".join(p.read_text() for p in REFERENCE)
    for note in NOTES:
        assert DATE.search(note.name) or DATE.search(note.read_text()), note.name
        assert f"notes/{note.name}" in linked, f"no reference page links {note.name}"
