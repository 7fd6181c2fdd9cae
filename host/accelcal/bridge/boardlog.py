"""Board logs on the host: decode pulled files (with device/acal/logger/log.py, the board's own codec),
and replay a raw capture through the current device modules to diff against what the board
logged - the check a firmware developer runs after changing device code."""
from __future__ import annotations

import os
import struct
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from acal.core import bins as dbins
from acal.core import effects as deff
from acal.core import fixed
from acal.logger import log
from acal.logger.app import Processor
from accelcal.errors import InputError
from accelcal.files.outputs import check_regular, note_input
from accelcal.fixedpoint import seconds

LOG_FILES = ("log.bin", "capture.bin", "cal_a.bin", "cal_b.bin")
FILE_MAX_BYTES = 1 << 30    # a pulled file is read whole: the largest capture deploy allows
FIELDS = {
    log.BOOT: ("log_bytes_at_boot", "version", "rate_hz", "seconds", "threshold", "axis", "range_g", "fifo",
               "min_count", "max_count", "differ", "iterations", "recal_seconds", "temp_ref", "model", "fit", "discover"),
    log.REST: ("index", "x", "y", "z", "temp", "subset", "merged"),
    log.CAL: ("index", "number", "status", "iterations", "points", "objective_start",
              "objective", *fixed.PARAM_NAMES),
    log.COUNTERS: ("index", "samples", "lost", "fifo_overruns", "bus_errors", "bus_retries",
                   "rest_segments", "rest_logged", "rest_skipped"),
    log.GAP: ("index", "lost"),
    log.EFFECT: ("index", "effect", "ref_temp", "ref_time", "p0", "p1", "p2"),
    log.SUPPLY: ("index", "supply_mv"),
    log.DISCOVERY: ("index", "adopted", "closest", "heldout_before", "heldout_after",
                    "blocks_better", "blocks", "effect", "p0", "p1", "p2"),
}


@dataclass
class Decoded:
    path: str
    records: list[tuple[int, tuple]] = field(default_factory=list)  # (type, values)
    dropped: list[tuple[int, int]] = field(default_factory=list)
    size: int = 0
    malformed: list[tuple[int, str]] = field(default_factory=list)  # (offset, why): CRC fine

    def of(self, rtype):
        return [v for t, v in self.records if t == rtype]

    def dicts(self, rtype):
        return [dict(zip(FIELDS[rtype], v)) for v in self.of(rtype)]

    def dropped_report(self, data: bytes | None = None) -> list[str]:
        out = []
        for off, n in self.dropped:
            what = "power-cut padding" if data is not None and not any(data[off:off + n]) else "damaged or torn bytes"
            out.append(f"{self.path}: dropped {n} bytes at offset {off} ({what})")
        for off, why in self.malformed:
            out.append(f"{self.path}: dropped a malformed record at offset {off} ({why})")
        return out


def check_pulled(path) -> None:
    """A pulled file, before it is read whole: a regular file (a link to a device such as
    /dev/zero is refused) of at most FILE_MAX_BYTES."""
    check_regular(path)
    size = Path(path).stat().st_size
    if size > FILE_MAX_BYTES:
        raise InputError(f"{path}: {size >> 20} MB is more than a board writes (at most "
                         f"{FILE_MAX_BYTES >> 20} MB, the largest --capture-kb)")


def decode(path: str | Path) -> Decoded:
    check_pulled(path)
    try:
        data = Path(path).read_bytes()
    except OSError as e:
        raise InputError(f"{path}: cannot read ({e.strerror})") from None
    recs, dropped = log.scan(data)
    if data and not recs:
        raise InputError(f"{path}: no valid accelcal log records in {len(data)} bytes "
                         "(not a log of ours, or destroyed)")
    out = Decoded(str(path), size=len(data), dropped=dropped)
    for off, t, payload in recs:
        why = malformed(t, payload)
        if why:   # its CRC passed, its content cannot be: dropped like a torn record, and said
            out.malformed.append((off, why))
            continue
        out.records.append((t, log.unpack(t, payload)))
    return out


_SIZES = {t: struct.calcsize(f) for t, f in log.FORMATS.items()}
# the record kinds' names, and every older layout a record of each kind was written with (the
# device's log.unpack reads each by its length): the host's alone, a board's heap keeps neither
TYPE_NAMES = {log.BOOT: "boot", log.REST: "rest", log.CAL: "cal", log.COUNTERS: "counters",
              log.SAMPLES: "samples", log.GAP: "gap", log.EFFECT: "effect", log.STORE: "store",
              log.SUPPLY: "supply", log.DISCOVERY: "discovery"}
