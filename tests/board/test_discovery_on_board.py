"""The board's own discovery as a user sees it (issue 29): a board log holding DISCOVERY records
(written by the device Processor with discover=True on test_discover's stream with a hidden
temp_offset) is told by `report` in text, JSON and on its page; `deploy`/`acquire --discover`
refuse the settings the board cannot discover from in one line; and (slow) the virtual board,
deployed with `--discover` and `base`, acquires two simulated days of wrist wear with a hidden
temp_offset, `pull` shows it adopted, and the host's replay of the capture is identical."""
import json

import numpy as np
import pytest

import test_discover
from conftest import run_cli, run_main


@pytest.fixture(scope="module")
def pulled(tmp_path_factory):
    """A folder as `pull` writes it, with the log of a board that discovered temp_offset."""
    d = tmp_path_factory.mktemp("discovered")
    script = test_discover._stream(d, "hidden", test_discover.C_TRUE)
    (d / "pulled").mkdir()
    test_discover._run_cpython(script, d / "pulled" / "log.bin")
    return d / "pulled"


def test_report_tells_the_boards_discovery(pulled, tmp_path):
    s = json.loads(run_cli("report", pulled, "--json").stdout)
    found = s["discoveries"]
    adopted = [d for d in found if d["adopted"]]     # the board retries after each calibration
    assert len(adopted) == 1 and found[-1] is adopted[0]   # until one is adopted
    first = adopted[0]
    assert first["adopted"] == first["closest"] == "temp_offset"
    assert first["heldout_after"] < 0.9 * first["heldout_before"]    # the rule's 10 %
    assert first["change_pct"] < -10 and 0 < first["blocks_better"] <= first["blocks"]
    # its parameters, in mg/degC, near the hidden ones (0.9, -0.7, 0.6 mg/degC)
    c = np.array(list(first["params"].values()))
    assert first["unit"] == "mg/degC" and np.abs(c - test_discover.C_TRUE * 1e3).max() < 0.3
    # the calibration after it is the composed model's
    cal = next(c for c in s["calibrations"] if c["index"] >= first["index"] and "effects" in c)
    assert list(cal["effects"]) == ["temp_offset"]

    r = run_cli("report", pulled, "--html", tmp_path / "board.html")
    assert r.returncode == 0, r.stderr
    assert "ADOPTED temp_offset" in r.stdout
    assert r.stdout.count("discovery at sample") == len(found), r.stdout
    page = (tmp_path / "board.html").read_text()
    assert "Discovery on the board" in page and "temp_offset" in page


@pytest.mark.parametrize("settings", [["--profile", "paper"], ["--model", "base+drift"]])
@pytest.mark.parametrize("command", [["deploy"], ["acquire", "--hours", "1"]])
def test_discover_refuses_what_the_board_cannot_discover_from(capsys, command, settings):
    code, _, err = run_main(capsys, [*command, "--port", "/dev/null", "--discover", *settings])
    assert code == 2 and len(err.strip().splitlines()) == 1 and "--discover" in err, err


@pytest.mark.slow
def test_the_virtual_board_discovers_a_hidden_temp_offset_and_replays(tmp_path):
    """Two days at 10 Hz on the unix port (~1 min), the capture pulled over mpremote (~3 min)."""
    from accelcal.board import virtual
    r = run_cli("simulate", "wrist", "--days", 2, "--rate", 10, "--seed", 31, "--effect",
                "temp_offset", "-o", tmp_path / "w.csv", "--stimulus", tmp_path / "w.bin")
    assert r.returncode == 0, r.stderr
    with virtual.Running(tmp_path / "flash", tmp_path / "w.bin", "--heap", "240k") as b:
        common = ["--port", b.port, "--rate", 10, "--capture-kb", 16384, "--discover"]
        assert run_cli("deploy", *common).returncode == 0
        r = run_cli("acquire", "--hours", 48, *common)
        assert r.returncode == 0, r.stderr
        r = run_cli("pull", "--port", b.port, "-o", tmp_path / "pulled")
        assert r.returncode == 0, r.stderr
    assert "ADOPTED temp_offset" in r.stdout, r.stdout
    rep = run_cli("replay", tmp_path / "pulled", "--json")
    out = json.loads(rep.stdout)
    assert out["identical"] and out["discovery"]["board"] >= 1, out


