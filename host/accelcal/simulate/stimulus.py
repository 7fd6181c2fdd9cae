"""Stimulus files for the simulated LIS3DH (format in host/accelcal/sim/vlis3dh.py)."""
from __future__ import annotations

import os
import struct
from pathlib import Path

import numpy as np

HEADER = struct.Struct("<4sHHII")
MAGIC = b"ACST"


class StimulusWriter:
    """Writes a stimulus file block by block (n_samples known up front): constant memory.  Into
    a temporary file beside it, renamed into place by close() once every sample is written."""

    def __init__(self, path: str | Path, rate_hz: int, n_samples: int, supply: bool = False):
        self.path = Path(path)
        self.tmp = self.path.with_name(f".{self.path.name}.{os.getpid()}.partial")
        self.fh = open(self.tmp, "wb")
        self.n = n_samples
        self.written = 0
        self.supply = supply   # version 2: each sample also carries the board's supply (mV)
        self.fh.write(HEADER.pack(MAGIC, 2 if supply else 1, int(rate_hz), n_samples, 0))

    def write(self, xyz_g: np.ndarray, temp_c: np.ndarray, supply_mv=None) -> None:
        """xyz_g: (N, 3) acceleration the sensing element sees (g); temp_c: (N,) degC;
        supply_mv: (N,) the board's supply (a version-2 file, written with supply=True)."""
        xyz_g = np.asarray(xyz_g, dtype=np.float64)
        rec = np.empty((len(xyz_g), 5 if self.supply else 4), dtype="<i4")
        rec[:, :3] = np.rint(np.clip(xyz_g, -2000.0, 2000.0) * 1e6)
        rec[:, 3] = np.rint(np.asarray(temp_c, dtype=np.float64) * 1e3)
        if self.supply:
            rec[:, 4] = np.rint(np.clip(supply_mv, 0, 65535))
        self.fh.write(rec.tobytes())
        self.written += len(rec)

    def abort(self) -> None:
        """The run failed: no stimulus file (the partial one removed)."""
        self.fh.close()
        self.tmp.unlink(missing_ok=True)

    def close(self) -> None:
        self.fh.close()
        if self.written != self.n:
            self.tmp.unlink(missing_ok=True)
            raise ValueError(f"stimulus: {self.written} samples written, header says {self.n}")
        os.replace(self.tmp, self.path)


def write_stimulus(path: str | Path, rate_hz: int, xyz_g: np.ndarray, temp_c: np.ndarray) -> None:
    """xyz_g: (N, 3) acceleration the sensing element sees (g); temp_c: (N,) temperature (degC)."""
    w = StimulusWriter(path, rate_hz, len(xyz_g))
    w.write(xyz_g, temp_c)
    w.close()


def read_stimulus(path: str | Path) -> tuple[int, np.ndarray, np.ndarray]:
    data = Path(path).read_bytes()
    magic, version, rate, n, _ = HEADER.unpack_from(data)
    if magic != MAGIC:
        raise ValueError(f"{path}: not a stimulus file")
    k = 5 if version == 2 else 4
    rec = np.frombuffer(data, dtype="<i4", offset=HEADER.size, count=k * n).reshape(n, k)
    return rate, rec[:, :3] / 1e6, rec[:, 3] / 1e3


def calibration_dance(path: str | Path, rate_hz: int, params, seed: int, rounds: int = 2,
                      rest_s: float = 10.0, move_s: float = 2.0, tilt_deg: float = 12.0,
                      noise_g: float = 0.0016) -> np.ndarray:
    """A calibration dance for a board on a bench, `rounds` times: still on each of its six faces
    (the paper's n and p subsets), then on six edges, two in each plane (its 0 subsets: the
    third axis level), each pose tilted up to tilt_deg at random so that repeats differ, with
    moves between whose samples jump by tens of mg; seen through a sensor with the 9 parameters
    `params` (paper order).  Writes the stimulus; returns what the sensing element saw (g)."""
    from accelcal.simulate.scenarios import uncorrect
    rng = np.random.default_rng(seed)
    edges = [(1, 1, 0), (-1, 1, 0), (1, 0, 1), (-1, 0, 1), (0, 1, 1), (0, -1, 1)]
    poses = np.vstack([np.eye(3), -np.eye(3), np.array(edges) / np.sqrt(2)])
    parts = []
    for _ in range(rounds):
        for pose in poses:
            d = pose + rng.uniform(-1, 1, 3) * np.tan(np.radians(tilt_deg))
            v = uncorrect(np.asarray(params, dtype=float), (d / np.linalg.norm(d))[None, :])[0]
            parts.append(v + rng.normal(scale=noise_g, size=(int(rate_hz * rest_s), 3)))
            parts.append(v + rng.normal(scale=0.3, size=(int(rate_hz * move_s), 3)))
    xyz = np.clip(np.concatenate(parts), -1.9, 1.9)
    write_stimulus(path, rate_hz, xyz, 30 + np.linspace(0, 2, len(xyz)))
    return xyz
