"""`accelcal bench`: pulling a board's file, `mpremote fs cp` beside `accelcal pull`'s copy
(board/transfer.py), the same file, each a process of its own started from nothing (connect,
copy, exit), on the virtual board (the MicroPython unix port on a pty) and, with --runtime
rp2040, the emulated Pico (its USB serial on a pty, its littlefs flash)."""
from __future__ import annotations

import subprocess
import sys
import tempfile
import time
from pathlib import Path

# The file the board writes for the bench: NBLOCKS blocks of 1 kB, bytes that are not text.
MAKE_FILE = """b = bytearray(1024)
for i in range(1024):
    b[i] = (i * 7919 + 13) & 255
f = open('bench_pull.bin', 'wb')
for k in range({n}):
    b[0] = k & 255
    b[1] = k >> 8
    f.write(b)
f.close()
"""
FETCH = ("import sys; from pathlib import Path; from accelcal.board import transfer; "
         "transfer.fetch(sys.argv[1], ['bench_pull.bin'], Path(sys.argv[2]))")


def _timed(cmd: list[str]) -> float:
    t0 = time.monotonic()
    subprocess.run(cmd, check=True, capture_output=True, timeout=3600)
    return time.monotonic() - t0


def side_by_side(port: str, kb: int, tmp: Path) -> dict:
    """Seconds for `mpremote fs cp` and for accelcal's copy of the same kb-kB file, both
    checked byte for byte against what the board wrote."""
    mp = [sys.executable, "-m", "mpremote", "connect", port]
    subprocess.run([*mp, "exec", MAKE_FILE.format(n=kb)], check=True, capture_output=True,
                   timeout=600)
    a, b = tmp / "mpremote", tmp / "accelcal"
    a.mkdir()
    b.mkdir()
    t_mp = _timed([*mp, "fs", "cp", ":bench_pull.bin", str(a / "bench_pull.bin")])
    t_ac = _timed([sys.executable, "-c", FETCH, port, str(b)])
    data = (a / "bench_pull.bin").read_bytes()
    if len(data) != kb * 1024 or data != (b / "bench_pull.bin").read_bytes():
        raise RuntimeError("the two copies of bench_pull.bin differ")
    subprocess.run([*mp, "exec", "import os; os.remove('bench_pull.bin')"], capture_output=True,
                   timeout=600)
    return {"mpremote_s": t_mp, "accelcal_s": t_ac, "kB": kb}


def measure(emulated: bool = False, kb_virtual: int = 512, kb_emulated: int = 128) -> dict:
    """The figures `accelcal bench` prints: pull_<board>_{kB,mpremote_s,accelcal_s,speedup}."""
    from accelcal.board import virtual
    from accelcal.simulate import wearer
    out = {}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        stim = tmp / "stim.bin"
        wearer.simulate_wrist(tmp / "stim.csv", 0.001, 10, 1, stimulus=stim)
        boards = [("virtual", tmp / "flash", (), kb_virtual)]
        if emulated:
            boards.append(("rp2040_emulated", tmp / "pico.bin", ("--chip", "rp2040"), kb_emulated))
        for name, flash, extra, kb in boards:
            with virtual.Running(flash, stim, *extra) as board:
                d = tmp / name
                d.mkdir()
                r = side_by_side(board.port, kb, d)
            out[f"pull_{name}_kB"] = r["kB"]
            out[f"pull_{name}_mpremote_s"] = r["mpremote_s"]
            out[f"pull_{name}_accelcal_s"] = r["accelcal_s"]
            out[f"pull_{name}_speedup"] = r["mpremote_s"] / r["accelcal_s"]
    return out