OLD_FORMATS = {log.BOOT: (log.BOOT_V1A, log.BOOT_V1B, log.BOOT_V1, log.BOOT_V2),
               log.EFFECT: (log.EFFECT_V1,), log.DISCOVERY: (log.DISCOVERY_V1,)}
# the fits' status codes' names (acal/core/status.py), for the host's logs and reports: the
# host's alone, a board keeps no string of them
STATUS_NAMES = ("ok", "diverged", "too few points", "out of calibration bounds",
                "parameters not determined by the points",
                "composed fit failed: base calibration kept",
                "composed fit worse than the base fit: base calibration kept")
_STATUS_COUNT = len(STATUS_NAMES)


def model_kinds(code: int) -> tuple[int, ...]:
    """The effect ids of a model code of the board's log (acal.core.effects.model_code's
    inverse: KIND_BITS an effect, the first lowest); the host's alone, a board never reads one."""
    kinds = []
    while code:
        kinds.append(code & deff.KIND_MAX)
        code >>= deff.KIND_BITS
    return tuple(kinds)


def model_name(code: int) -> str | None:
    """A model code of the board's (acal.core.effects.model_code: one effect, or a pair such as the
    curve) as its effects' names joined by '+'; None for 0 (no effect)."""
    return "+".join(deff.NAMES[k] for k in model_kinds(code)) or None


def malformed(rtype: int, payload: bytes) -> str | None:
    """Why a record that passed its CRC is still not one the app writes (its length for its
    kind, a field out of its range), or None."""
    name = TYPE_NAMES.get(rtype)
    if name is None or rtype == log.STORE:
        return f"unknown record type {rtype}"
    n = len(payload)
    if rtype == log.SAMPLES:
        if n < 6 or (n - 6) % 6 or payload[4] != (n - 6) // 6 or payload[4] > log.SAMPLES_PER_RECORD:
            return f"{name} record of {n} bytes does not hold the samples it counts"
        return None
    # every layout the app ever wrote (OLD_FORMATS; docs/boards-and-logs.md "Record layouts")
    sizes = (_SIZES[rtype], *(struct.calcsize(f) for f in OLD_FORMATS.get(rtype, ())))
    if n not in sizes:
        return f"{name} record of {n} bytes (a {name} record has {_SIZES[rtype]})"
    v = log.unpack(rtype, payload)
    if rtype == log.BOOT:
        kinds = model_kinds(v[14])
        checks = [(1 <= v[2] <= 5376, "rate_hz"), (v[5] <= 3, "axis"),
                  (1 <= v[3] and v[2] * v[3] <= 65535, "seconds (a segment of 1..65535 samples)"),
                  (all(k in deff.NAMES for k in kinds) and len(set(kinds)) == len(kinds), "model"),
                  (v[6] in (2, 4, 8, 16), "range_g"), (v[7] <= 1, "fifo"),
                  (1 <= v[8] <= v[9] <= 64, "min_count/max_count"), (v[15] <= 1, "fit"),
                  (v[16] <= 1, "discover")]
    elif rtype == log.REST:
        checks = [(-1 <= v[5] < 9, "subset")]
    elif rtype == log.CAL:
        checks = [(v[2] < _STATUS_COUNT, "status")]
    elif rtype == log.EFFECT:
        checks = [(v[1] in deff.NAMES, "effect")]
    elif rtype == log.DISCOVERY:
        checks = [(all(k in deff.NAMES for k in model_kinds(v[1])), "adopted"),
                  (all(k in deff.NAMES for k in model_kinds(v[2])), "closest"),
                  (v[5] <= v[6], "blocks"), ((v[7] in deff.NAMES) == (v[2] != 0), "effect")]
    else:
        checks = []
    for ok, field_name in checks:
        if not ok:
            return f"{name} record with {field_name} out of range"
    return None


@dataclass
class Capture:
    blocks: list  # ("samples", first_index, temp, ndarray (n, 3) int), ("gap", index, lost)
    # or ("supply", index, mV)
    boot: tuple | None


def read_capture(dirpath: Path) -> Capture:
    cap = decode(dirpath / "capture.bin")
    blocks = []
    for t, v in cap.records:
        if t == log.SAMPLES:
            first, n, temp, xyz = v
            blocks.append(("samples", first, temp, np.array(xyz, dtype=np.int64).reshape(n, 3)))
        elif t == log.GAP:
            blocks.append(("gap", v[0], v[1]))
        elif t == log.SUPPLY:
            blocks.append(("supply", v[0], v[1]))
    boots = decode(dirpath / "log.bin").of(log.BOOT)
    return Capture(blocks, boots[-1] if boots else None)


