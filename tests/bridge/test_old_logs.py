"""Every board-log record layout the app ever wrote still loads (docs/boards-and-logs.md
"Record layouts"): fixtures written by the log.py of each layout's time (tests/data/oldlogs/,
made by make_fixtures.py beside them from each commit's own device/acal) decode with no
record dropped or called malformed, each field as the layout's rule reads it (a BOOT without
the temperature reference: -128, relative temperatures; without the model: 0; without fit or
discover: GRADIENT, 0; an EFFECT's whole-degC reference in Q2; a version-3 DISCOVERY's effect
its closest's), and `report` lists their calibrations' effects and their discoveries."""
import pytest

from accelcal.bridge import boardlog
from conftest import ROOT, run_main

OLD = ROOT / "tests" / "data" / "oldlogs"
COMMON = [50, 5, 0, 3, 2, 1, 2, 8, 6554, 20, 3600]   # rate .. recal_seconds, as written
# file -> (BOOT as decoded: first field, version, COMMON, temp_ref, model, fit, discover;
#          EFFECT record?, DISCOVERY record?)
EXPECT = {
    "boot1a-9562c53.bin": ([1, 1, *COMMON, -128, 0, 0, 0], False, False),
    "boot1b-a3c88e0.bin": ([0, 1, *COMMON, 20, 0, 0, 0], False, False),
    "boot1-3678e9b.bin": ([0, 1, *COMMON, 20, 1, 0, 0], True, False),
    "boot2-95d74b3.bin": ([0, 2, *COMMON, 20, 1, 1, 0], True, False),
    "disc1-791069c.bin": ([0, 2, *COMMON, 20, 1, 1, 0], True, True),
    "boot3-98e9e41.bin": ([0, 3, *COMMON, 20, 1, 1, 1], True, True),
    "effectq2-b88c2cc.bin": ([0, 3, *COMMON, 20, 1, 1, 1], True, True),
    "disc2-4ab10d2.bin": ([0, 4, *COMMON, 20, 1, 1, 1], True, True),
}


def test_every_layout_has_its_fixture():
    assert sorted(p.name for p in OLD.glob("*.bin")) == sorted(EXPECT)


@pytest.mark.parametrize("name", sorted(EXPECT))
def test_old_layout_decodes_whole(name):
    boot, effect, disc = EXPECT[name]
    d = boardlog.decode(OLD / name)
    assert d.malformed == [] and d.dropped == [], (d.malformed, d.dropped)
    assert [list(v) for v in d.of(boardlog.log.BOOT)] == [boot]
    assert [r["index"] for r in d.dicts(boardlog.log.REST)] == [250, 500]
    (cal,) = d.dicts(boardlog.log.CAL)
    assert (cal["index"], cal["points"], cal["kxx"], cal["ox"]) == (1000, 18, 1 << 24, 4096)
    assert d.dicts(boardlog.log.COUNTERS)[0]["samples"] == 1500
    effects = d.dicts(boardlog.log.EFFECT)
    # 25 degC, whole degC in the old layout and Q2 (x4) in the new: the same 100 decoded
    assert effects == ([dict(index=1000, effect=1, ref_temp=100, ref_time=0, p0=1677, p1=0, p2=0)]
                       if effect else [])
    discs = d.dicts(boardlog.log.DISCOVERY)
    assert discs == ([dict(index=2000, adopted=1, closest=1, heldout_before=5000,
                           heldout_after=3000, blocks_better=7, blocks=8, effect=1, p0=3355,
                           p1=0, p2=0)] if disc else [])


@pytest.mark.parametrize("name", sorted(EXPECT))
def test_report_lists_effects_and_discoveries(name, tmp_path, capsys):
    _, effect, disc = EXPECT[name]
    (tmp_path / "log.bin").write_bytes((OLD / name).read_bytes())
    code, out, err = run_main(capsys, ["report", tmp_path])
    assert code == 0, err
    assert ("effect temp_offset: cx=+0.006247" in out and "(reference 25 degC)" in out) == effect, out
    assert ("discovery at sample 2000 (0.0 h): ADOPTED temp_offset (held-out error -40 %, better "
            "in 7 of 8 held-out blocks)" in out) == disc, out
    assert "malformed" not in out + err


def test_report_page_of_an_old_log_shows_its_effect_and_discovery(tmp_path, capsys):
    (tmp_path / "log.bin").write_bytes((OLD / "disc1-791069c.bin").read_bytes())
    page = tmp_path / "board.html"
    code, _, err = run_main(capsys, ["report", tmp_path, "--html", page])
    assert code == 0, err
    html = page.read_text()
    cals, disc = html.split("<h2>Calibrations over time</h2>")[1].split(
        "<h2>Discovery on the board</h2>")
    assert "temp_offset" in cals.split("<h2>")[0] and "temp_offset" in disc.split("<h2>")[0]
