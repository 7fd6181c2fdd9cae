"""What a calibration gives: one CalibrationResult per device or file, built by pipeline/calibrate.py
(and batch.py for a file that could not be read), printed, saved and summarised by its own methods,
as lmfit's ModelResult is.

A result is the JSON record of docs/method-and-formats.md "Calibration records" (a dict: `r["status"]`,
`json.dumps(r)`), with the methods a person and a batch need.  Fields by status:
  calibrated       params, params_int (Q24), error_before_mg / error_after_mg, points, ...
  not_enough_data  reason (the bins did not fill, or a composed model's spread was not reached)
  failed           reason (the fit, or the file)
A recording's result also carries its quality (hours, gaps, still windows, exclusions, clipping).
"""
from __future__ import annotations

import csv
import json
import os

from acal.core.fixed import PARAM_NAMES
from accelcal.errors import InputError, printable
from accelcal.files.outputs import atomic
from accelcal.pipeline.record import Params, Record

SUMMARY_COLUMNS = ("file", "status", "calibration", "reason", "profile", "format", "rate_hz", "hours",
                   "hours_used", "gaps", "still_windows", "nonwear_excluded", "imputed_excluded",
                   "clipped_excluded", "bins_filled", "temp_min_c", "temp_max_c", "clipped_pct",
                   "error_before_mg", "error_after_mg", "iterations", "seconds", *PARAM_NAMES)


def discovery_line(d: dict) -> str:
    """The board's own discovery in one line (pipeline/calibrate.py discovery_record)."""
    if d.get("reason"):
        return f"discovery: nothing tried: {d['reason']}"
    if d["closest"] is None:
        return "discovery: no candidate testable on these points"
    after = (f"{d['heldout_error_before_mg']:.2f} -> {d['heldout_error_after_mg']:.2f} mg "
             f"held-out, better in {d['blocks_better']} of {d['blocks']} held-out blocks")
    if "heldout_error_unplaced_mg" in d:
        after += (f"; the step's time placed among {d['step_gap_points']} held-out points "
                  f"({d['step_time_fitted_s']:.0f} -> {d['step_time_s']:.0f} s; its error "
                  f"leave-one-out, {d['heldout_error_unplaced_mg']:.2f} mg at the fit's time)")
    if d["effect"]:
        line = f"discovery: the board adopts {d['effect']} (model {d['model']}): {after}"
    else:
        line = f"discovery: no effect adopted; the closest, {d['closest']}: {after}"
    for k, later in enumerate(d.get("rounds", ()), 2):   # from the model adopted before
        line += "\n  " + discovery_line(later).replace("discovery:", f"discovery, round {k}:", 1)
    return line


