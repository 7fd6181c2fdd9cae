"""The emulated Pico: MicroPython's RPI_PICO firmware on rp2040js (bridge/rp2040.py) with the
simulated LIS3DH on its I2C0 (bridge/scripts/lis3dh.mjs), fed by the stimulus files the virtual
board reads.  Two ways in: run scripts on it (run; board/powercut.py cuts its power), and serve
its USB CDC on a pseudo-terminal that mpremote, `deploy`, `acquire` and `pull` use as a Pico's
port (EmulatedBoard).  Its flash is a 2 MB image file: littlefs as the firmware wrote it."""
from __future__ import annotations

import json
import os
import pty
import select
import signal
import subprocess
import tempfile
import tty
from dataclasses import dataclass, field
from pathlib import Path

from accelcal.bridge import rp2040
from accelcal.errors import InputError, InterpreterFailed
from accelcal.files.outputs import check_output
from accelcal.locations import script

DRIVER = script("pico.mjs")
# the LIS3DH on SPI: BUS,SCK,MOSI,MISO,CS as boards/pico.py and boards/feather_rp2040.py wire it
SPI_PICO = "0,18,19,16,17"
SPI_FEATHER = "0,18,19,20,7"


def node_args(stimulus=None, bus_faults=0, seed=1, flash_in=None, flash_out=None,
              fw: rp2040.Firmware = rp2040.MICROPYTHON, i2c="0,4,5", spi=None) -> list[str]:
    """pico.mjs's command line up to its mode: the firmware, the chip (on I2C, or on SPI when
    spi is "BUS,SCK,MOSI,MISO,CS"), its flash."""
    uf2, rom = rp2040.firmware_files(fw)
    args = ["node", DRIVER, "--rp2040js", rp2040.emulator_index(), "--firmware", str(uf2),
            "--bootrom", str(rom), "--bus-faults", str(bus_faults), "--seed", str(seed),
            "--flavour", fw.flavour, "--i2c", i2c]
    if spi:
        args += ["--spi", spi]
    if stimulus:
        args += ["--stimulus", str(stimulus)]
    if flash_in:
        args += ["--flash-in", str(flash_in)]
    if flash_out:
        args += ["--flash-out", str(flash_out)]
    return args


@dataclass
class PicoRun:
    out: str                                   # what the scripts printed
    files: dict = field(default_factory=dict)  # remote name -> bytes, of those asked for
    report: dict = field(default_factory=dict)  # the chip model's ground truth, cycles


def run(scripts: list[str], *, stimulus=None, puts: dict | None = None, gets=(), bus_faults=0,
        seed=1, flash_in=None, flash_out=None, timeout: float = 1800,
        fw: rp2040.Firmware = rp2040.MICROPYTHON, i2c: str = "0,4,5", spi: str | None = None) -> PicoRun:
    """Boot (from flash_in, default: the image with the device package installed), put files
    (remote name -> bytes), run each script, fetch `gets` (those that exist).  fw: the firmware
    (the Feather's CircuitPython: i2c="1,2,3", its board.I2C()); spi: the chip on SPI instead
    (SPI_PICO, SPI_FEATHER)."""
    flash_in = flash_in or rp2040.flash_image(fw)
    with tempfile.TemporaryDirectory() as tmp:
        t = Path(tmp)
        args = node_args(stimulus, bus_faults, seed, flash_in, flash_out, fw, i2c, spi) + ["run"]
        for i, (remote, data) in enumerate((puts or {}).items()):
            (t / f"put{i}").write_bytes(data)
            args += ["--put", f"{t / f'put{i}'}={remote}"]
        for i, code in enumerate(scripts):
            (t / f"s{i}.py").write_text(code)
            args += ["--exec", str(t / f"s{i}.py")]
        for i, remote in enumerate(gets):
            args += ["--get", f"{remote}={t / f'get{i}'}"]
        args += ["--report", str(t / "report.json")]
        p = subprocess.run(args, capture_output=True, timeout=timeout, encoding="latin1")
        if p.returncode != 0:
            raise InterpreterFailed(fw.name, p)
        files = {r: (t / f"get{i}").read_bytes() for i, r in enumerate(gets) if (t / f"get{i}").exists()}
        return PicoRun(p.stdout, files, json.loads((t / "report.json").read_text()))


