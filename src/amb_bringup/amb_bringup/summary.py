"""The summary of a run, from each node's final /diagnostics and each process's exit (dict and text)."""

from __future__ import annotations

from amb_ros.report_keys import read_peaks, read_vibration

from .supervisor import Child, describe_exit


def _num(values: dict, key: str, default=None):
    try:
        return float(values[key])
    except (KeyError, ValueError):
        return default


def build_summary(run: dict, children: list[Child], collector, errors: list[str]) -> dict:
    """Plain-data summary; ``ok`` is False if ``errors`` is not empty."""
    nodes = {}
    for c in children:
        diag = collector.get(c.spec.node) if (collector is not None and c.spec.node) else None
        nodes[c.spec.name] = {
            "pid": c.pid,
            "exit": describe_exit(c.popen.returncode),
            "exit_code": c.popen.returncode,
            "stopped_by_amb_rig": c.stopped_by_us,
            "log": str(c.log),
            "level": diag["level"] if diag else "NONE",
            "message": diag["message"] if diag else "no diagnostics received",
            "final": bool(diag and diag["final"]),
            "values": diag["values"] if diag else {},
        }
    out = {"ok": not errors, "errors": list(errors), **run, "nodes": nodes}
    plant = nodes.get("plant", {}).get("values", {})
    if plant:
        out["steps"] = int(_num(plant, "steps", 0))
        out["simulated_s"] = _num(plant, "simulated time (s)")
        out["wall_s"] = _num(plant, "wall time (s)")
        out["steps_per_s"] = _num(plant, "steps per second")
        gap = _num(plant, "air gap (m)")
        out["air_gap_m"] = gap
        out["peak_displacement"] = read_peaks(plant)
        if (vib := read_vibration(plant)) is not None:  # ISO 14839-2 grade of the run's last second (its end)
            out["vibration"] = vib
    ctl = nodes.get("controller", {}).get("values", {})
    if ctl:
        keys = ("samples answered", "samples lost", "saturated samples", "max current (A)", "ticks",
                "missed deadlines", "skipped ticks", "sensor losses")  # fmt: skip
        stats = {k: _num(ctl, k) for k in keys if k in ctl}
        stats.update({k: _num(ctl, k) for k in ctl if k.startswith(("compute ", "period error "))})
        out["controller"] = stats
    mon = nodes.get("monitor")
    if mon:
        v = mon["values"]
        out["stability"] = {"verdict": v.get("verdict", "none"), "unstable": v.get("unstable") == "true",
                            "rho": _num(v, "rho"), "rho_std": _num(v, "rho std"),
                            "periods_used": _num(v, "periods used"), "flag_raised_at_s": _num(v, "flag raised at (s)"),
                            "model_rho": _num(v, "model rho"), "model_mismatch": v.get("model mismatch") == "true",
                            "message": mon["message"]}  # fmt: skip
    return out


def format_summary(s: dict) -> str:
    lines = []
    head = f"amb-rig run: {s.get('mode')}, {s.get('motion')}, {s.get('duration_s')} s at {s.get('rate_hz'):g} Hz"
    verdict = "INTERRUPTED" if s.get("interrupted") else ("OK" if s["ok"] else "FAILED")
    lines.append(f"{head}  [{verdict}]")
    if "steps" in s:
        lines.append(
            f"  steps {s['steps']}   simulated {s.get('simulated_s') or 0:.6g} s   wall {s.get('wall_s') or 0:.3f} s"
            f"   {s.get('steps_per_s') or 0:.0f} steps/s"
        )
    if s.get("peak_displacement"):
        lines.append(f"  peak displacement (air gap {s.get('air_gap_m'):.3g} m):")
        for ch, p in s["peak_displacement"].items():
            flag = "  EXCEEDS AIR GAP" if (p["air_gap_ratio"] or 0) > 1 else ""
            lines.append(f"    {ch:<8} {p['m']:.4g} m   {p['air_gap_ratio']:.4g} x gap{flag}")
    if s.get("vibration"):
        v = s["vibration"]
        axes = ", ".join(f"{ch} {a['m']:.3g} m zone {a['zone']}" for ch, a in v["axes"].items())
        lines.append(f"  vibration over the last {v['window_s']:.3g} s (ISO 14839-2 vs C_min): {axes}")
    if s.get("controller"):
        c = s["controller"]
        text = ", ".join(f"{k} {v:g}" for k, v in c.items() if v is not None)
        lines.append(f"  controller: {text}")
    if s.get("stability"):
        st = s["stability"]
        lines.append(f"  stability monitor: {'UNSTABLE' if st['unstable'] else st['verdict']} - {st['message']}")
    if s.get("discovery", "LOCALHOST") != "LOCALHOST" or s.get("ended_by"):  # a run across hosts (split.py)
        ended = f", ended: {s['ended_by']}" if s.get("ended_by") else ""
        lines.append(f"  discovery: {s.get('discovery')}{ended}" + "".join(f"; {n}" for n in s.get("notes", [])))
    lines.append("  nodes:")
    for name, n in s["nodes"].items():
        lines.append(f"    {name:<12} {n['level']:<5} {n['exit']:<22} {n['message']}")
    for err in s["errors"]:
        lines.append(f"  error: {err}")
    if s.get("log_dir"):
        lines.append(f"  logs: {s['log_dir']}")
    return "\n".join(lines)
