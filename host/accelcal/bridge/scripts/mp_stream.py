# The device pipeline on a board's REPL: the line protocol of mp_runner.py arrives on sys.stdin
# (its length in bytes on a first line, then the lines) and the records go back on stdout.  Bytes
# are read in blocks and split here: a line at a time from a USB CDC costs ~0.2 ms on an RP2040.
import sys

from mp_runner import print_record, run


def lines(stream, total, block=1024):
    buf = bytearray(block)
    view = memoryview(buf)
    rest = b""
    left = total
    while left > 0:
        n = stream.readinto(view[:min(block, left)])
        left -= n
        parts = (rest + bytes(view[:n])).split(b"\n")
        rest = parts.pop()
        for p in parts:
            yield p.decode()
    if rest:
        yield rest.decode()


def main():
    # MicroPython: the protocol is text, but a stray 0x03 must not interrupt it.  CircuitPython
    # has no kbd_intr (nor sys.stdin.buffer: its sys.stdin reads bytes into a buffer itself).
    try:
        from micropython import kbd_intr
    except ImportError:
        kbd_intr = None
    if kbd_intr is not None:
        kbd_intr(-1)
    try:
        total = int(sys.stdin.readline())
        run(lines(getattr(sys.stdin, "buffer", sys.stdin), total), print_record)
    finally:
        if kbd_intr is not None:
            kbd_intr(3)
