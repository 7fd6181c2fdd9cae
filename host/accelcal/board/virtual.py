"""The virtual board: the MicroPython unix port on a pseudo-terminal, a folder as its flash, the
simulated LIS3DH (host/accelcal/sim) wired in through boards/virtual.py.

Two pseudo-terminals: the interpreter's console (A) and the port a client opens (B), relayed
byte for byte.  Why not one: the unix port *exits* where a board soft-resets (Ctrl-D), so the
relay plays the board's part: it prints "soft reboot", starts a fresh interpreter on a new A, and
puts it back into the raw REPL if it was there - which is what `mpremote` expects of a board.

The interpreter's path is the flash folder and its lib/ (what `deploy` copies there), then the
simulator's folder (the board's "hardware"); device/ of this checkout is *not* on it, so the
board runs what was deployed."""
from __future__ import annotations

import os
import pty
import select
import signal
import subprocess
import sys
import time
import tty
from pathlib import Path

from accelcal.bridge import runtime
from accelcal.errors import InputError
from accelcal.files.outputs import check_output, check_output_dir, write_text
from accelcal.locations import CHIP_DIR

SIM_DIR = CHIP_DIR


class VirtualBoard:
    def __init__(self, flash: str | Path, stimulus: str | Path, bus_faults: int = 0,
                 heap: str | None = None, speed: int = 0, log=None, bus: str = "i2c"):
        self.flash = Path(flash).resolve()
        self.flash.mkdir(parents=True, exist_ok=True)
        self.stimulus = Path(stimulus).resolve()
        self.bus_faults = bus_faults
        self.heap = heap
        self.speed = speed
        self.bus = bus
        self.log = log or (lambda msg: None)
        self.proc: subprocess.Popen | None = None
        self.master_a = -1
        self.raw = False
        self.boots = 0
        self.client_master, client_slave = pty.openpty()
        tty.setraw(client_slave)
        self.port = os.ttyname(client_slave)
        self._client_slave = client_slave  # kept open: the port survives clients closing it

    def _spawn(self):
        ma, sa = pty.openpty()
        tty.setraw(sa)
        cmd = [runtime.micropython_path()]
        if self.heap:
            cmd += ["-X", f"heapsize={self.heap}"]
        env = dict(os.environ, MICROPYPATH=f".frozen:.:lib:{SIM_DIR}",
                   ACCELCAL_STIMULUS=str(self.stimulus), ACCELCAL_BUS_FAULTS=str(self.bus_faults),
                   ACCELCAL_SPEED=str(self.speed), ACCELCAL_BUS=self.bus)
        self.proc = subprocess.Popen(cmd, stdin=sa, stdout=sa, stderr=sa, cwd=self.flash, env=env,
                                     close_fds=True, start_new_session=True)
        os.close(sa)
        self.master_a = ma
        self.boots += 1

    def _reboot(self):
        """The interpreter exited (Ctrl-D): behave like a board's soft reset."""
        if self.master_a >= 0:
            os.close(self.master_a)
        if self.proc is not None:
            self.proc.wait()
        os.write(self.client_master, b"soft reboot\r\n")
        self._spawn()
        if self.raw:
            os.write(self.master_a, b"\x01")
        self.log(f"soft reboot ({self.boots})")

    def _from_client(self, data: bytes):
        # Follow the REPL mode the client asks for: Ctrl-A raw, Ctrl-B friendly.
        for b in data:
            if b == 1:
                self.raw = True
            elif b == 2:
                self.raw = False
        os.write(self.master_a, data)

    @staticmethod
    def _read(fd) -> bytes:
        """What fd has (b"" at its end: a pty whose other side closed reads EIO)."""
        try:
            return os.read(fd, 65536)
        except OSError:
            return b""

    def serve(self, until=lambda: False):
        """Relay until `until()` is true (or forever)."""
        self._spawn()
        while not until():
            r, _, _ = select.select([self.master_a, self.client_master], [], [], 0.2)
            if self.master_a in r:
                data = self._read(self.master_a)
                if not data:
                    self._reboot()
                    continue
                os.write(self.client_master, data)
            if self.client_master in r:
                data = self._read(self.client_master)
                if data:
                    self._from_client(data)
            if self.proc is not None and self.proc.poll() is not None and self.master_a not in r:
                # Exited with output still queued: pass it on, then reboot.
                while select.select([self.master_a], [], [], 0.05)[0]:
                    data = self._read(self.master_a)
                    if not data:
                        break
                    os.write(self.client_master, data)
                self._reboot()

    def stop(self):
        if self.proc is not None and self.proc.poll() is None:
            os.killpg(self.proc.pid, signal.SIGTERM)
            try:
                self.proc.wait(5)
            except subprocess.TimeoutExpired:
                os.killpg(self.proc.pid, signal.SIGKILL)