class CalibrationResult(Record):
    """One device's (or file's) calibration: its JSON record (keys and attributes: status,
    params, error_before_mg, error_after_mg, ...), and how it reads (report(), summary()).
    `params` is a Params mapping (name -> value, unit, Q24 int); `r["params"]` the JSON's
    {name: value}."""

    @classmethod
    def failed(cls, path: str, reason: str) -> "CalibrationResult":
        """A file that could not be calibrated at all (unreadable, a worker lost)."""
        return cls(file=path, status="failed", calibration="none", reason=reason)

    @property
    def ok(self) -> bool:
        return self["status"] == "calibrated"

    @property
    def params(self) -> Params:
        """The parameters by name, each with its value, unit and the device's integer (empty
        when there are none)."""
        return Params.of(self.get("params"), self.get("params_int"), self.get("model"))

    def _repr_fields(self) -> str:
        head = f"{self.get('file') or ''} {self['status']}".strip()
        if self.get("error_after_mg") is not None and self.get("error_before_mg") is not None:
            head += (f" {self.get('model', 'base')} by {self.get('method', '?')}: "
                     f"{self['error_before_mg']:.2f} -> {self['error_after_mg']:.2f} mg")
        elif self.get("reason"):
            why = self["reason"]
            head += f": {why[:80]}" + ("..." if len(why) > 80 else "")
        return head

    def summary(self) -> str:
        """report()'s lines, then the parameters with their units and Q24 integers."""
        text = self.report()
        return text + ("\n" + self.params.table() if self.get("params") else "")

    @property
    def usable(self) -> bool:
        """Calibrated, or given its fallback calibration (said so in the record)."""
        return self.ok or self.get("calibration") == "fallback"

    def save(self, path: str, force: bool = False) -> None:
        """The parameters file `calibrate --save` writes (for apply, --fallback, a board),
        never over one of the inputs (force: replace an existing file)."""
        from accelcal.files.outputs import check_output
        from accelcal.files.params import save_params
        if not self.ok:
            raise InputError(f"{self.get('file', 'this result')}: not calibrated "
                             f"({self['status']}); nothing to save")
        check_output(path, [self.get("file")], force, "--save")
        save_params(path, self)

    def report(self, by: str | None = None) -> str:
        """The lines `calibrate` prints: the quality of a recording first, then the outcome."""
        r = self
        head = f"{by} {r[by]}: " if by else ""
        lines = []
        if "hours" in r:
            ex = r["excluded"]
            tr = r["temp_range_c"]
            lines.append(
                f"{head}{r['file']} ({r['format']}, {r['rate_hz']:g} Hz): {r['hours']:.2f} h, "
                f"{r['gaps']} gaps, {r['still_windows']} still windows kept (excluded: "
                f"{ex['nonwear']} non-wear = {r['nonwear_hours']:.2f} h, {ex['imputed']} imputed, "
                f"{ex['clipped']} clipped), clipping {r['clipped_pct']:.3f} %"
                + (f", {tr[0]:.1f}..{tr[1]:.1f} degC" if tr else ", no temperature"))
            lines += [f"{head}warning: {w}" for w in r.get("reader_warnings", ())
                      if w.startswith("a truncated file")]    # files/binpages.py
        if not self.ok:
            label = "NOT ENOUGH DATA" if r["status"] == "not_enough_data" else "FAILED"
            lines.append(f"{head}{label}: {r['reason']}")
            if r.get("calibration") == "fallback":
                lines.append(f"  using the fallback calibration {r['fallback']} (not this file's): "
                             + "  ".join(f"{k}={v:+.5g}" for k, v in r["params"].items()))
                if r.get("error_after_mg") is not None and r.get("error_before_mg") is not None:
                    lines.append(f"  calibration error: {r['error_before_mg']:.2f} mg before -> "
                                 f"{r['error_after_mg']:.2f} mg with the fallback")
            return "\n".join(lines)
        it = f", {r['iterations']} iterations" if r.get("iterations") else ""
        lines.append(f"{head}calibrated {r['model']} by {r['method']} ({r['runtime']}) on "
                     f"{r['points']} points of {r['rest_points']} rest points{it}")
        lines.append("  " + "  ".join(f"{k}={v:+.5g}" for k, v in r["params"].items()))
        if "reference" in r:
            ref = r["reference"]
            more = "".join(f", step at t = {v:g} s" if k == "ts" else f", {k[:-1]} = {v:.6g}"
                           for k, v in ref.items() if k not in ("T0", "t0"))
            lines.append(f"  reference: {ref['T0']:g} degC, t = {ref['t0']:g} s{more}")
        lines.append(f"  calibration error: {r['error_before_mg']:.2f} mg before -> "
                     f"{r['error_after_mg']:.2f} mg after")
        if "auto" in r:   # --model auto (pipeline/job.py calibrate_auto)
            lines.append(f"  model auto: {r['auto']}")
        if r.get("model_from") == "discovery":
            lines.append(f"  the model the discovery ended with (saved and applied as such); the "
                         f"base fit: {r['base_fit']['error_after_mg']:.2f} mg after")
        if "discovery" in r:
            lines.append("  " + discovery_line(r["discovery"]))
        return "\n".join(lines)

    def summary_row(self) -> dict:
        """The batch summary's row (SUMMARY_COLUMNS; None where a figure does not apply)."""
        ex = self.get("excluded") or {}
        tr = self.get("temp_range_c") or [None, None]
        row = {k: self.get(k) for k in SUMMARY_COLUMNS}
        row.update(nonwear_excluded=ex.get("nonwear"), imputed_excluded=ex.get("imputed"),
                   clipped_excluded=ex.get("clipped"), temp_min_c=tr[0], temp_max_c=tr[1])
        for k, v in (self.get("params") or {}).items():
            if k in row:
                row[k] = v
        return row


