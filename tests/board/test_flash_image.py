"""`board virtual --chip rp2040 --flash FILE` takes FILE for the emulated Pico's flash image by
its content, not its size (board/emulated.py check_flash_image): a user's 2 MiB CSV was
overwritten with an image when only the size was checked.  An image is recognised as the RP2040
boot ROM recognises one: the 256-byte second stage whose CRC-32/MPEG-2 is its last 4 bytes
(RP2040 datasheet 2.8.1.3.1), then the firmware's vector table; the firmware UF2 in firmware/
(MicroPython's, its licence note beside it) gives real ones."""
import struct

import numpy as np
import pytest

from accelcal.board.emulated import check_flash_image, looks_like_flash_image
from accelcal.bridge.rp2040 import FLASH_SIZE
from accelcal.errors import InputError
from conftest import ROOT, run_main


def uf2_flash(uf2) -> bytes:
    """A flash image as the emulated chip saves one: the UF2's blocks at their addresses."""
    img = bytearray(b"\xff" * FLASH_SIZE)
    data = uf2.read_bytes()
    for off in range(0, len(data), 512):
        _, _, _, addr, size = struct.unpack("<IIIII", data[off:off + 20])
        if 0x10000000 <= addr < 0x10000000 + FLASH_SIZE:
            img[addr - 0x10000000:addr - 0x10000000 + size] = data[off + 32:off + 32 + size]
    return bytes(img)


def test_a_2_mib_csv_is_never_taken_for_an_image(tmp_path, capsys):
    csv = tmp_path / "mine.csv"
    row = b"12345.678,0.0123,-0.9876,0.0456,24.5\n"
    body = b"t,x,y,z,temp\n" + row * (FLASH_SIZE // len(row))
    csv.write_bytes(body + b"0" * (FLASH_SIZE - len(body) - 1) + b"\n")
    assert csv.stat().st_size == FLASH_SIZE
    before = csv.read_bytes()
    code, _, err = run_main(capsys, ["board", "virtual", "--chip", "rp2040", "--flash", csv,
                                     "--days", "0.01"])
    assert code == 2 and len(err.splitlines()) == 1, err
    assert "not an emulated Pico's flash image" in err and "boot" in err, err
    assert csv.read_bytes() == before


@pytest.mark.parametrize("uf2", sorted((ROOT / "firmware").glob("*/*.uf2")), ids=lambda p: p.parent.name)
def test_a_firmware_image_is_recognised_and_a_damaged_one_is_not(uf2, tmp_path):
    image = uf2_flash(uf2)
    assert looks_like_flash_image(image[:264]) is None
    f = tmp_path / "pico.bin"
    f.write_bytes(image)
    assert check_flash_image(f) == f.resolve() or check_flash_image(f) == f
    for where in (0, 100, 252, 257, 263):       # the boot stage, its CRC, the vector table
        bad = bytearray(image)
        bad[where] ^= 0x80 if where != 263 else 0x10
        f.write_bytes(bytes(bad))
        with pytest.raises(InputError, match="not an emulated Pico's flash image"):
            check_flash_image(f)
    f.write_bytes(np.random.default_rng(1).bytes(FLASH_SIZE))
    with pytest.raises(InputError, match="boot ROM's CRC"):
        check_flash_image(f)
    f.write_bytes(image[:-1])
    with pytest.raises(InputError, match="bytes, an image has"):
        check_flash_image(f)