def start_virtual(*, flash_dir: str | None, stimulus: str | None, days: float, rate: int,
                  seed: int, bus_faults: int, heap: str | None, speed: int, link: str | None,
                  port_file: str | None, chip: str = "unix", bus: str = "i2c",
                  say=lambda m: None):
    """`accelcal board virtual` up to serving: the outputs checked, a stimulus simulated if none
    is given, the board started, its link and port file made.  chip: unix (the unix port, a
    folder as its flash) or rp2040 (the emulated Pico, a flash image file).  bus: "i2c" or "spi",
    where the LIS3DH is wired (rp2040: I2C0 or SPI0 only, as boards/pico.py; unix: the chip
    answers on both, and this is the board file's BUS).  say(message): what
    it does and the board's log.  Returns (board, flash); serve_until() relays."""
    from accelcal.simulate import wearer
    if chip == "rp2040":
        from accelcal.board import emulated
        if heap or speed:
            raise InputError("--heap and --speed are the unix port's: the emulated Pico has its "
                             "own heap and runs on its emulated clock")
        flash = emulated.check_flash_image(flash_dir or "vboard-pico.bin", stimulus)
    else:
        flash = check_output_dir(flash_dir or "vboard-flash", [stimulus], "--flash")
    if link:
        # never replaces a file it did not make: the link must be new
        if Path(link).is_symlink() or Path(link).exists():
            raise InputError(f"{link}: exists; --link makes a new symlink (remove it or "
                             "choose another name)")
        check_output(link, [stimulus], False, "--link")
    if port_file:
        check_output(port_file, [stimulus], True, "--port-file")
    stim = Path(stimulus) if stimulus else \
        flash.parent / ((flash.stem if chip == "rp2040" else flash.name) + "-stimulus.bin")
    if not stimulus:
        rec = stim.with_suffix(".csv")
        say(f"simulating {days:g} day(s) of wrist wear at {rate} Hz (seed {seed}) into {stim}")
        wearer.simulate_wrist(rec, days, rate, seed, stimulus=stim)
    log = lambda m: say(f"virtual board: {m}")  # noqa: E731
    if bus not in ("i2c", "spi"):
        raise InputError(f"--bus {bus}: i2c or spi")
    board = (emulated.EmulatedBoard(flash, stim, bus_faults, seed, log=log,
                                    spi=emulated.SPI_PICO if bus == "spi" else None)
             if chip == "rp2040" else VirtualBoard(flash, stim, bus_faults, heap, speed, log=log,
                                                   bus=bus))
    if link:
        Path(link).symlink_to(board.port)
    if port_file:
        write_text(port_file, board.port + "\n")
    return board, flash


def serve_until(board, link: str | None, until) -> None:
    """Relay until until() is true or Ctrl-C; then stop the board and remove the link this run
    made."""
    try:
        board.serve(until=until)
    except KeyboardInterrupt:
        pass
    finally:
        board.stop()
        made = Path(link) if link else None
        if made is not None and made.is_symlink() and os.readlink(made) == board.port:
            made.unlink()   # ours: the symlink this run made, still pointing at its port


class Running:
    """A virtual board served by a child `accelcal board virtual` process (tests, demo)."""

    def __init__(self, flash: Path, stimulus: Path, *extra: str):
        port_file = Path(flash).parent / (Path(flash).name + ".port")
        port_file.unlink(missing_ok=True)
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "accelcal.cli", "board", "virtual", "--flash", str(flash),
             "--stimulus", str(stimulus), "--port-file", str(port_file), *extra],
            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        deadline = time.monotonic() + 30
        while not port_file.exists() or not port_file.read_text().endswith("\n"):
            if self.proc.poll() is not None or time.monotonic() > deadline:
                raise RuntimeError("virtual board did not start: " + (self.proc.stderr.read() or ""))
            time.sleep(0.05)
        self.port = port_file.read_text().strip()

    def close(self):
        self.proc.terminate()
        try:
            self.proc.wait(10)
        except subprocess.TimeoutExpired:
            self.proc.kill()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
