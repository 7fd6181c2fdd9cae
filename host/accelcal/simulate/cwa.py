"""An Axivity AX3 .cwa writer, for the bench and tests: a recording's samples (t s, xyz g,
temperature degC) as the device stores them (OpenMovement's cwa.h, docs/ax3-technical.md): a
1024-byte 'MD' header packet, then 512-byte 'AX' data blocks of 80 unpacked samples (three
signed 16-bit axes, 1/256 g; +-8 g), each block with its whole-second timestamp, the index of
the sample it belongs to (timestampOffset), the 10-bit temperature reading and a checksum that
makes the block's 16-bit words sum to 0.  Blocks are built in bulk with numpy: a 14-day 100 Hz
recording (1.5 M blocks, 0.8 GB) in seconds."""
from __future__ import annotations

import calendar

import numpy as np

PER_BLOCK = 80        # unpacked samples (numAxesBPS 0x32: 3 axes, 2 bytes each)
UNIT = 256            # per g
RANGE_G = 8
BLOCK = np.dtype([("head", "S2"), ("length", "<u2"), ("fractional", "<u2"), ("session", "<u4"),
                  ("sequence", "<u4"), ("timestamp", "<u4"), ("light", "<u2"), ("temp", "<u2"),
                  ("events", "u1"), ("battery", "u1"), ("rate", "u1"), ("axes_bps", "u1"),
                  ("offset", "<i2"), ("count", "<u2"), ("samples", "<i2", (PER_BLOCK, 3)),
                  ("checksum", "<u2")])
assert BLOCK.itemsize == 512


def rate_code(rate_hz: int, range_g: int = RANGE_G) -> int:
    """cwa.h's sampleRate byte: rate = 3200 / 2^(15 - low nibble), range = 16 >> (top 2 bits)."""
    n = 15 - int(round(np.log2(3200 / rate_hz)))
    if 3200 / (1 << (15 - n)) != rate_hz:
        raise ValueError(f"{rate_hz} Hz is no AX3 rate")
    return ({16: 0, 8: 1, 4: 2, 2: 3}[range_g] << 6) | n


def packed_time(s: np.ndarray) -> np.ndarray:
    """Whole seconds since the epoch (UTC) as cwa.h packs a date and time into 32 bits."""
    d = np.asarray(s, np.int64).astype("datetime64[s]")
    year = d.astype("datetime64[Y]").astype(np.int64) + 1970
    month = d.astype("datetime64[M]").astype(np.int64) % 12 + 1
    day = (d.astype("datetime64[D]") - d.astype("datetime64[M]")).astype(np.int64) + 1
    sec = (d - d.astype("datetime64[D]")).astype(np.int64)
    return ((year - 2000) << 26 | month << 22 | day << 17 | (sec // 3600) << 12 |
            (sec // 60 % 60) << 6 | sec % 60).astype(np.uint32)


def header(rate_hz: int, session: int = 1) -> bytes:
    h = bytearray(1024)
    h[0:2] = b"MD"
    h[2:4] = (1020).to_bytes(2, "little")
    h[4] = 0x00                                  # hardwareType: AX3 (0x00 or 0xFF)
    h[5:7] = (14).to_bytes(2, "little")          # deviceId
    h[7:11] = session.to_bytes(4, "little")
    h[35] = 0xFF                                 # sensorConfig: no gyroscope
    h[36] = rate_code(rate_hz)
    h[41] = 45                                   # firmwareRevision
    return bytes(h)


class CwaWriter:
    """Samples in, whole blocks out; the last block holds what is left (sampleCount)."""

    def __init__(self, fh, rate_hz: int, start_s: float = calendar.timegm((2026, 1, 5, 0, 0, 0))):
        self.fh, self.rate, self.start = fh, rate_hz, start_s
        self.seq = 0
        self.held = np.zeros((0, 5))
        fh.write(header(rate_hz))

    def write(self, t: np.ndarray, xyz: np.ndarray, temp: np.ndarray) -> None:
        rows = np.vstack([self.held, np.column_stack([t, xyz, temp])])
        whole = len(rows) // PER_BLOCK * PER_BLOCK
        self._blocks(rows[:whole])
        self.held = rows[whole:]

    def close(self) -> None:
        if len(self.held):
            self._blocks(self.held)

    def _blocks(self, rows: np.ndarray) -> None:
        n = -(-len(rows) // PER_BLOCK)
        if n == 0:
            return
        b = np.zeros(n, BLOCK)
        b["head"], b["length"], b["session"] = b"AX", 508, 1
        b["sequence"] = self.seq + np.arange(n)
        b["rate"], b["axes_bps"], b["battery"] = rate_code(self.rate), 0x32, 200
        first = rows[::PER_BLOCK, 0] + self.start
        whole = np.floor(first)
        # the block's timestamp is the second its first sample is in; offset: the (negative)
        # index of that second's start relative to the block's first sample
        b["timestamp"] = packed_time(whole.astype(np.int64))
        b["offset"] = -np.round((first - whole) * self.rate).astype(np.int16)
        counts = np.minimum(PER_BLOCK, len(rows) - np.arange(n) * PER_BLOCK)
        b["count"] = counts
        q = np.zeros((n * PER_BLOCK, 3), np.int16)
        q[:len(rows)] = np.clip(np.round(rows[:, 1:4] * UNIT), -RANGE_G * UNIT, RANGE_G * UNIT - 1)
        b["samples"] = q.reshape(n, PER_BLOCK, 3)
        reading = np.round((rows[::PER_BLOCK, 4] + 50) * 256 / 75)   # cwa.h: degC = v * 75/256 - 50
        b["temp"] = np.clip(reading, 0, 1023).astype(np.uint16)
        words = b.view(np.uint16).reshape(n, 256)
        b["checksum"] = (-words[:, :255].sum(axis=1, dtype=np.uint64)) & 0xFFFF
        self.fh.write(b.tobytes())
        self.seq += n
