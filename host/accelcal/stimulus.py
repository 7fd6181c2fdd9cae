"""Stimulus files for the simulated LIS3DH (format in host/accelcal/sim/vlis3dh.py)."""
from __future__ import annotations

import struct
from pathlib import Path

import numpy as np

HEADER = struct.Struct("<4sHHII")
MAGIC = b"ACST"


class StimulusWriter:
    """Writes a stimulus file block by block (n_samples known up front): constant memory."""

    def __init__(self, path: str | Path, rate_hz: int, n_samples: int):
        self.fh = open(path, "wb")
        self.n = n_samples
        self.written = 0
        self.fh.write(HEADER.pack(MAGIC, 1, int(rate_hz), n_samples, 0))

    def write(self, xyz_g: np.ndarray, temp_c: np.ndarray) -> None:
        """xyz_g: (N, 3) acceleration the sensing element sees (g); temp_c: (N,) degC."""
        xyz_g = np.asarray(xyz_g, dtype=np.float64)
        rec = np.empty((len(xyz_g), 4), dtype="<i4")
        rec[:, :3] = np.rint(np.clip(xyz_g, -2000.0, 2000.0) * 1e6)
        rec[:, 3] = np.rint(np.asarray(temp_c, dtype=np.float64) * 1e3)
        self.fh.write(rec.tobytes())
        self.written += len(rec)

    def close(self) -> None:
        self.fh.close()
        if self.written != self.n:
            raise ValueError(f"stimulus: {self.written} samples written, header says {self.n}")


def write_stimulus(path: str | Path, rate_hz: int, xyz_g: np.ndarray, temp_c: np.ndarray) -> None:
    """xyz_g: (N, 3) acceleration the sensing element sees (g); temp_c: (N,) temperature (degC)."""
    w = StimulusWriter(path, rate_hz, len(xyz_g))
    w.write(xyz_g, temp_c)
    w.close()


def read_stimulus(path: str | Path) -> tuple[int, np.ndarray, np.ndarray]:
    data = Path(path).read_bytes()
    magic, _, rate, n, _ = HEADER.unpack_from(data)
    if magic != MAGIC:
        raise ValueError(f"{path}: not a stimulus file")
    rec = np.frombuffer(data, dtype="<i4", offset=HEADER.size, count=4 * n).reshape(n, 4)
    return rate, rec[:, :3] / 1e6, rec[:, 3] / 1e3
