"""The AX3 .cwa writer of the bench (simulate/cwa.py), read back by actfast through accelcal's
streaming reader: the samples at the format's 1/256 g, the times, the block temperatures, and
each block's words summing to 0 (cwa.h's checksum), read from the raw bytes."""
import numpy as np

from accelcal.files.recordings import CwaRecording, open_recording
from accelcal.simulate.cwa import PER_BLOCK, CwaWriter


def test_written_blocks_read_back_to_the_samples(tmp_path, rng):
    n = 100 * 600 + 37      # ten minutes at 100 Hz and a part block
    t = np.arange(n) / 100
    xyz = rng.normal(0, 0.6, (n, 3))
    temp = 28 + 4 * np.arange(n) / n
    f = tmp_path / "w.cwa"
    with open(f, "wb") as fh:
        w = CwaWriter(fh, 100)
        for a in range(0, n, 7777):       # chunks that split blocks
            w.write(t[a:a + 7777], xyz[a:a + 7777], temp[a:a + 7777])
        w.close()
    rec = open_recording(f)
    assert isinstance(rec, CwaRecording) and rec.range_g == 8 and rec.has_temp
    chunks = list(rec.chunks())
    got_t = np.concatenate([c.t for c in chunks])
    assert len(got_t) == n
    assert np.abs(got_t - got_t[0] - t).max() < 1e-5
    assert np.array_equal(np.concatenate([c.xyz for c in chunks]), np.round(xyz * 256) / 256)
    # each block carries its first sample's temperature as cwa.h's 10-bit reading
    got_temp = np.concatenate([c.temp for c in chunks])
    first = temp[::PER_BLOCK]
    assert np.abs(got_temp[::PER_BLOCK] - first).max() < 75 / 256
    raw = np.fromfile(f, np.uint16)[512:].reshape(-1, 256)
    assert len(raw) == -(-n // PER_BLOCK)
    assert (raw.sum(axis=1, dtype=np.uint64) & 0xFFFF == 0).all()