def save_summary(path: str, results: list[CalibrationResult]) -> None:
    """The batch summary CSV, one row per file, written whole or not at all."""
    with atomic(path, newline="") as fh:
        w = csv.DictWriter(fh, SUMMARY_COLUMNS)
        w.writeheader()
        for r in results:
            w.writerow({k: ("" if v is None else v) for k, v in r.summary_row().items()})


def summary_table(results: list[CalibrationResult]) -> str:
    """A batch as a table a person reads: one line per file, then the count calibrated."""
    name_w = max(12, *(len(os.path.basename(r["file"])) for r in results))
    lines = [f"{'file':<{name_w}}  {'status':<15} {'hours':>7} {'still':>6} {'bins':>4} "
             f"{'before mg':>9} {'after mg':>8}  reason"]
    for r in results:
        def num(k, fmt):
            v = r.get(k)
            width = int(fmt.split(".")[0].rstrip("dfg"))
            return format(v, fmt) if isinstance(v, (int, float)) else "-".rjust(width)
        status = r["status"] + ("*" if r.get("calibration") == "fallback" else "")
        bins = f"{r['bins_filled']}/9" if "bins_filled" in r else "-"
        lines.append(f"{os.path.basename(r['file']):<{name_w}}  {status:<15} {num('hours', '7.1f')} "
                     f"{num('still_windows', '6d')} {bins:>4} {num('error_before_mg', '9.2f')} "
                     f"{num('error_after_mg', '8.2f')}  {r.get('reason') or ''}")
    n_ok = sum(r.ok for r in results)
    n_fb = sum(r.get("calibration") == "fallback" for r in results)
    lines.append(f"{n_ok} of {len(results)} files calibrated"
                 + (f"; {n_fb} use their fallback calibration (*)" if n_fb else ""))
    return "\n".join(lines)


class DiagnoseResult(Record):
    """`diagnose`'s finding on one file (docs/model-discovery.md): the model's held-out error
    beside the noise floor, where it fails, each catalogue candidate's held-out error and the
    effect named (or none), with why."""

    HISTORY_FIELDS = ("model", "input", "heldout_error_mg", "noise_floor_mg", "missing_effect")

    def _repr_fields(self) -> str:
        return (f"{self['input']} model {self['model']}: held-out {self['heldout_error_mg']:.2f} mg, "
                f"missing effect {self['missing_effect'] or 'none'}")

    def history_step(self) -> dict:
        """The line `diagnose --history` appends (pipeline/history.py)."""
        return {k: self[k] for k in self.HISTORY_FIELDS}

    def report(self) -> str:
        """The lines `diagnose` prints."""
        rp = self["rest_points"]
        lines = [f"{self['input']}: model {self['model']}, {rp['train']} training / "
                 f"{rp['heldout']} held-out rest points ({self['split']})",
                 f"held-out calibration error {self['heldout_error_mg']:.2f} mg, noise floor "
                 + (f"{self['noise_floor_mg']:.2f} mg" if self.get("noise_floor_measured", True)
                    else "not measured (no samples)") + ", wrist floor "
                 + (f"{self['wrist_floor_mg']:.2f} mg ({self['wrist_floor_pairs']} pairs)"
                    if self.get("wrist_floor_mg") is not None else "not estimated (too few pairs)")
                 + f", {self.get('heldout_blocks')} held-out blocks",
                 "where the model fails (held-out residual, mean per quintile of each regressor, mg):"]
        kw = max([8] + [len(k) for k in self["where_it_fails"]])
        for k, w in self["where_it_fails"].items():
            lines.append(f"  {k:<{kw}} corr {w['corr']:+.2f}  spread {w['range_mg']:6.2f}  "
                         + " ".join(f"{b:+6.2f}" for b in w["quintile_mean_residual_mg"]))
        lines.append("candidates:")
        ew = max([12] + [len(c["effect"]) for c in self["candidates"]])
        for c in self["candidates"]:
            if c["heldout_error_mg"] is None:
                lines.append(f"  +{c['effect']:<{ew}} not testable: {c['untestable']}")
            else:
                lines.append(f"  +{c['effect']:<{ew}} {c['heldout_error_mg']:6.2f} mg  "
                             f"{c['improvement_pct']:+6.1f} %  better in "
                             f"{c['blocks_improved']:2d} of {c['blocks']:2d} blocks "
                             f"({c['blocks_improved_pct']:3.0f} %"
                             + (", weak evidence)" if c["evidence"] == "weak" else ")"))
            if c.get("device_folds"):   # diagnose.curve_as_device
                j = c["device_folds"]
                lines.append(f"   {'':<{ew}} as the device fits it, each half held out in turn: "
                             f"{j['before_mg']:.2f} -> {j['after_mg']:.2f} mg "
                             f"{j['improvement_pct']:+6.1f} %  better in {j['blocks_improved']} "
                             f"of {j['blocks']} blocks" + (" (named)" if j["named"] else ""))
        lines.append(f"missing effect: {self['missing_effect'] or 'none'}")
        lines.append(self["explanation"])
        lines += [f"plot: {f}" for f in self.get("plots", [])]
        if self.get("report"):
            lines.append(f"report: {self['report']}")
        return "\n".join(lines)