def _crc32_mpeg2(data: bytes) -> int:
    """CRC-32/MPEG-2 (polynomial 0x04C11DB7, not reflected, init 0xFFFFFFFF): the RP2040 boot
    ROM's check of the second-stage bootloader (RP2040 datasheet 2.8.1.3.1)."""
    crc = 0xFFFFFFFF
    for b in data:
        crc ^= b << 24
        for _ in range(8):
            crc = ((crc << 1) ^ 0x04C11DB7) if crc & 0x80000000 else crc << 1
            crc &= 0xFFFFFFFF
    return crc


def looks_like_flash_image(head: bytes) -> str | None:
    """None when `head` (a file's first 264 bytes) begins as an RP2040 flash image does: a
    256-byte boot2 whose last 4 bytes are the CRC the boot ROM checks over the first 252, then
    the firmware's vector table (the initial stack pointer in SRAM, the reset handler a Thumb
    address in flash); else what is missing."""
    if len(head) < 264:
        return "shorter than a boot stage and a vector table"
    if _crc32_mpeg2(head[:252]) != int.from_bytes(head[252:256], "little"):
        return "no RP2040 boot stage: its first 256 bytes fail the boot ROM's CRC"
    sp, reset = int.from_bytes(head[256:260], "little"), int.from_bytes(head[260:264], "little")
    if not (0x20000000 <= sp <= 0x20042000 and 0x10000000 <= reset < 0x11000000 and reset & 1):
        return "no firmware vector table after the boot stage"
    return None


def check_flash_image(path, stimulus=None) -> Path:
    """The emulated Pico's flash: a new file, or one this board saved before, recognised by its
    content (2 MB exactly, beginning with the RP2040's boot stage and a vector table), never by
    its size alone: no other file is ever taken for a flash image and overwritten (a user's
    2 MiB CSV was, when only the size was checked)."""
    p = check_output(path, [stimulus], True, "--flash")
    if p.exists():
        size = p.stat().st_size
        with open(p, "rb") as fh:
            why = looks_like_flash_image(fh.read(264))
        if size != rp2040.FLASH_SIZE or why:
            raise InputError(f"{path}: not an emulated Pico's flash image ("
                             f"{why if size == rp2040.FLASH_SIZE else f'{size} bytes, an image has {rp2040.FLASH_SIZE}'}"
                             "); give a new file name")
    return p


class EmulatedBoard:
    """The emulated Pico's USB CDC on a pseudo-terminal: a Node process owns the chip and speaks
    the CDC on its stdin/stdout; this relays it to the pty's master.  Unlike the unix port, the
    firmware soft-resets by itself (Ctrl-D), so the relay is a plain byte pipe."""

    def __init__(self, flash: str | Path, stimulus: str | Path, bus_faults: int = 0, seed: int = 1,
                 log=None, spi: str | None = None):
        self.flash = Path(flash).resolve()
        self.stimulus = Path(stimulus).resolve()
        self.log = log or (lambda msg: None)
        if not self.flash.exists():    # a new board: the firmware formats its littlefs at boot
            self.log(f"new flash image {self.flash}")
        # spi: the LIS3DH on SPI (SPI_PICO) instead of I2C0
        self.args = node_args(self.stimulus, bus_faults, seed,
                               self.flash if self.flash.exists() else None, self.flash,
                               spi=spi) + ["serve"]
        self.client_master, client_slave = pty.openpty()
        tty.setraw(client_slave)
        self.port = os.ttyname(client_slave)
        self._client_slave = client_slave   # kept open: the port survives clients closing it
        self.proc: subprocess.Popen | None = None

    def serve(self, until=lambda: False):
        self.proc = subprocess.Popen(self.args, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                     stderr=None, start_new_session=True)
        out = self.proc.stdout.fileno()
        while not until():
            r, _, _ = select.select([out, self.client_master], [], [], 0.2)
            if out in r:
                data = os.read(out, 65536)
                if not data:
                    raise InputError(f"the emulated Pico stopped (exit {self.proc.wait()})")
                os.write(self.client_master, data)
            if self.client_master in r:
                try:
                    data = os.read(self.client_master, 65536)
                except OSError:
                    data = b""
                if data:
                    self.proc.stdin.write(data)
                    self.proc.stdin.flush()

    def stop(self):
        """Close the chip's stdin: it saves its flash image and exits."""
        if self.proc is not None and self.proc.poll() is None:
            try:
                self.proc.stdin.close()
                self.proc.wait(60)
            except (subprocess.TimeoutExpired, BrokenPipeError):
                os.killpg(self.proc.pid, signal.SIGKILL)
