"""Nothing lost with a four-effect model adopted and applied: the app as `deploy` starts it (FIFO
past its watermark, the wear profile) with model base+temp_offset+temp_scale+drift+nonlinear, on
the emulated Pico (MicroPython) and the emulated Feather RP2040 (CircuitPython).  The model reaches
the board the way a board that adopted it holds it: its calibration saved in the two-slot store
(cal_a.bin, log.CalStore.save, as Processor._take saves a fit), which the app resumes at boot
and applies to every block (Processor.feed -> Calibration.apply_samples -> on_samples).  The
stimulus's temperature keeps changing (whole-degree steps across blocks), so the temperature
terms change from block to block; the drift term is non-zero from the start (the stored
reference time lies 40 units back) and, in the hour, its time moves on 56 units.

The board keeps a Fletcher checksum of every calibrated value it produced while its capture
(raw samples and each block's temperature) still had room, and the count of all of them.  The
host feeds the pulled capture to the numpy twin (accelcal.bridge.twin.apply_params) with the
stored parameters and each block's dT and dt (and, should the board fit again as a resumed board
does once its bins are ready, with each usable fit it logged, from the index it took it at):
its checksum must be the board's.  The short runs
capture everything; an hour's capture holds its first 600 kB (all of it at 10 and 25 Hz, the
first ~4 min at 400 Hz), and the rest is counted: every sample read was applied.  The checksum
tells a dt 30 units (32 min) off or a dT a quarter degree off (both tried).  A short run makes
the board fit again mid-run (test_the_twin_follows_a_refit_of_the_board) and checks the twin
across it."""
import numpy as np
import pytest

from accelcal.simulate.stimulus import write_stimulus
from conftest import ROOT, emulated_chip, relative

MODEL = "base+temp_offset+temp_scale+drift+nonlinear"
STIM_HZ = 50
REF_TIME_BACK = 40          # the stored reference time, in 64 s units before the boot
CAPTURE_BYTES = 600_000
BOARDS = {"pico": ("pico.py", "MICROPYTHON", "0,4,5"),
          "feather": ("feather_rp2040.py", "CIRCUITPYTHON", "1,2,3")}
RATES = [10, 25, 50, 100, 200, 400]
APP = """import acal.logger.app, acal_board
app = acal.logger.app.App(acal_board, rate_hz={rate}, profile=1, model='{model}', capture_bytes={cap}{settings})
{extra}
st = [0, 1, 0, 0]   # values applied, Fletcher a, b over those the capture kept
proc = app.proc
def check(buf, n):
    m = 3 * n
    st[0] += m
    if proc.capture_full:
        return
    a = st[1]
    b = st[2]
    for i in range(m):
        a = (a + (buf[i] & 0xffff)) % 65521
        b = (b + a) % 65521
    st[1] = a
    st[2] = b
    st[3] += m
proc.on_samples = check
app.run({seconds})
print('ACAL_DONE', app.samples, app.lost, app.fifo_overruns, app.bus_errors, proc.calibrations,
      st[0], st[1], st[2], st[3])
"""


