"""Copying files off a board fast: one program in the raw REPL reads each file in blocks and
prints them as base64 lines, with each file's size and CRC-32; the host reads the port in bulk
(mpremote's transport for entering the raw REPL and sending the program, pyserial's reads for the
rest).  `mpremote fs cp` asks for 256 bytes at a time, each a round trip returning repr() text,
and reads its answer a byte at a time: measured side by side by `accelcal bench` (studies/
bench_pull.py)."""
from __future__ import annotations

import binascii
import time
import zlib
from pathlib import Path

from accelcal.errors import PIP_BOARD, InputError

BLOCK = 8192        # bytes the board reads and sends per line (11 kB of base64): 13x fs cp on the
                    # emulated Pico, 8 kB more heap while pulling (the app is stopped then)

# Board side: MicroPython and CircuitPython alike (sys.stdout.buffer where there is one).
READER = """import sys, binascii
def _send(names, block):
    try:
        w = sys.stdout.buffer.write
    except AttributeError:
        w = lambda b: sys.stdout.write(b.decode())
    crc32 = getattr(binascii, 'crc32', None)
    buf = bytearray(block)
    mv = memoryview(buf)
    for name in names:
        f = open(name, 'rb')
        f.seek(0, 2)
        print('ACAL_FILE', f.tell(), name)
        f.seek(0)
        crc = 0
        while True:
            n = f.readinto(buf)
            if not n:
                break
            if crc32:
                crc = crc32(mv[:n], crc)
            w(binascii.b2a_base64(mv[:n]))
        f.close()
        print('ACAL_END', crc if crc32 else -1)
"""


def transport(port: str):
    """mpremote's serial transport on port, or one line saying how to install it."""
    try:
        from mpremote.transport import TransportError
        from mpremote.transport_serial import SerialTransport
    except ImportError:
        raise InputError(f"mpremote is not installed: {PIP_BOARD}") from None
    try:
        return SerialTransport(port, baudrate=115200), TransportError
    except TransportError as e:
        raise InputError(f"{port}: {e}") from None


def fetch(port: str, names: list[str], dest: Path, progress=lambda done, total: None,
          block: int = BLOCK, total: int | None = None) -> dict[str, int]:
    """Copy the board's files `names` (paths on the board) into dest (same names); each one's
    size and CRC-32 checked against the board's.  progress(bytes so far, total) as the data
    arrives (total: the sum of the sizes, when known beforehand).  Returns {name: size}."""
    t, TransportError = transport(port)
    sizes: dict[str, int] = {}
    try:
        try:
            t.enter_raw_repl(soft_reset=False)
            t.exec_raw_no_follow(READER + f"_send({list(names)!r}, {int(block)})\n")
        except TransportError as e:
            raise InputError(f"{port}: no MicroPython REPL answers there ({e})") from None
        err = _receive(t.serial, dest, sizes, progress, total)
        if err:
            last = err.strip().splitlines()[-1] if err.strip() else "error"
            at = next((n for n in names if n not in sizes), "its files")
            raise InputError(f"{port}: reading {at} on the board failed: {last}")
        missing = [n for n in names if n not in sizes]
        if missing:
            raise InputError(f"{port}: the board did not send {' '.join(missing)}")
    finally:
        try:
            t.exit_raw_repl()
        finally:
            t.close()
    return sizes


def _receive(ser, dest: Path, sizes: dict, progress, total, quiet_s: float = 60.0) -> str:
    """Read the board's answer: base64 lines between ACAL_FILE and ACAL_END, then the raw
    REPL's two EOFs (the second ends the error text, returned).  One line if the board falls
    silent for quiet_s."""
    ser.timeout = 0.05
    pending = bytearray()
    out, name, crc, done, size = None, None, 0, 0, 0
    stage, err = 0, bytearray()      # stage 0: the output; 1: the error text; 2: finished
    last = time.monotonic()
    while stage < 2:
        chunk = ser.read(65536)
        if not chunk:
            if time.monotonic() - last > quiet_s:
                raise InputError(f"the board fell silent for {quiet_s:g} s in the middle of a copy")
            continue
        last = time.monotonic()
        if stage == 1:
            err += chunk
        else:
            pending += chunk
            eof = pending.find(b"\x04")
            if eof >= 0:
                err += pending[eof + 1:]
                del pending[eof:]
                pending += b"\n"
                stage = 1
            lines = pending.split(b"\n")
            pending = bytearray(lines.pop())
            for line in lines:
                line = bytes(line).rstrip(b"\r")
                if line.startswith(b"ACAL_FILE "):
                    _, sz, nm = line.decode().split(" ", 2)
                    name, size, crc = nm, int(sz), 0
                    out = open(dest / name, "wb")
                elif line.startswith(b"ACAL_END "):
                    out.close()
                    got = (dest / name).stat().st_size
                    want_crc = int(line.split()[1])
                    if got != size or (want_crc >= 0 and want_crc != crc):
                        raise InputError(f"{name}: the copy differs from the board's ({got} of "
                                         f"{size} B, CRC-32 {crc:#x}, the board's {want_crc:#x})")
                    sizes[name] = size
                    out = None
                elif out is not None and line:
                    data = binascii.a2b_base64(line)
                    out.write(data)
                    crc = zlib.crc32(data, crc)
                    done += len(data)
                    progress(done, total)
        if stage == 1 and err.count(b"\x04") >= 1:
            err = err[:err.index(b"\x04")]
            stage = 2
    if out is not None:
        out.close()
    return err.decode(errors="replace")