def _processor(lg, b: dict, profile: str | None):
    """The device Processor with a BOOT record's settings (profile: that profile's pipeline
    settings instead)."""
    model = "+".join(["base"] + [deff.NAMES[k] for k in model_kinds(b["model"])])
    if profile is None:
        return Processor(lg, b["rate_hz"], recal_seconds=b["recal_seconds"], seconds=b["seconds"],
                         threshold=b["threshold"], axis=b["axis"], min_count=b["min_count"],
                         max_count=b["max_count"], differ=b["differ"], iterations=b["iterations"],
                         model=model, fit=b["fit"], range_g=b["range_g"],
                         discover=bool(b["discover"]))
    from acal.core import profile as dprofile
    return Processor(lg, b["rate_hz"], recal_seconds=b["recal_seconds"], seconds=b["seconds"],
                     model=model, profile=dprofile.parse(profile), range_g=b["range_g"],
                     discover=bool(b["discover"]) and profile == "wear")


def run_capture(dirpath: str | Path, log_path: str | Path, profile: str | None = None):
    """Feed a pulled capture through the current device Processor, configured from the board's
    BOOT record, logging to log_path.  profile: run that profile's pipeline settings instead
    of the board's (rate, recalibration interval and model stay the board's).  Returns the
    Processor."""
    d = Path(dirpath)
    for f in ("log.bin", "capture.bin"):
        if not (d / f).exists():
            raise InputError(f"{d}: no {f} (pull a board that ran with capture on)")
    cap = read_capture(d)
    if cap.boot is None:
        bad = [why for _, why in decode(d / "log.bin").malformed]
        raise InputError(f"{d}/log.bin: no BOOT record, cannot tell the board's settings"
                         + (f" (dropped: {bad[0]})" if bad else ""))
    b = dict(zip(FIELDS[log.BOOT], cap.boot))
    lg = log.Log(str(log_path))
    try:
        proc = _processor(lg, b, profile)
    except (ValueError, KeyError, OverflowError) as e:   # settings the app's checks refuse
        raise InputError(f"{d}/log.bin: the BOOT record's settings are not ones the app runs "
                         f"({' '.join(str(e).split())[:120]})") from None
    for blk in cap.blocks:
        if blk[0] == "gap":
            proc.gap(blk[2])
        elif blk[0] == "supply":   # the board's supply from here on, as its feeder set it
            proc.now[fixed.C_SUPPLY] = blk[2]
        else:
            _, first, temp, xyz = blk
            if first != proc.index:
                raise InputError(f"{d}/capture.bin: sample {first} follows {proc.index}: "
                                 "capture records missing")
            proc.now[fixed.C_TEMP] = temp << fixed.TEMP_Q   # whole degC, as the app reads it
            proc.feed(xyz.ravel().tolist(), len(xyz))
    lg.close()
    return proc


def replay(dirpath: str | Path, profile: str | None = None) -> dict:
    """Re-run a pulled capture through the current device Processor; diff REST and CAL records
    against the board's log over the span the capture covers.  profile: replay with that
    profile's settings instead of the board's (what it would have done; differences expected)."""
    d = Path(dirpath)
    with tempfile.TemporaryDirectory() as tmp:
        proc = run_capture(d, Path(tmp) / "log.bin", profile)
        end = proc.index
        if end == 0:   # nothing replayed is nothing compared: not "identical"
            raise InputError(f"{d / 'capture.bin'}: holds no samples to replay (deploy with "
                             "--capture-kb to keep them)")
        mine = decode(Path(tmp) / "log.bin")
    board = decode(d / "log.bin")
    # The capture is the last session's (it restarts at each boot): compare the records the
    # board wrote after its last BOOT record.
    last_boot = max((i for i, (t, _) in enumerate(board.records) if t == log.BOOT), default=0)
    session = board.records[last_boot:]
    out = {"samples_replayed": end, "profile": profile or "the board's"}
    for rtype, name in ((log.REST, "rest"), (log.CAL, "cal"), (log.EFFECT, "effect"),
                        (log.DISCOVERY, "discovery")):
        theirs = [v for t, v in session if t == rtype and v[0] <= end]
        ours = mine.of(rtype)
        if rtype == log.CAL:  # the number counts calibrations before the capture began too
            theirs = [v[:1] + v[2:] for v in theirs]
            ours = [v[:1] + v[2:] for v in ours]
        diffs = [i for i, (a, c) in enumerate(zip(theirs, ours)) if a != c]
        out[name] = {"board": len(theirs), "replay": len(ours), "differ": len(diffs),
                     "first_difference": (diffs[0] if diffs else (min(len(theirs), len(ours))
                                                                 if len(theirs) != len(ours) else None))}
    out["identical"] = all(out[k]["differ"] == 0 and out[k]["board"] == out[k]["replay"]
                           for k in ("rest", "cal", "effect", "discovery"))
    return out


