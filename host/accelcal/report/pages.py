"""One self-contained HTML file a person reads: a diagnose run (`diagnose --report DIR`), a model
discovery history (`report HISTORY --html FILE`) or a pulled board log (`report DIR --html FILE`).
Figures are embedded as PNG data, styles inline: it opens from disk with no server and no
network.  Its numbers are the JSON's: the run's JSON is embedded as it is (a script block of type
application/json) and every table cell is formatted from it."""
from __future__ import annotations

import base64
import html
import json
from pathlib import Path

STYLE = """
body { font-family: system-ui, sans-serif; max-width: 1100px; margin: 2em auto; color: #222; }
h1 { font-size: 1.5em; } h2 { font-size: 1.2em; border-bottom: 1px solid #ccc; margin-top: 2em; }
table { border-collapse: collapse; margin: 0.5em 0; } td, th { padding: 3px 10px; text-align: right;
border-bottom: 1px solid #eee; } th { background: #f4f4f4; } td.l, th.l { text-align: left; }
.named { background: #eef7ee; padding: 0.6em 1em; border-left: 4px solid #3a3; }
.none { background: #f7f3e8; padding: 0.6em 1em; border-left: 4px solid #c93; }
pre { background: #f4f4f4; padding: 0.6em; overflow-x: auto; } img { max-width: 100%; }
figcaption { font-size: 0.9em; color: #555; margin-bottom: 1.5em; }
"""


def _e(v) -> str:
    return html.escape(str(v))


def _num(v, fmt: str = ".3f") -> str:
    return "–" if v is None else format(v, fmt)


def _table(head: list[str], rows: list[list[str]], left: int = 1) -> str:
    th = "".join(f'<th class="{"l" if i < left else ""}">{_e(h)}</th>' for i, h in enumerate(head))
    body = "".join("<tr>" + "".join(f'<td class="{"l" if i < left else ""}">{c}</td>'
                                    for i, c in enumerate(r)) + "</tr>" for r in rows)
    return f"<table><tr>{th}</tr>{body}</table>"


def _figure(png: bytes, caption: str) -> str:
    data = base64.b64encode(png).decode("ascii")
    return (f'<figure><img alt="{_e(caption)}" src="data:image/png;base64,{data}">'
            f"<figcaption>{_e(caption)}</figcaption></figure>")


def _page(title: str, body: str, data: dict) -> str:
    # Script data ends at "</script" and "<!--" changes how it is parsed (HTML spec, "script
    # data"): every <, > and & in the JSON (only ever inside strings) becomes its \\u escape,
    # which JSON.parse reads back to the same text.
    blob = json.dumps(data).replace("<", "\\u003c").replace(">", "\\u003e").replace("&", "\\u0026")
    return (f'<!DOCTYPE html><html lang="en"><head><meta charset="utf-8"><title>{_e(title)}'
            f"</title><style>{STYLE}</style></head><body><h1>{_e(title)}</h1>{body}"
            f'<script type="application/json" id="accelcal-data">{blob}</script></body></html>\n')


CAPTIONS = {
    "residuals.png": "Held-out residual | |a| − 1 g | in mg against each regressor, for the model "
                     "as it stands: dots the rest points, the line their binned mean with its 95 % "
                     "interval, the grey band the noise floor; points beyond the y-range are ▲▼ at "
                     "its edge, counted. A structure beyond the band is what the model misses.",
    "candidates.png": "Held-out calibration error (mg) of the model and of each catalogue effect "
                      "added to it; the dashed line is the noise floor.",
    "step.png": "The same panels before and after the model's last effect, on one y-range: "
                "where the error fell.",
    "steps.png": "Held-out calibration error (mg) at each model step, and the noise floor.",
    "calibrations.png": "The board's calibrations over its running time: each parameter's value "
                        "at each calibration (scale and misalignment dimensionless, offsets in mg).",
}


