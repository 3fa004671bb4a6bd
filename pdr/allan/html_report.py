"""A self-contained HTML page of an Allan-variance report (plots embedded as base64 PNG)."""

from __future__ import annotations

import base64
import html
from collections.abc import Mapping
from typing import Any

from pdr.allan.grade import REFERENCE, REFERENCE_SHORT
from pdr.allan.noise_model import TERMS
from pdr.allan.units import headline_unit

_CSS = """
body{font-family:system-ui,-apple-system,Segoe UI,Roboto,sans-serif;margin:2em;max-width:70em;color:#222}
table{border-collapse:collapse;margin:0.6em 0 1.4em}td,th{border:1px solid #ccc;padding:0.25em 0.6em;text-align:right}
th{background:#f3f3f3}td.l,th.l{text-align:left}.flag{color:#a40}.na{color:#888}img{max-width:100%}
h2{border-bottom:2px solid #ddd;padding-bottom:0.2em}code{background:#f6f6f6;padding:0 0.2em}
"""
_SENSOR_TITLE = {"gyro": "Gyroscope", "acc": "Accelerometer"}
_TERM_TITLE = {"Q": "quantisation Q", "N": "white noise N", "B": "bias instability B", "K": "rate random walk K",
               "R": "rate ramp R"}


def _e(x: Any) -> str:
    return html.escape(str(x))


def _num(v: Any, digits: int = 4) -> str:
    if v is None:
        return '<span class="na">-</span>'
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        return _e(v)
    return f"{v:.{digits}g}"


def _table(head: list[str], rows: list[list[str]], left: int = 1) -> str:
    th = "".join(f'<th class="{"l" if i < left else ""}">{h}</th>' for i, h in enumerate(head))
    body = "".join("<tr>" + "".join(f'<td class="{"l" if i < left else ""}">{c}</td>' for i, c in enumerate(r))
                   + "</tr>" for r in rows)
    return f"<table><tr>{th}</tr>{body}</table>"


def _terms_table(sensor: str, s: Mapping[str, Any], axes: list[str]) -> str:
    rows = []
    for k in TERMS:
        unit = headline_unit(sensor, k)
        row = [f"{_TERM_TITLE[k]} [{_e(unit)}]"]
        for a in axes:
            ax = s[a]
            v = ax["datasheet"][k][unit]
            if v is None:
                ub = ax.get("datasheet_upper_bound", {}).get(k, {}).get(unit)
                cell = f'<span class="na" title="{_e(ax["fit"]["reason"][k])}">unresolved (&lt; {_num(ub, 3)})</span>'
            else:
                se = ax["fit"]["std_error"][k]
                si = ax[k]
                rel = f" &plusmn; {100 * se / si:.2g} %" if se is not None and si else ""
                cell = f"{_num(v)}{rel}"
            if k in ("N", "B", "K"):
                sv = ax["datasheet_slopes"][k][unit]
                cell += f'<br><small>slope reading: {_num(sv)}</small>'
            row.append(cell)
        rows.append(row)
    return _table(["term (fit, weighted NNLS)", *axes], rows)


def _impact(s: Mapping[str, Any]) -> str:
    imp = s.get("pdr_impact")
    if not imp:
        return ""
    rows = [[_e(a), _num(v["bias_deg_h"], 3), _e(v["bias_source"]), _e(v["readable"]["2pct"]),
             _e(v["readable"]["3pct"]), _e(v["readable"]["3deg"])] for a, v in imp["axes"].items()]
    rows += [[f"<i>{REFERENCE_SHORT} Table 3, consumer</i>", "25", "paper", "5.5 min", "8.3 min", "7.2 min"],
             [f"<i>{REFERENCE_SHORT} Table 3, tactical</i>", "1", "paper", "2.3 h", "3.4 h", "3.0 h"],
             [f"<i>{REFERENCE_SHORT} Table 3, navigation</i>", "0.0035", "paper", "27 days", "41 days", "35 days"]]
    w = imp["walker"]
    out = (f"<h3>PDR impact of the gyro bias instability</h3><p>Simulated PDR ({REFERENCE_SHORT} eqs. 20-22): "
           "walker at "
           f"{w['step_length_m']:g} m steps, {w['step_rate_hz']:g} steps/s, gyro integrated at "
           f"{w['gyro_rate_hz']:g} Hz, "
           "bias uncompensated.</p>"
           + _table(["axis", "bias [deg/h]", "from", "2 % rel. position error", "3 % rel. position error",
                     "3 deg heading error"], rows))
    sf = imp.get("scale_factor")
    if sf:
        out += ("<h3>PDR impact of a gyro scale-factor error (180 deg turn, then walking; Table 4)</h3>"
                + _table(["scale factor error [%]", "constant heading error [deg]",
                          "constant relative position error [%]",
                          "source"], [[_num(sf["error_pct"], 3), _num(sf["heading_error_deg"], 3),
                                       _num(sf["rel_position_error_pct"], 3), _e(sf["source"])]]))
    return out