class CompareResult(Record):
    """`compare`'s table: every method fitted on the same training points and scored on the same
    held-out ones (rows: method, points, fit time, error before and after, status)."""

    def _repr_fields(self) -> str:
        return f"{self['input']}: " + ", ".join(
            f"{r['method']} {r['error_after_mg']:.2f} mg" if r["error_after_mg"] is not None
            else f"{r['method']} {r['status']}" for r in self["rows"])

    @property
    def any_calibrated(self) -> bool:
        """Any method fitted (a row worse than no calibration was fitted too, and says so)."""
        return any(r["status"] in ("calibrated", "worse_than_none") for r in self["rows"])

    def table(self) -> str:
        """The table `compare` prints."""
        rp = self["rest_points"]
        models = {r.get("model", "base") for r in self["rows"]}
        names = [r["method"] if len(models) == 1 else f"{r['method']} ({r.get('model', 'base')})"
                 for r in self["rows"]]
        w = max([10] + [len(n) + 2 for n in names])
        hdr = (f"{'method':<{w}}{'points':>7}{'fit ms':>9}{'before mg':>11}{'after mg':>10}"
               f"{'R (eq.21)':>11}  status")
        lines = [f"{self['input']}: {rp['train']} training / {rp['heldout']} held-out rest points "
                 f"({self['split']})",
                 f"fitted on {self['training']}; scored on {self['heldout']}: {self['metric']}\n",
                 hdr, "-" * (len(hdr) + 20)]
        for r, name in zip(self["rows"], names):
            head = f"{name:<{w}}{r['points']:>7}{r['fit_ms']:9.1f}{r['error_before_mg']:11.2f}"
            if r["status"] in ("calibrated", "worse_than_none"):
                imp = f"{r['improvement_pct']:.0f} %" if r["improvement_pct"] is not None else "-"
                verdict = "ok" if r["status"] == "calibrated" else \
                    f"WORSE than no calibration ({r['error_after_mg'] / r['error_before_mg']:.1f}x)"
                lines.append(f"{head}{r['error_after_mg']:10.3f}{imp:>11}  {verdict}")
            else:
                lines.append(f"{head}{'-':>10}{'-':>11}  FAILED: {r['reason']}")
        return "\n".join(lines)


class StepsResult(Record):
    """`report HISTORY`: the model steps of a diagnose history (steps), and the figure (plot)
    and page (report) written, if any."""

    def to_json(self) -> str:
        return json.dumps(self["steps"])

    def table(self) -> str:
        """The table `report` prints: each step, its held-out error and its change."""
        lines = [f"{'step':<5}{'model':<36}{'held-out mg':>12}{'floor mg':>10}{'change':>9}  named next"]
        prev = None
        for k, st in enumerate(self["steps"], 1):
            e = st["heldout_error_mg"]
            ch = "" if prev is None else f"{100 * (e - prev) / prev:+.0f} %"
            model = printable(st["model"])[:200]   # from the file: no terminal escapes
            lines.append(f"{k:<5}{model:<36}{e:12.2f}{st['noise_floor_mg']:10.2f}{ch:>9}  "
                         f"{printable(st['missing_effect'] or '-')[:100]}")
            prev = e
        return "\n".join(lines)


