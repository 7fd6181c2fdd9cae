"""Figures that show the structure, not the outliers, and one report a person reads: the
y-range excludes injected outliers and holds the bulk, the binned means equal an independent
computation, the outliers are drawn at the edge and counted; diagnose --report, report --html
(a history, a pulled board log) write one HTML file that parses, holds every figure inline and
no external URL, and whose numbers are --json's; where a headless Chromium is present, the
report renders to a screenshot that is not blank."""
import json
import re
import shutil
import subprocess
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pytest

from accelcal.report import figures
from conftest import run_cli


def test_robust_limits_hold_the_bulk_and_leave_out_false_rest(rng):
    # the demo's case: +-5 mg of structure, five false-rest points at -180 to -520 mg
    bulk = rng.normal(0, 1.5, 4000) + 3 * np.sin(np.linspace(0, 6, 4000))
    y = np.r_[bulk, [-180, -260, -330, -410, -520]]
    lo, hi = figures.robust_limits(y, floor=0.5)
    assert -30 < lo < bulk.min() + 1e-9 and bulk.max() - 1e-9 < hi < 30
    assert np.mean((bulk >= lo) & (bulk <= hi)) == 1.0
    # a constant residual still gets a range, and the noise band always shows
    lo0, hi0 = figures.robust_limits(np.zeros(100), floor=0.2)
    assert lo0 < -0.2 and hi0 > 0.2


def test_binned_means_equal_an_independent_computation(rng):
    x = rng.uniform(20, 35, 3000)
    y = 0.4 * (x - 27) + rng.normal(0, 2, 3000)
    b = figures.binned_means(x, y, bins=8)
    # independently: sort by x, cut into 8 near-equal runs at the same quantile edges
    edges = np.quantile(x, np.linspace(0, 1, 9))
    for k in range(8):
        last = k == 7
        sel = (x >= edges[k]) & ((x <= edges[k + 1]) if last else (x < edges[k + 1]))
        assert b.n[k] == sel.sum()
        assert b.mean[k] == pytest.approx(y[sel].mean(), abs=1e-12)
        assert b.ci95[k] == pytest.approx(1.96 * y[sel].std(ddof=1) / np.sqrt(sel.sum()))
        assert b.centre[k] == pytest.approx(np.median(x[sel]))
    assert b.n.sum() == len(x)


def test_a_panel_draws_the_outliers_at_its_edge_and_counts_them(rng):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    x = rng.uniform(0, 70, 2000)
    r = rng.normal(0, 1, 2000)
    r[:7] = [-200, -300, -400, 250, -500, 600, -180]
    fig, ax = plt.subplots()
    drawn = figures.residual_panel(ax, x, r, 0.3, "time (h)")
    lo, hi = ax.get_ylim()
    assert drawn["below"] == 5 and drawn["above"] == 2
    assert -10 < lo and hi < 10
    texts = [t.get_text() for t in ax.texts]
    assert any(t.startswith("7 beyond the axis") for t in texts)
    assert ax.get_ylabel().endswith("(mg)") and ax.get_xlabel() == "time (h)"
    plt.close(fig)


class _Page(HTMLParser):
    def __init__(self):
        super().__init__()
        self.imgs, self.data, self.cells, self._in_json, self._cell = [], None, [], False, None

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if tag == "img":
            self.imgs.append(a.get("src", ""))
        if tag == "script" and a.get("type") == "application/json":
            self._in_json = True
        if tag == "td":
            self._cell = ""

    def handle_endtag(self, tag):
        if tag == "script":
            self._in_json = False
        if tag == "td" and self._cell is not None:
            self.cells.append(self._cell)
            self._cell = None

    def handle_data(self, data):
        if self._in_json:
            self.data = json.loads(data)
        elif self._cell is not None:
            self._cell += data


