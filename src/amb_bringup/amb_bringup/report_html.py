"""HTML of the commissioning report (:mod:`.report`): one file, figures embedded as base64 PNGs, no external
resources.  A small inline script marks the body with the number of images and of broken ones once the page has
loaded (``data-images``, ``data-broken``), which a headless browser reads back."""

from __future__ import annotations

import base64
import datetime as dt
from html import escape
from pathlib import Path

from amb_dynamics.delay_margin import margin_text

MODES_SHOWN = 10
ZONE_COLOURS = {"A": "#cdeccd", "B": "#eef5c4", "C": "#fde2b8", "D": "#f8c4c0", "unstable": "#e39a94"}
STYLE = """
body { font-family: sans-serif; max-width: 70em; margin: 2em auto; color: #222; line-height: 1.4; }
h1 { font-size: 1.6em; } h2 { border-bottom: 1px solid #bbb; margin-top: 2em; }
table { border-collapse: collapse; margin: 0.5em 0; } td, th { border: 1px solid #ccc; padding: 2px 8px; }
th { background: #f0f0f0; text-align: left; } td.num { text-align: right; font-variant-numeric: tabular-nums; }
img { max-width: 100%; border: 1px solid #ddd; } .note { color: #555; } .warn { color: #a00; font-weight: bold; }
"""
CHECK = """
window.addEventListener('load', function () {
  var imgs = document.images, broken = 0;
  for (var i = 0; i < imgs.length; i++) { if (!imgs[i].complete || imgs[i].naturalWidth === 0) broken++; }
  document.body.setAttribute('data-images', String(imgs.length));
  document.body.setAttribute('data-broken', String(broken));
});
"""


def render(doc: dict) -> str:
    parts = [
        f"<h1>{escape(doc['title'])}</h1>",
        _p(
            f"Config {doc['config']}. Generated {dt.datetime.now(dt.UTC):%Y-%m-%d %H:%M} UTC by amb-rig report.", "note"
        ),
        "<h2>Rotor and controller</h2>",
        _p(doc["rotor"]),
        _table(["item", "value"], doc["controller"]),
        "<h2>Modes and Campbell diagram</h2>",
        *[_modes(s) for s in doc["modes"]],
        _p(doc["campbell"]),
        _figure(doc, "Campbell diagram"),
        "<h2>Sensitivity per AMB axis (ISO 14839-3)</h2>",
        _sensitivity(doc["sensitivity"]),
        *[_p(line, "warn") for line in doc["sensitivity_lines"]],
        _figure(doc, "Sensitivity of the digital loop (model)"),
        _measured(doc),
        "<h2>Unbalance response and vibration zones (ISO 14839-2)</h2>",
        _vibration(doc),
        _figure(doc, "Unbalance response"),
        "<h2>Stability chart of the operating envelope</h2>",
        _chart(doc),
        "<h2>The stability monitor's verdict</h2>",
        _monitor(doc.get("run")),
    ]
    body = "\n".join(p for p in parts if p)
    return (
        "<!DOCTYPE html>\n<html lang='en'><head><meta charset='utf-8'>"
        f"<title>{escape(doc['title'])}</title><style>{STYLE}</style><script>{CHECK}</script></head>\n"
        f"<body>\n{body}\n</body></html>\n"
    )


def _p(text: str, cls: str = "") -> str:
    return f"<p{f' class={cls!r}' if cls else ''}>{escape(str(text))}</p>"


def _table(head: list[str], rows, zone_col: int | None = None) -> str:
    out = ["<table><tr>" + "".join(f"<th>{escape(h)}</th>" for h in head) + "</tr>"]
    for row in rows:
        cells = []
        for i, v in enumerate(row):
            style = f" style='background:{ZONE_COLOURS[v]}'" if i == zone_col and v in ZONE_COLOURS else ""
            cls = " class='num'" if isinstance(v, int | float) else ""
            text = f"{v:.4g}" if isinstance(v, float) else str(v)
            cells.append(f"<td{cls}{style}>{escape(text)}</td>")
        out.append("<tr>" + "".join(cells) + "</tr>")
    return "\n".join(out) + "</table>"


def _figure(doc: dict, name: str) -> str:
    path = doc["figures"].get(name)
    if path is None:
        return ""
    data = base64.b64encode(Path(path).read_bytes()).decode("ascii")
    caption = f"<figcaption>{escape(name)}</figcaption>"
    return f"<figure><img alt='{escape(name)}' src='data:image/png;base64,{data}'>{caption}</figure>"