class BoardReport(Record):
    """`report PULLED_DIR`: a pulled board's summary (boardlog.summary), the sample rate it
    logged at (None: no boot record) and the page written (report), if any."""

    def to_json(self) -> str:
        return json.dumps(self["summary"])

    def table(self) -> str:
        """The table `report` prints: each calibration the board made."""
        rate = self["rate_hz"]
        lines = [f"{'number':>6} {'hours':>7} {'status':<34} {'points':>6}  kxx      kyy      kzz      "
                 "ox mg   oy mg   oz mg"]
        for c in self["summary"]["calibrations"]:
            h = f"{c['index'] / rate / 3600:7.2f}" if rate else "      -"
            lines.append(f"{c['number']:>6} {h} {c['status']:<34} {c['points']:>6}  {c['kxx']:.5f}  "
                         f"{c['kyy']:.5f}  {c['kzz']:.5f}  {c['ox'] * 1e3:6.2f}  "
                         f"{c['oy'] * 1e3:6.2f}  {c['oz'] * 1e3:6.2f}")
            for name, e in c.get("effects", {}).items():   # a composed model's EFFECT records
                vals = " ".join(f"{n}={v:+.4g}" for n, v in e["params"].items())
                lines.append(f"{'':>6} effect {name}: {vals} {e['unit']} (reference "
                             f"{e['ref_temp']:g} degC)")
        lines += [board_discovery_line(d, rate) for d in self["summary"].get("discoveries", [])]
        if self["summary"].get("deployed"):
            lines.insert(0, deployed_line(self["summary"]["deployed"]))
        return "\n".join(lines)


def deployed_line(s: dict) -> str:
    """The settings deploy recorded on the board (board/settings.py), as its command line gave
    them: the app options away from their unset value."""
    opts = " ".join(f"--{k.replace('_', '-')}" + ("" if v is True else f" {v}")
                    for k, v in sorted(s.get("options", {}).items()) if v not in (None, False))
    return f"deployed with {opts} (board {s.get('board')}, modules as .{s.get('modules')})"


def board_discovery_line(d: dict, rate_hz: int | None = None) -> str:
    """One DISCOVERY record of a board (boardlog.summary's form), as `pull` and `report` say it:
    when, the effect adopted or the closest candidate, the held-out error's change, the blocks."""
    when = f"sample {d['index']}" + (f" ({d['index'] / rate_hz / 3600:.1f} h)" if rate_hz else "")
    if d["closest"] is None:
        return (f"discovery at {when}: no candidate testable (too few held-out points or "
                "blocks, or no spread in temperature, time or supply)")
    change = f"held-out error {d['change_pct']:+.0f} %" if d["change_pct"] is not None else ""
    blocks = f"better in {d['blocks_better']} of {d['blocks']} held-out blocks"
    vals = " ".join(f"{n}={v:+.4g}" for n, v in d.get("params", {}).items())
    if "+" in (d["adopted"] or ""):    # a model of two effects: the parameters are one's
        vals = f"{d['params_effect']} {vals}"
    if d["adopted"]:
        return (f"discovery at {when}: ADOPTED {d['adopted']} ({change}, {blocks}): "
                f"{vals} {d.get('unit', '')}".rstrip())
    return f"discovery at {when}: nothing adopted; closest {d['closest']} ({change}, {blocks})"


class ApplyResult(Record):
    """`apply`: the file written (output), samples calibrated, how many were past the device's
    full scale (clipped, range_g), and the effects applied on the host (host_only).  (Samples
    given as an array or frame come back calibrated as the same kind instead.)"""

    def _repr_fields(self) -> str:
        return f"{self['samples']} samples -> {self['output']}, {self['clipped']} clipped"

    def report(self) -> str:
        """The line `apply` says."""
        if self["host_only"]:
            how = ("applied on the host in float64: the device has no form for "
                   + ", ".join(self["host_only"]))
        else:
            how = f"the device's apply at +-{self['range_g']} g" + (
                f"; {self['clipped']} samples past that full scale were clipped, as the device's "
                "would be: --range 4, 8 or 16 keeps them" if self["clipped"] else "")
        return f"wrote {self['samples']} calibrated samples to {self['output']} ({how})"