def summary(dirpath: str | Path) -> dict:
    """What a pulled folder holds, decoded: counters, calibrations, rest points, dropped bytes."""
    d = Path(dirpath)
    lg = decode(d / "log.bin")
    data = (d / "log.bin").read_bytes()
    from accelcal.model.effects import CATALOGUE
    cals = lg.dicts(log.CAL)
    effects = lg.dicts(log.EFFECT)
    for c in cals:
        for n in fixed.PARAM_NAMES:
            c[n] = c[n] / fixed.PARAM_ONE
        code = c["status"]
        c["status"] = (STATUS_NAMES[code] if code < len(STATUS_NAMES)
                       else f"status {code}")
        for e in effects:  # a composed model's EFFECT records follow their CAL, same index
            if e["index"] == c["index"] and e["effect"] in deff.NAMES:
                eff = CATALOGUE[deff.NAMES[e["effect"]]]
                vals = eff.from_int([e["p0"], e["p1"], e["p2"]]) * eff.scale
                # a step's record holds its time where the others hold the reference time, a
                # supply's its reference supply (mV)
                if e["effect"] == deff.SUPPLY_OFFSET:
                    when, value = "ref_supply_mv", e["ref_time"]
                else:
                    when = "step_time_s" if e["effect"] == deff.STEP else "ref_time_s"
                    value = seconds(e["ref_time"])
                c.setdefault("effects", {})[eff.name] = {
                    "unit": eff.report_unit, "params": dict(zip(eff.param_names, vals.tolist())),
                    "ref_temp": e["ref_temp"] / (1 << fixed.TEMP_Q), when: value}   # degC
    rests = lg.dicts(log.REST)
    out_discoveries = [_discovery(d, CATALOGUE) for d in lg.dicts(log.DISCOVERY)]
    for r in rests:
        for k in "xyz":
            r[k] = r[k] / fixed.POINT_ONE_G
        r["subset"] = dbins.SUBSET_NAMES[r["subset"]] if r["subset"] >= 0 else None
    out = {"log_bytes": lg.size, "boots": len(lg.of(log.BOOT)),
           "counters": lg.dicts(log.COUNTERS)[-1] if lg.of(log.COUNTERS) else None,
           "calibrations": cals, "discoveries": out_discoveries, "rest_points": rests,
           "dropped": lg.dropped_report(data)}
    for f in ("cal_a.bin", "cal_b.bin"):
        note_input(d / f)
        if os.path.lexists(d / f):
            check_pulled(d / f)
    store = log.CalStore(str(d / "cal_a.bin"), str(d / "cal_b.bin"))
    slot, rec = store.load()
    out["stored_calibration"] = None if rec is None else {
        "slot": "ab"[slot], "number": rec[1],
        **{n: v / fixed.PARAM_ONE for n, v in zip(fixed.PARAM_NAMES, rec[7:])}}
    return out


def _discovery(d: dict, catalogue) -> dict:
    """A DISCOVERY record for people: the effects by name, the held-out errors (the board's
    integers: heldscore's sums of | |a|^2 - 1 |, Q16 g^2) and their change in %, the closest
    candidate's parameters in their report units."""
    out = {"index": d["index"], "adopted": model_name(d["adopted"]),
           "closest": model_name(d["closest"]),
           "heldout_before": d["heldout_before"], "heldout_after": d["heldout_after"],
           "blocks_better": d["blocks_better"], "blocks": d["blocks"]}
    before, after = d["heldout_before"], d["heldout_after"]
    out["change_pct"] = (round(100.0 * (after - before) / before, 1)
                         if before and out["closest"] else None)
    if out["closest"]:    # the record holds the parameters of the effect its round added
        eff = catalogue[deff.NAMES[d["effect"]]]
        vals = eff.from_int([d["p0"], d["p1"], d["p2"]]) * eff.scale
        out["params_effect"] = eff.name
        out["unit"] = eff.report_unit
        out["params"] = dict(zip(eff.param_names, vals.tolist()))
    return out
