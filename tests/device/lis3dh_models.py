"""The two LIS3DH models driven by one list of register operations ([t_us, "w", reg, [bytes]] or
[t_us, "r", reg, n]; or [t_us, "s", 0, [bytes]], one SPI transaction): the Python one the virtual board runs (simulate/chip/vlis3dh.py) and the
Node one on the emulated Pico's I2C0 (bridge/scripts/lis3dh.mjs).  test_lis3dh_conformance.py holds
each to the datasheet, test_pico_lis3dh.py holds them to each other."""
import json
import subprocess
import sys

from accelcal.locations import CHIP_DIR, script

sys.path.insert(0, str(CHIP_DIR))
from vclock import Clock  # noqa: E402
from vlis3dh import SimLIS3DH, Stimulus  # noqa: E402


def python_model(stim, ops) -> dict:
    """{"reads": each read's bytes, "dropped": the sets the FIFO overwrote} from the Python chip
    on the stimulus file stim."""
    clock = Clock()
    chip = SimLIS3DH(Stimulus(str(stim)), clock)
    reads = []
    for t, op, reg, arg in ops:
        clock.set_us(t)
        if op == "w":
            chip.write(reg, bytes(arg), 0, len(arg))
        elif op == "s":       # one SPI transaction: CS low, the bytes, CS high
            chip.spi_select(True)
            reads.append([chip.spi_byte(b) for b in arg])
            chip.spi_select(False)
        else:
            buf = bytearray(arg)
            chip.read(reg, buf, 0, arg)
            reads.append(list(buf))
    return {"reads": reads, "dropped": chip.dropped}


def js_model(stim, ops, folder, timeout=120) -> dict:
    """The same from the Node chip (its operations written to a file in folder)."""
    f = folder / f"ops{len(list(folder.iterdir()))}.json"
    f.write_text(json.dumps(ops))
    p = subprocess.run(["node", script("lis3dh.mjs"), "--ops", str(f), "--stimulus", str(stim)],
                       capture_output=True, text=True, timeout=timeout)
    assert p.returncode == 0, p.stderr
    return json.loads(p.stdout)
