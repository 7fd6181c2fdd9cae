"""Makes the old-log fixtures beside it: one log.bin per record layout the board app ever wrote,
written by the log.py of that time (COMMIT's device/acal, `git archive`d into a scratch folder
and imported under CPython: its own Log class and FORMATS), so the bytes are what a board of that time wrote.  Run from
a checkout that has the history: python tests/data/oldlogs/make_fixtures.py.  The layouts:
docs/boards-and-logs.md "Record layouts"; the test: tests/bridge/test_old_logs.py.

Each log: BOOT (its layout's fields: 50 Hz, 5 s, all axes, 2 g, ...), two REST, a CAL, an
EFFECT (temp_offset at 25 degC: whole degC before b88c2cc, Q2 after) where the layout has it,
COUNTERS, and a DISCOVERY (temp_offset adopted) where it has it."""
import struct
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[2]
# (file, commit whose log.py wrote it, BOOT version the app wrote then)
LAYOUTS = [("boot1a-9562c53.bin", "9562c53", 1), ("boot1b-a3c88e0.bin", "a3c88e0", 1),
           ("boot1-3678e9b.bin", "3678e9b", 1), ("boot2-95d74b3.bin", "95d74b3", 2),
           ("disc1-791069c.bin", "791069c", 2), ("boot3-98e9e41.bin", "98e9e41", 3),
           ("effectq2-b88c2cc.bin", "b88c2cc", 3), ("disc2-4ab10d2.bin", "4ab10d2", 4)]
TEMP_OFFSET = 1


def old_log(commit: str):
    """The board-log module (log.py) as it was at commit, imported from that commit's device
    package (git archive into a scratch folder), with the modules it imports as they were then,
    wherever log.py lived at that commit."""
    import importlib
    import tarfile
    import tempfile
    tmp = Path(tempfile.mkdtemp(prefix=f"acal-{commit}-"))
    tar = subprocess.run(["git", "-C", str(ROOT), "archive", commit, "device/acal"],
                         capture_output=True, check=True).stdout
    import io
    with tarfile.open(fileobj=io.BytesIO(tar)) as t:
        t.extractall(tmp, filter="data")
    for name in [m for m in sys.modules if m == "acal" or m.startswith("acal.")]:
        del sys.modules[name]
    sys.path.insert(0, str(tmp / "device"))
    log_py = sorted((tmp / "device").glob("acal/**/log.py"))[0]
    name = ".".join(log_py.relative_to(tmp / "device").with_suffix("").parts)
    try:
        return importlib.import_module(name)     # loaded whole: the folder can go
    finally:
        sys.path.remove(str(tmp / "device"))
        import shutil
        shutil.rmtree(tmp)


def fields(fmt: str) -> int:
    return len(struct.unpack(fmt, bytes(struct.calcsize(fmt))))


def write(path: Path, commit: str, version: int) -> None:
    lg = old_log(commit)
    f = lg.FORMATS
    has_effect, has_disc = hasattr(lg, "EFFECT"), hasattr(lg, "DISCOVERY")
    path.unlink(missing_ok=True)
    log = lg.Log(str(path))
    model = TEMP_OFFSET if has_effect else 0
    boot = [1 if commit == "9562c53" else 0, version, 50, 5, 0, 3, 2, 1, 2, 8, 6554, 20, 3600,
            20, model, 1, 1 if has_disc else 0]
    log.write(lg.BOOT, *boot[:fields(f[lg.BOOT])])
    log.write(lg.REST, 250, 0, 0, 65536, 24, 4, 1)
    log.write(lg.REST, 500, 65536, 0, 0, 25, 0, 1)
    log.write(lg.CAL, 1000, 1, 0, 5, 18, 1000, 10, *([1 << 24] * 3 + [0] * 3 + [4096, -4096, 0]))
    if has_effect:
        q2 = f[lg.EFFECT][3] == "h"              # "<IBhI3i": Q2 degC; "<IBbI3i": whole degC
        log.write(lg.EFFECT, 1000, TEMP_OFFSET, 100 if q2 else 25, 0, 1677, 0, 0)
    log.write(lg.COUNTERS, 1500, 1500, 0, 0, 0, 0, 2, 2, 0)
    if has_disc:
        disc = [2000, TEMP_OFFSET, TEMP_OFFSET, 5000, 3000, 7, 8]
        if fields(f[lg.DISCOVERY]) == 11:        # version 4: the effect its round added
            disc.append(TEMP_OFFSET)
        log.write(lg.DISCOVERY, *disc, 3355, 0, 0)
    log.close()


if __name__ == "__main__":
    for name, commit, version in LAYOUTS:
        write(HERE / name, commit, version)
        print(name, (HERE / name).stat().st_size, "bytes")