def _quality(s: Mapping[str, Any]) -> str:
    q = s.get("quality")
    if not q:
        return ""
    rows = [["samples (used)", f"{q['n_samples']} ({q['n_used']})"], ["duration [s]", _num(q["duration_s"], 6)],
            ["rate [Hz]", _num(q["rate_hz"], 6)], ["timing jitter [%]", _num(100 * q["jitter"], 3)],
            ["gaps", str(len(q["gaps"]))], ["resampled", str(q["resampled"])],
            ["motion intervals", str(len(q["motion"]))]]
    return _table(["stream", _e(q["kind"])], rows)


def _sensor_section(name: str, s: Mapping[str, Any], png: bytes | None) -> str:
    axes = [a for a in ("x", "y", "z") if a in s]
    parts = [f"<h2>{_SENSOR_TITLE.get(name, name)}</h2>"]
    if png:
        parts.append(f'<img alt="{_e(name)} Allan deviation" src="data:image/png;base64,'
                     f'{base64.b64encode(png).decode("ascii")}">')
    parts.append(_terms_table(name, s, axes))
    fit_rows = [[_e(a), _num(s[a]["fit"]["chi2_reduced"], 3), _num(s[a]["slopes"]["tau_min_s"], 3),
                 "<br>".join(_e(n) for n in s[a]["slopes"]["notes"]) or "-"] for a in axes]
    parts.append(_table(["axis", "reduced chi2 of the fit", "tau_min [s]", "slope-reading notes"], fit_rows))
    g = s["grade"]
    grows = [[_e(c.get("axis") or "-"), _e(c["parameter"].replace("_", " ")), _num(c["value"], 3), _e(c["unit"]),
              _e(c["grade"])] for c in g["calls"]]
    parts.append(f"<h3>Grade ({REFERENCE_SHORT}, Table 1): {_e(g['overall'])}</h3>"
                 + _table(["axis", "parameter", "measured", "unit", "grade"], grows, left=2)
                 + _table(["Table 1", "unit", "navigation", "tactical", "consumer"],
                          [[_e(k), _e(v["unit"]), _num(v["navigation"]), _num(v["tactical"]), _num(v["consumer"])]
                           for k, v in g["table1"].items()]) + f"<p><small>{_e(g['note'])}</small></p>")
    parts.append(_impact(s))
    f = s["filter"]["sensor"]
    parts.append("<h3>Filter noise parameters (largest over axes)</h3>" + _table(
        ["parameter", "value"], [[_e(k), _num(v) if not isinstance(v, str) else _e(v)] for k, v in f.items()]))
    parts.append(_quality(s))
    flags = s.get("flags", [])
    if flags:
        parts.append("<h3>Flags</h3><ul>" + "".join(f'<li class="flag">{_e(x)}</li>' for x in flags) + "</ul>")
    return "\n".join(parts)


def _source_name(source: str) -> str:
    """The recording's file name: never a directory of the machine that made the report (a server's temp path)."""
    return str(source).replace("\\", "/").rstrip("/").split("/")[-1] or "recording"


def render(data: Mapping[str, Any], pngs: Mapping[str, bytes]) -> str:
    """The HTML page of a report dictionary (:func:`pdr.allan.report.report_dict`) with its PNG plots."""
    rec = data["recording"]
    t = rec.get("temperature")
    file_name = _source_name(rec["source"])
    rows = [["source", _e(file_name)], ["format", _e(rec["format"])],
            ["device", _e(", ".join(f"{k}={v}" for k, v in rec["device"].items() if v))],
            ["duration [s]", _num(rec["duration_s"], 6)],
            ["temperature [degC]", "not recorded" if not t else
             f"mean {_num(t['mean_degC'], 4)}, range {_num(t['min_degC'], 4)}-{_num(t['max_degC'], 4)}, "
             f"change {_num(t['change_degC'], 3)}"]]
    for name in ("gyro", "acc"):
        if name in data:
            s = data[name]
            rows.append([f"{name} rate [Hz] / samples", f"{_num(s['rate_hz'], 6)} / {s['n_samples']}"])
    body = [f"<h1>Allan-variance report: {_e(file_name)}</h1>",
            _table(["recording", ""], rows)]
    if data.get("flags"):
        body.append("<h3>Flags</h3><ul>" + "".join(f'<li class="flag">{_e(x)}</li>' for x in data["flags"]) + "</ul>")
    for name in ("gyro", "acc"):
        if name in data:
            body.append(_sensor_section(name, data[name], pngs.get(name)))
    body.append("<p><small>Overlapping Allan deviation with confidence intervals from equivalent degrees of freedom "
                "(Greenhall-Riley); IEEE noise model AVAR = 3Q&sup2;/&tau;&sup2; + N&sup2;/&tau; + "
                "(2 ln2/&pi;)B&sup2; + "
                "K&sup2;&tau;/3 + R&sup2;&tau;&sup2;/2 fitted by weighted non-negative least squares; all numbers in "
                "<code>report.json</code>. Grades, PDR impact and noise-term reading after "
                f"{_e(REFERENCE)}.</small></p>")
    return (f"<!DOCTYPE html><html><head><meta charset=\"utf-8\"><title>Allan-variance report: {_e(file_name)}</title>"
            f"<style>{_CSS}</style></head><body>{''.join(body)}</body></html>\n")
