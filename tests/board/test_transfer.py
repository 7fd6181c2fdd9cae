"""pull's copy (board/transfer.py): one raw-REPL program sends each file as base64 blocks with
its size and CRC-32; the host checks both.  On the virtual board with the real mpremote
transport: files of 0, 1 and a few blocks and a byte arrive as the board holds them; a missing
file and a copy that does not match are one line each.  Its speed beside `mpremote fs cp` is
`accelcal bench`'s (studies/bench_pull.py), not a test's."""
import binascii
import zlib

import numpy as np
import pytest

import test_app
from accelcal.board import transfer, virtual
from accelcal.errors import InputError


def test_files_arrive_as_the_board_holds_them(tmp_path):
    stim = tmp_path / "stim.bin"
    test_app.stimulus(stim, np.random.default_rng(1), n_rest=2)
    rng = np.random.default_rng(9)
    flash = tmp_path / "flash"
    flash.mkdir()
    sizes = {"empty.bin": 0, "one.bin": 1, "blocks.bin": 3 * transfer.BLOCK + 17}
    for name, n in sizes.items():
        (flash / name).write_bytes(rng.bytes(n))
    seen = []
    with virtual.Running(flash, stim) as b:
        dest = tmp_path / "got"
        dest.mkdir()
        got = transfer.fetch(b.port, list(sizes), dest, lambda done, total: seen.append((done, total)),
                             total=sum(sizes.values()))
        with pytest.raises(InputError, match="nothere.bin"):
            transfer.fetch(b.port, ["one.bin", "nothere.bin"], dest)
    assert got == sizes
    for name in sizes:
        assert (dest / name).read_bytes() == (flash / name).read_bytes()
    assert seen[-1] == (sum(sizes.values()), sum(sizes.values()))
    assert [d for d, _ in seen] == sorted(d for d, _ in seen) and len(seen) >= 4


class FakeSerial:
    """What a board sends, in pieces of 7 bytes (a port's reads split lines anywhere)."""
    def __init__(self, data):
        self.data = data
        self.timeout = None

    def read(self, n):
        out, self.data = self.data[:7], self.data[7:]
        return out


def test_a_copy_that_does_not_match_the_board_is_refused(tmp_path):
    data = bytes(range(256)) * 3
    good = zlib.crc32(data)
    for crc, size, ok in ((good, len(data), True), (good ^ 1, len(data), False),
                          (good, len(data) + 1, False), (-1, len(data), True)):
        sent = (f"ACAL_FILE {size} f.bin\r\n".encode() + binascii.b2a_base64(data[:500])
                + binascii.b2a_base64(data[500:]) + f"ACAL_END {crc}\r\n".encode() + b"\x04\x04>")
        sizes = {}
        if ok:
            assert transfer._receive(FakeSerial(sent), tmp_path, sizes, lambda *a: None, None) == ""
            assert (tmp_path / "f.bin").read_bytes() == data and sizes == {"f.bin": len(data)}
        else:
            with pytest.raises(InputError, match="f.bin: the copy differs from the board's"):
                transfer._receive(FakeSerial(sent), tmp_path, sizes, lambda *a: None, None)
    # the board's error (after the first EOF) is returned for the caller's one line
    err = transfer._receive(FakeSerial(b"\x04Traceback...\r\nOSError: [Errno 2] ENOENT\r\n\x04>"),
                            tmp_path, {}, lambda *a: None, None)
    assert err.strip().splitlines()[-1] == "OSError: [Errno 2] ENOENT"