def four_effect_store(tmp_path, rate):
    """cal_a.bin as a board that adopted the four-effect model holds it (its CAL and EFFECT
    records under one CRC), with parameters inside the bounds; and the parameters (Q24)."""
    from acal.core import effects
    from acal.logger import log
    one = 1 << 24
    base = [int(v * one) for v in (1.02, 0.98, 1.01, 0.01, -0.01, 0.005, 0.03, -0.02, 0.04)]
    kinds = effects.parse_model(MODEL)
    fx = []
    for j, k in enumerate(kinds):
        b = effects.BOUNDS[k]
        fx.append([b // 3, -b // 5, b // 4 - j * (b // 17)])
    ref_temp = 0   # Q2 degC, relative to the chip's reference (the boards give no TEMP_REF_C)
    # saved REF_TIME_BACK time units into its session, at time 0: resumed, the reference lies
    # that far back (Processor._resume)
    saved_at = REF_TIME_BACK * effects.DT_UNIT_S * rate
    values = (saved_at, 3, 0, 40, 120, 1 << 20, 1 << 12) + tuple(base)
    recs = [(saved_at, k, ref_temp, 0, *fx[j]) for j, k in enumerate(kinds)]
    a, b = tmp_path / "cal_a.bin", tmp_path / "cal_b.bin"
    log.CalStore(str(a), str(b)).save(values, recs)
    p = base + [v for e in fx for v in e]
    return (a if a.exists() else b).read_bytes(), p, kinds, ref_temp


def stimulus(path, seconds):
    """Six still poses in turn (10 s each) and a temperature swinging 15..45 degC (a triangle of
    `period` s: whole-degree steps a few blocks apart), for `seconds` and a little more."""
    n = (seconds + 30) * STIM_HZ
    t = np.arange(n) / STIM_HZ
    poses = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1.0]])
    xyz = poses[(t // 10).astype(int) % 6] * 0.98 + 0.01
    period = 8.0 if seconds < 60 else 1200.0
    ph = (t % period) / period
    temp = 15 + 30 * np.where(ph < 0.5, 2 * ph, 2 - 2 * ph)
    write_stimulus(path, STIM_HZ, xyz, temp)


def refit_stimulus(path, seconds):
    """Twelve still poses in turn (the six faces and six edges, 5 s each) with 2 mg of noise (the
    wear profile takes no exactly constant segment as still) and a temperature swinging
    15..45 degC (an 80 s triangle): rest points enough for a fit of the four-effect model
    within ~90 s, their temperatures spread."""
    n = (seconds + 30) * STIM_HZ
    t = np.arange(n) / STIM_HZ
    faces = np.vstack([np.eye(3), -np.eye(3)])
    edges = np.array([[1, 1, 0], [-1, 0, 1], [0, 1, -1], [1, 0, -1], [-1, -1, 0], [0, -1, 1],
                      [1, 0, 1], [-1, 1, 0], [0, -1, -1], [1, -1, 0], [-1, 0, -1], [0, 1, 1.0]])
    poses = np.vstack([faces, edges / np.sqrt(2)])
    noise = np.random.default_rng(7).normal(scale=0.002, size=(n, 3))
    xyz = poses[(t // 5).astype(int) % 12] * 0.98 + 0.01 + noise
    temp = 15 + 30 * np.abs((t / 40) % 2 - 1)
    write_stimulus(path, STIM_HZ, xyz, temp)


def fletcher(values):
    a, b = 1, 0
    for v in (np.asarray(values, dtype=np.int64).ravel() & 0xffff).tolist():
        a = (a + v) % 65521
        b = (b + a) % 65521
    return a, b


def twin_apply(pull, p, kinds, ref_temp, q, temp, index, block_start, rate, shift=0):
    """The twin's apply of what the board applied: the stored calibration from the boot, each
    usable fit the board logged (CAL and its EFFECT records) from the index it was taken at
    (plus shift: a wrong index, which the checksum must tell), each sample with its block's dT
    and dt from the calibration's references.  Also the count of those fits.  A block's dt is
    its first sample's (Processor.feed sets the conditions once a block): where a 64 s unit
    ends inside a block, its later samples keep the earlier unit."""
    from accelcal.bridge import twin
    from accelcal.bridge.boardlog import FIELDS, decode
    from acal.core import effects, fixed
    from acal.core.status import usable
    from acal.logger import log
    lg = decode(pull / "log.bin")
    cals = [dict(zip(FIELDS[log.CAL], v)) for v in lg.of(log.CAL)]
    fx = [dict(zip(FIELDS[log.EFFECT], v)) for v in lg.of(log.EFFECT)]
    time = block_start // (effects.DT_UNIT_S * rate)
    segments = [(0, p, ref_temp, -REF_TIME_BACK)]
    for c in cals:
        if usable(c["status"]):
            mine = [e for e in fx if e["index"] == c["index"]]
            assert [e["effect"] for e in mine] == list(kinds)
            new = [c[n] for n in FIELDS[log.CAL][7:]] + [e[k] for e in mine for k in ("p0", "p1", "p2")]
            segments.append((c["index"] + shift, new, mine[0]["ref_temp"], mine[0]["ref_time"]))
    out = np.empty_like(q)
    for j, (start, params, rt, rtime) in enumerate(segments):
        end = segments[j + 1][0] if j + 1 < len(segments) else 1 << 62
        m = (index >= start) & (index < end)
        out[m] = twin.apply_params(params, q[m], kinds,
                                   relative(int(m.sum()), (temp[m] << fixed.TEMP_Q) - rt,
                                            time[m] - rtime), 2)
    return out, len(segments) - 1


def run_four_effects(tmp_path, which, rate, seconds, refit=False):
    from accelcal.board import emulated
    from accelcal.bridge import rp2040
    from accelcal.bridge.boardlog import read_capture
    board_file, fw_name, i2c = BOARDS[which]
    fw = getattr(rp2040, fw_name)
    emulated_chip(fw)
    store, p, kinds, ref_temp = four_effect_store(tmp_path, rate)
    stim = tmp_path / "stim.bin"
    (refit_stimulus if refit else stimulus)(stim, seconds)
    r = emulated.run([APP.format(seconds=seconds, rate=rate, model=MODEL, cap=CAPTURE_BYTES,
                                 settings=REFIT_SETTINGS if refit else "",
                                 extra=EARLY_BINS if refit else "")],
                     stimulus=stim, fw=fw, i2c=i2c, gets=("log.bin", "capture.bin"),
                     puts={"acal_board.py": (ROOT / "boards" / board_file).read_bytes(),
                           "cal_a.bin": store},
                     timeout=max(1800, 6 * seconds))
    assert "ACAL_DONE" in r.out, r.out[-2000:]
    (samples, lost, overruns, bus_errors, cals, applied, fa, fb,
     checked) = map(int, r.out.split("ACAL_DONE")[1].split()[:9])
    chip = r.report["lis3dh"]
    pull = tmp_path / "pull"
    pull.mkdir()
    for name, data in r.files.items():
        (pull / name).write_bytes(data)
    cap = read_capture(pull)
    blocks = [b for b in cap.blocks if b[0] == "samples"]
    q = np.concatenate([b[3] for b in blocks])[:checked // 3]
    temp = np.concatenate([np.full(len(b[3]), b[2]) for b in blocks])[:len(q)]
    index = np.concatenate([b[1] + np.arange(len(b[3])) for b in blocks])[:len(q)]
    block_start = np.concatenate([np.full(len(b[3]), b[1]) for b in blocks])[:len(q)]
    host, refits = twin_apply(pull, p, kinds, ref_temp, q, temp, index, block_start, rate)
    print(f"\n{which} {rate} Hz four effects, {seconds} emulated s: {samples} samples, {lost} lost, "
          f"{overruns} overruns; the chip converted {chip['converted']}, dropped "
          f"{chip['dropped']}; {applied // 3} applied, the first {checked // 3} checked against "
          f"the twin ({len(set(temp.tolist()))} temperatures, {refits} fits of the board's own)")
    assert (lost, overruns, chip["dropped"], bus_errors) == (0, 0, 0, 0)
    assert seconds * rate <= samples <= chip["converted"] <= samples + 32
    assert cals == 3 + refits            # the stored calibration resumed, then the board's fits
    assert applied == 3 * samples        # every sample read was applied
    assert checked == 3 * len(q) and len(q) >= min(samples, 40_000)
    assert len(set(temp.tolist())) >= 5  # the temperature terms changed across blocks
    assert (fa, fb) == fletcher(host)
    return refits, (fa, fb), (pull, p, kinds, ref_temp, q, temp, index, block_start, rate)


@pytest.mark.parametrize("which", ["pico", "feather"])
def test_a_four_effect_model_applied_loses_nothing_at_400_hz(tmp_path, which):
    run_four_effects(tmp_path, which, 400, 5 if which == "pico" else 2)


# A refit within the run: the bins' least time spread for the drift term, 12 h
# (fixed.DIFFERS[C_TIME]), made one 64 s unit, so they are ready as a resumed board's are once it has
# worn the model 12 h; rest judged against a fixed threshold (60 mg, Q10 g) over 2 s segments
# (the wear profile's noise gauge judges nothing still before 80 s of quiet segments).
EARLY_BINS = "app.proc.pipe.bins.set_differ((app.proc.pipe.bins.differs[0], 1, 0))"
REFIT_SETTINGS = ", threshold=60, seconds=2"


def test_the_twin_follows_a_refit_of_the_board(tmp_path):
    """The Pico, with the four-effect model resumed, fits again mid-run (its bins made ready
    early): the board's checksum over the applied values equals the twin's, which takes the
    stored calibration up to the refit's index and the refit's parameters from there; taken a
    block (25 samples) early or late, or never, the twin's checksum differs from the board's."""
    # 160 s: the refit came at 111.5 s, then at 118.9 s once the app's start took other time
    # (the chip's samples start when the app sets it up, so their phase against the stimulus,
    # the temperatures read and the fit all move with the start)
    refits, board_sum, args = run_four_effects(tmp_path, "pico", 50, 160, refit=True)
    assert refits >= 1
    for shift in (-25, 25, 1 << 40):   # a block early, late, never
        assert fletcher(twin_apply(*args, shift=shift)[0]) != board_sum


@pytest.mark.slow
@pytest.mark.parametrize("rate", RATES[::-1])
@pytest.mark.parametrize("which", ["pico", "feather"])
def test_an_emulated_hour_with_four_effects_loses_nothing(tmp_path, which, rate):
    run_four_effects(tmp_path, which, rate, 3600)