def parse_page(path: Path) -> _Page:
    text = path.read_text(encoding="utf-8")
    assert text.startswith("<!DOCTYPE html>") and text.rstrip().endswith("</html>")
    assert not re.search(r"(src|href)\s*=\s*[\"']?(https?:|//)", text), "an external reference"
    assert "http://" not in text and "https://" not in text
    p = _Page()
    p.feed(text)
    assert all(s.startswith("data:image/png;base64,") for s in p.imgs)
    return p


@pytest.fixture(scope="module")
def hidden(tmp_path_factory):
    d = tmp_path_factory.mktemp("report")
    f = d / "ts.csv"
    assert run_cli("simulate", "wrist", "--days", "3", "--rate", "10", "--seed", "7", "--effect",
                   "temp_scale", "-o", f).returncode == 0
    return d, f


def test_diagnose_report_is_one_self_contained_page_with_the_json_numbers(hidden):
    d, f = hidden
    r = run_cli("diagnose", f, "--json", "--report", d / "rep", "--history", d / "h.jsonl")
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    page = parse_page(d / "rep" / "report.html")
    assert len(page.imgs) == 2                      # residuals, candidates
    assert page.data == {k: v for k, v in out.items() if k != "report"}
    assert f"{out['heldout_error_mg']:.3f}" in page.cells
    assert f"{out['noise_floor_mg']:.3f}" in page.cells
    for c in out["candidates"]:
        if c["heldout_error_mg"] is not None:
            assert f"{c['heldout_error_mg']:.3f}" in page.cells
    assert out["missing_effect"] == "temp_scale"
    text = (d / "rep" / "report.html").read_text()
    assert "Named effect: temp_scale" in text and "--model base+temp_scale" in text
    # the next step: before and after, side by side, in the same folder's new report
    r = run_cli("diagnose", f, "--json", "--model", "base+temp_scale", "--report", d / "rep",
                "--history", d / "h.jsonl", "--force")
    assert r.returncode == 0, r.stderr
    page = parse_page(d / "rep" / "report.html")
    assert len(page.imgs) == 3                      # + step.png, before and after
    assert "Model steps so far" in (d / "rep" / "report.html").read_text()
    # the history as its own page
    r = run_cli("report", d / "h.jsonl", "--html", d / "steps.html")
    assert r.returncode == 0, r.stderr
    steps = parse_page(d / "steps.html")
    assert [s["model"] for s in steps.data["steps"]] == ["base", "base+temp_scale"]
    assert len(steps.imgs) == 1


def test_a_pulled_board_log_as_a_page(tmp_path, rng):
    import test_app
    path = tmp_path / "stim.bin"
    test_app.stimulus(path, rng)
    work = tmp_path / "pulled"
    work.mkdir()
    test_app.run_app(work, test_app.board(path), recal_seconds=300)
    r = run_cli("report", work, "--html", tmp_path / "board.html")
    assert r.returncode == 0, r.stderr
    page = parse_page(tmp_path / "board.html")
    cals = page.data["calibrations"]
    assert len(cals) >= 1 and len(page.imgs) == 1
    assert f"{cals[-1]['kxx']:.5f}" in page.cells
    r = run_cli("report", work, "--json")
    assert json.loads(r.stdout)["calibrations"] == cals


def test_the_report_renders_in_a_headless_browser(hidden, tmp_path):
    browser = next((shutil.which(b) for b in ("chromium", "chromium-browser", "google-chrome")
                    if shutil.which(b)), None)
    if browser is None:
        pytest.skip("no headless Chromium on this machine (Debian: apt install chromium)")
    d, f = hidden
    assert run_cli("diagnose", f, "--report", tmp_path / "rep").returncode == 0
    shot = tmp_path / "shot.png"
    subprocess.run([browser, "--headless", "--no-sandbox", "--disable-gpu",
                    f"--screenshot={shot}", "--window-size=1200,3000",
                    (tmp_path / "rep" / "report.html").as_uri()], capture_output=True, timeout=120)
    import matplotlib.image as mpimg
    img = mpimg.imread(shot)
    assert img.std() > 0.05   # not a blank page