def test_boot_records_of_earlier_versions_read_as_not_discovering():
    """A board flashed before discovery logged a shorter BOOT (version 2 without `discover`,
    version 1 without `fit` too): pulled logs of those boards still decode, as not discovering."""
    import struct
    from acal.logger import log
    from accelcal.bridge import boardlog
    values = (0, 2, 25, 5, 0, 3, 2, 0, 2, 8, 6553, 20, 600, -128, 0, 1)
    for fmt, vals, fit in ((log.BOOT_V2, values, 1), (log.BOOT_V1, values[:-1], 0)):
        payload = struct.pack(fmt, *vals)
        assert boardlog.malformed(log.BOOT, payload) is None
        b = dict(zip(boardlog.FIELDS[log.BOOT], log.unpack(log.BOOT, payload)))
        assert b["discover"] == 0 and b["fit"] == fit and b["rate_hz"] == 25
    now = struct.pack(log.FORMATS[log.BOOT], *values, 1)
    assert dict(zip(boardlog.FIELDS[log.BOOT], log.unpack(log.BOOT, now)))["discover"] == 1


def test_a_discovering_board_calibrates_as_early_as_one_that_does_not(tmp_path):
    """Until its first calibration a discovering board's bins take the held-out blocks' rest
    means too (Pipeline.early), so that calibration comes when it would without discovery;
    after it those points leave the bins, and the discovery runs from the next calibration, on
    points its held-out set never shares.  Held out from the start, the same stream's bins
    fill later."""
    from acal.logger import log
    from accelcal.bridge import boardlog
    script = test_discover._stream(tmp_path, "hidden", test_discover.C_TRUE)
    text = script.read_text()
    variants = {"discover": text, "plain": text.replace('{"discover": True}', '{"discover": False}'),
                "held_from_start": text.replace("    buf = array(", "    p.pipe.plug.early = False\n    buf = array(", 1)}
    assert len({variants[k] for k in variants}) == 3
    first = {}
    for name, t in variants.items():
        f = tmp_path / f"{name}.py"
        f.write_text(t)
        test_discover._run_cpython(f, tmp_path / f"{name}.bin")
        d = boardlog.decode(tmp_path / f"{name}.bin")
        first[name] = d.dicts(log.CAL)[0]["index"]
        if name == "discover":
            found = d.dicts(log.DISCOVERY)
            assert found and found[0]["index"] > first[name]   # not after the first calibration
            assert found[-1]["adopted"]
    assert first["discover"] == first["plain"] < first["held_from_start"], first


def test_leaving_early_takes_every_held_out_point_out_of_the_bins():
    from acal.core import profile
    from acal.core.bins import N_SUBSETS
    from acal.core.fixed import C_TEMP, C_TIME
    from acal.discover.heldout import held_out
    from acal.core.pipeline import Pipeline
    from acal.discover.plug import Plug
    pipe = Pipeline(10, plug=Plug(), **profile.settings(profile.WEAR, False))
    pipe.plug.early = True
    rng = np.random.default_rng(3)
    for i in range(600):          # 600 rest means over 40 h, in every direction
        v = rng.normal(size=3)
        v = v / np.linalg.norm(v)
        pipe.now[C_TIME] = i * 4         # 64 s units: 256 s apart
        pipe.now[C_TEMP] = (20 + i % 9) * 4   # Q2 degC
        pipe.offer(*(int(c * 65536) for c in v))
    b = pipe.bins
    def times():
        return [b.condition(s, k)[1] for s in range(N_SUBSETS) for k in range(b.counts[s])]
    assert any(held_out(t) for t in times())           # early: the bins took them too
    kept = [t for t in times() if not held_out(t)]
    pipe.plug.leave_early(pipe)
    assert sorted(times()) == sorted(kept) and not pipe.plug.early
