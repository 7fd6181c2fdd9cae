"""docs/first-board.md, run: every command of its ```sh blocks, in order, in a shell with PORT
the board's port, as a reader types them; on the virtual board, and (slow) on the emulated Pico.
The pip line is the one tests/test_wheel.py runs in a fresh venv (the wheel in place of the
name), not run here: it would replace this checkout's install."""
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import test_app
from accelcal.board import virtual
from accelcal.errors import PIP_BOARD
from conftest import ROOT

GUIDE = ROOT / "docs" / "first-board.md"


def guide_commands() -> list[str]:
    text = GUIDE.read_text()
    blocks = re.findall(r"^```sh\n(.*?)^```", text, re.M | re.S)
    return [line for b in blocks for line in b.splitlines() if line.strip()]


def run_guide(tmp_path, port):
    env = dict(os.environ, PORT=port,
               PATH=str(Path(sys.executable).parent) + os.pathsep + os.environ.get("PATH", ""))
    outs = {}
    for cmd in guide_commands():
        if cmd.split("#")[0].strip() == PIP_BOARD:
            continue
        r = subprocess.run(["bash", "-c", cmd], cwd=tmp_path, env=env, capture_output=True,
                           text=True, timeout=1800)
        assert r.returncode == 0, (cmd, r.stderr[-2000:])
        outs[cmd.split("#")[0].strip()] = r.stdout + r.stderr
    return outs


def test_the_guide_says_what_it_runs():
    cmds = [c.split("#")[0].strip() for c in guide_commands()]
    assert cmds[0] == PIP_BOARD
    assert [c.split()[:2] for c in cmds[1:]] == [["mpremote", "devs"], ["accelcal", "deploy"],
                                                 ["accelcal", "acquire"], ["accelcal", "pull"],
                                                 ["accelcal", "report"]]
    assert "`accelcal board virtual --chip rp2040`" in GUIDE.read_text()


def check(outs, tmp_path, board):
    """The lines the guide explains: 36 s at the deployed 25 Hz, every sample read or lost
    (the emulated Pico, slower than real time, loses some: 17 of 900 on 28 November)."""
    acquire = next(v for k, v in outs.items() if k.startswith("accelcal acquire"))
    got = re.search(r"acal: 36 s, (\d+) samples, (\d+) lost, \d+ bus errors, \d+ rest logged, "
                    r"\d+ calibrations", acquire)
    assert got and int(got[1]) + int(got[2]) == 900, acquire
    assert (tmp_path / "week" / "summary.json").exists() and (tmp_path / "week.html").exists()
    pull = next(v for k, v in outs.items() if k.startswith("accelcal pull"))
    assert f"(board {board}, modules as ." in pull and "--rate 25" in pull
    assert f"samples {got[1]}, lost {got[2]}, FIFO overruns" in pull


def test_the_guide_on_the_virtual_board(tmp_path):
    test_app.stimulus(tmp_path / "stim.bin", np.random.default_rng(3), n_rest=6)
    with virtual.Running(tmp_path / "flash", tmp_path / "stim.bin") as b:
        outs = run_guide(tmp_path, b.port)
    check(outs, tmp_path, "virtual")


@pytest.mark.slow
def test_the_guide_on_the_emulated_pico(tmp_path):
    """Deploy ~30 s, 36 emulated s of acquiring, pull: a few minutes wall."""
    from accelcal.bridge import rp2040
    from accelcal.errors import InputError
    try:
        rp2040.emulator_index()
    except InputError as e:
        pytest.skip(f"emulated RP2040 not available: {e}")
    test_app.stimulus(tmp_path / "stim.bin", np.random.default_rng(3), n_rest=6)
    with virtual.Running(tmp_path / "pico.bin", tmp_path / "stim.bin", "--chip", "rp2040") as b:
        outs = run_guide(tmp_path, b.port)
    check(outs, tmp_path, "pico")