def _modes(speed: dict) -> str:
    d = speed["digital_loop"]
    verdict = "stable" if d["stable"] else "UNSTABLE"
    rows = [(m["frequency_hz"], m["damping_ratio"], m["whirl"]) for m in speed["modes"][:MODES_SHOWN]]
    line = (
        f"Digital loop at {d['rate_hz']:g} Hz (delay {d['delay_samples']}): {verdict}, max|mu| per sample "
        f"{d['spectral_radius_per_sample']:.7g}"
        + (f"; {margin_text(d['delay_margin'])}." if "delay_margin" in d else ".")
    )
    head = f"<h3>{speed['speed_rpm']:g} rpm</h3>" + _p(line, "" if d["stable"] else "warn")
    return head + _table(["frequency (Hz)", "damping ratio", "whirl"], rows)


def _sensitivity(sens: dict) -> str:
    rows = []
    for s in sens["speeds"]:
        for axis, a in s["axes"].items():
            rows.append((f"{s['speed_rpm']:g}", axis, a["peak_abs"], a["peak_db"], a["peak_hz"], a["zone"]))
    limits = ", ".join(f"{x:g}" for x in sens["zone_limits_abs"])
    text = (
        f"Model of the digital loop the rig runs ({sens.get('controller_law', '')}); zone limits |S| "
        f"A/B, B/C, C/D = {limits}."
    )
    return _p(text) + _table(["speed (rpm)", "axis", "peak |S|", "peak (dB)", "at (Hz)", "zone"], rows, zone_col=5)


def _measured(doc: dict) -> str:
    run = doc.get("run")
    if not run or not run.get("sensitivity"):
        why = "no run given (--bag)" if not run else "the run had no sensor-signal injection (amb-rig sensitivity)"
        return _p(f"Measured sensitivity: none: {why}.", "note")
    m = run["sensitivity"]
    p = m["peak"]
    err = m.get("max_rel_error_where_coherent")
    rows = [
        ("axis", m["axis"]),
        ("peak |S|", "-" if p["peak_abs"] is None else f"{p['peak_abs']:.4g} at {p['peak_hz']:.4g} Hz"),
        ("zone", p.get("zone") or "- (peak not resolved)"),
        ("frequency resolution", f"{m['resolution_hz']:g} Hz"),
        (
            "model agreement",
            "-"
            if err is None
            else f"{100 * err:.2f} % over {m['coherent_bins']} coherent bins "
            f"(at most {m['max_difference_in_random_errors']:.2g} x the estimate's random error)",
        ),
    ]
    fit = m.get("fitted_model")
    if fit:
        rows.append(("calibrated model", f"ki x{fit['ki_scale']:.4f}, ks x{fit['ks_scale']:.4f}, residual "
                     f"{100 * fit['rms_rel_residual']:.2f} % RMS"))  # fmt: skip
        rows.append(("zone at its peak", f"{fit['zone'] or '-'}: |S| {fit['peak_abs']:.4g} at {fit['peak_hz']:.4g} Hz"))
    return (
        "<h3>Measured on the running loop</h3>"
        + _table(["item", "value"], rows)
        + _figure(doc, f"Measured sensitivity {m['axis']}")
    )


def _vibration(doc: dict) -> str:
    unb, model = doc["unbalance"], doc["vibration_model"]
    if model is None:
        return _p(f"No unbalance response: {unb['missing']}.", "note")
    run = doc.get("run") or {}
    measured = (run.get("vibration") or {}).get("axes", {})
    rows = []
    for axis, z in model.items():
        got = measured.get(axis) or {}
        ratio = z["ratio_to_c_min"] if z["ratio_to_c_min"] is not None else "-"
        rows.append((axis, z["displacement_m"], ratio, z["zone"] or "-", got.get("m", "-"), got.get("zone", "-")))
    reason = next((z["reason"] for z in model.values() if z.get("reason")), None)
    head = ["axis", f"model at {unb['speed_rpm']:g} rpm (m)", "/ C_min", "zone", "run's last second (m)", "run zone"]
    return _table(head, rows, zone_col=3) + (_p(reason, "note") if reason else "")


def _chart(doc: dict) -> str:
    c = doc["chart"]
    if c["controller"] == "sampled":
        loop = (f"the digital loop the rig runs, {c['controller_rate_hz']:g} Hz, delay {c['delay_samples']}; "
                f"error bound per point up to {c['max_error_bound']:.2g}")  # fmt: skip
    else:
        loop = "continuous controller"
    text = f"{c['points']} points ({c['motion']}, {loop}): {c['unstable_points']} unstable."
    return _p(text, "warn" if c["unstable_points"] else "") + _figure(doc, f"Stability chart ({c['motion']})")


def _monitor(run: dict | None) -> str:
    if not run:
        return _p("No run given (--bag): the monitor's verdict comes from a recorded amb-rig run.", "note")
    mon = run.get("monitor")
    if not mon:
        return _p(f"{run['bag']}: the bag holds no report of the stability monitor (run without --no-monitor).")
    cls = "warn" if mon.get("unstable") == "true" else ""
    return _p(f"Run {run['bag']} ({run['duration_s']:.3g} s).", cls) + _table(["key", "value"], list(mon.items()))