def diagnose_page(out: dict, pngs: dict[str, bytes], steps: list[dict] | None = None) -> str:
    """The report of one diagnose run: out is its JSON (diagnose --json)."""
    f = out["input"]
    body = [f"<p>File <code>{_e(f)}</code>, model <b>{_e(out['model'])}</b>, "
            f"{out['rest_points']['train']} training and {out['rest_points']['heldout']} held-out "
            f"rest points ({_e(out['split'])}).</p>"]
    blocks = out.get("heldout_blocks")
    body.append("<h2>Held-out error</h2>" + _table(
        ["model", "held-out error (mg)", "noise floor (mg)", "wrist floor (mg)", "training points",
         "held-out points", "held-out blocks"],
        [[_e(out["model"]), _num(out["heldout_error_mg"]), _num(out["noise_floor_mg"]),
          _num(out.get("wrist_floor_mg")), str(out["rest_points"]["train"]),
          str(out["rest_points"]["heldout"]), _num(blocks, "d")]])
        + "<p>The noise floor is the sensor's noise alone; the wrist floor what a complete model "
          f"would still leave, from {_num(out.get('wrist_floor_pairs'), 'd')} pairs of rest means "
          "of nearly the same posture close in time and temperature (the model discovery "
          "page of the docs, What remains).</p>")
    named = out.get("missing_effect")
    if named:     # the explanation opens with the effect's physics: said once
        body.append(f'<h2>Named effect: {_e(named)}</h2><div class="named"><p>'
                    f"{_e(out['explanation'])}</p></div>")
    else:
        body.append(f'<h2>No effect named</h2><div class="none"><p>{_e(out["explanation"])}</p>'
                    "</div>")
    rows = []
    for c in out["candidates"]:
        params = c.get("params") or {}
        ptxt = ", ".join(f"{k}={v:g}" for k, v in params.items())
        if params:
            ptxt += f" ({_e(c.get('param_unit', ''))})"
        share = _num(c["blocks_improved_pct"], ".0f")
        if c["blocks_improved_pct"] is not None and c.get("blocks"):   # the count beside the share
            share = f"{c['blocks_improved']} of {c['blocks']} ({share} %)"
        if c.get("evidence") == "weak":   # few blocks (acal/discover/rule.py clear)
            share += ", weak evidence"
        rows.append([_e("+" + c["effect"]), _num(c["heldout_error_mg"]),
                     _num(c["improvement_pct"], ".1f"), share,
                     _e(ptxt if params else c.get("untestable", ""))])
        j = c.get("device_folds")
        if j:   # the curve judged again as the device fits it (pipeline/foldjudge.py)
            rows.append([_e(f"+{c['effect']} as the device fits it, each half held out in turn"),
                         _num(j["after_mg"]), _num(j["improvement_pct"], ".1f"),
                         f"{j['blocks_improved']} of {j['blocks']}", "named" if j["named"] else ""])
    body.append("<h2>Candidates</h2>" + _table(
        ["effect added", "held-out error (mg)", "improvement (%)", "held-out blocks improved",
         "fitted parameters"], rows))
    wf = out.get("where_it_fails", {})
    if wf:
        body.append("<h2>Where the model fails</h2><p>Mean held-out residual per quintile of each "
                    "regressor (mg), its spread across the quintiles and its correlation.</p>"
                    + _table(["regressor", "correlation", "spread (mg)", "Q1", "Q2", "Q3", "Q4",
                              "Q5"],
                             [[_e(k), _num(w["corr"], "+.2f"), _num(w["range_mg"])]
                              + [_num(b, "+.3f") for b in w["quintile_mean_residual_mg"]]
                              for k, w in wf.items()]))
    for name, png in pngs.items():
        body.append(_figure(png, CAPTIONS.get(name, name)))
    if steps:
        body.append("<h2>Model steps so far</h2>" + _steps_table(steps))
    body.append("<h2>Next</h2><pre>" + _e("\n".join(next_commands(out))) + "</pre>")
    return _page(f"accelcal diagnose: {Path(f).name}", "".join(body), out)


def next_commands(out: dict) -> list[str]:
    f = out["input"]
    named = out.get("missing_effect")
    if named:
        m = f"{out['model']}+{named}"
        return [f"accelcal diagnose {f} --model {m} --history steps.jsonl --report report/",
                f"accelcal calibrate {f} --model {m} --save params.json",
                f"accelcal acquire --port PORT --hours 48 --model {m}   # the board fits it too"]
    return [f"accelcal calibrate {f} --model {out['model']} --save params.json",
            f"accelcal compare {f} --plots plots/   # every method on the same held-out points"]


def _steps_table(steps: list[dict]) -> str:
    rows, prev = [], None
    for k, s in enumerate(steps, 1):
        e = s["heldout_error_mg"]
        ch = "" if prev is None else f"{100 * (e - prev) / prev:+.0f} %"
        rows.append([str(k), _e(s["model"]), _num(e), _num(s["noise_floor_mg"]), ch,
                     _e(s.get("missing_effect") or "–")])
        prev = e
    return _table(["step", "model", "held-out error (mg)", "noise floor (mg)", "change",
                   "named next"], rows, left=2)


def history_page(path: str, steps: list[dict], pngs: dict[str, bytes]) -> str:
    body = [f"<p>Model discovery steps recorded in <code>{_e(path)}</code>.</p>",
            _steps_table(steps)]
    for name, png in pngs.items():
        body.append(_figure(png, CAPTIONS.get(name, name)))
    return _page(f"accelcal report: {Path(path).name}", "".join(body), {"steps": steps})


def board_page(folder: str, summ: dict, pngs: dict[str, bytes], rate_hz: int | None) -> str:
    """A pulled board log: its calibrations over time, counters, what was dropped."""
    cals = summ.get("calibrations", [])
    rows = []
    for c in cals:
        h = "–" if not rate_hz else f"{c['index'] / rate_hz / 3600:.2f}"
        eff = ", ".join(c.get("effects", {})) or "–"
        rows.append([str(c["number"]), h, _e(c["status"]), str(c["points"]), str(c["iterations"]),
                     _num(c["kxx"], ".5f"), _num(c["kyy"], ".5f"), _num(c["kzz"], ".5f"),
                     _num(c["ox"] * 1e3, ".2f"), _num(c["oy"] * 1e3, ".2f"),
                     _num(c["oz"] * 1e3, ".2f"), _e(eff)])
    body = [f"<p>Logs pulled into <code>{_e(folder)}</code>: {summ.get('boots', 0)} boot(s), "
            f"{len(cals)} calibration(s), {len(summ.get('rest_points', []))} rest point(s) "
            f"logged.</p>",
            "<h2>Calibrations over time</h2>" + _table(
                ["number", "running time (h)", "status", "points", "iterations", "kxx", "kyy",
                 "kzz", "ox (mg)", "oy (mg)", "oz (mg)", "effects"], rows)]
    for name, png in pngs.items():
        body.append(_figure(png, CAPTIONS.get(name, name)))
    found = summ.get("discoveries") or []
    if found:
        drows = []
        for d in found:
            h = "–" if not rate_hz else f"{d['index'] / rate_hz / 3600:.2f}"
            pars = ", ".join(f"{n} {v:+.4g}" for n, v in d.get("params", {}).items())
            if pars and "+" in (d["closest"] or ""):   # the parameters of one of its effects
                pars = f"{d['params_effect']}: {pars}"
            drows.append([h, _e(d["adopted"] or "–"), _e(d["closest"] or "–"),
                          str(d["heldout_before"]), str(d["heldout_after"]),
                          "–" if d["change_pct"] is None else f"{d['change_pct']:+.0f} %",
                          f"{d['blocks_better']} of {d['blocks']}",
                          _e(pars + (f" ({d['unit']})" if pars else ""))])
        body.append("<h2>Discovery on the board</h2><p>After a calibration the board fits each "
                    "effect of its catalogue on its fit points and scores it on rest points from "
                    "held-out 2-hour blocks; it adopts one only under the rule <code>diagnose</code> "
                    "names by. Held-out errors in the board's integers (sums of | |a|² − 1 |, "
                    "Q16 g²).</p>" + _table(
                        ["running time (h)", "adopted", "closest candidate", "held-out before",
                         "held-out after", "change", "blocks better", "its parameters"], drows))
    cnt = summ.get("counters")
    if cnt:
        body.append("<h2>Counters</h2>" + _table(list(cnt), [[str(v) for v in cnt.values()]], 0))
    dropped = summ.get("dropped") or []
    body.append("<h2>Dropped bytes</h2>" + ("<pre>" + _e("\n".join(dropped)) + "</pre>"
                                            if dropped else "<p>None: every record whole.</p>"))
    return _page(f"accelcal board log: {Path(folder).name}", "".join(body), summ)
