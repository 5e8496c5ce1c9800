"""The summary of a run, from each node's final /diagnostics and each process's exit (dict and text)."""

from __future__ import annotations

from amb_ros.diag_keys import Controller, Key, Monitor, Plant, read_peaks, read_vibration

from .supervisor import Child, describe_exit


def _num(values: dict, key: Key | str, default=None):
    """A numeric value as float (the summary's JSON numbers), ``default`` if absent or malformed."""
    v = (key if isinstance(key, Key) else Key(key)).read(values)
    return default if v is None or isinstance(v, bool | str) else float(v)


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
        out["steps"] = int(_num(plant, Plant.steps, 0))
        out["simulated_s"] = _num(plant, Plant.simulated_time)
        out["wall_s"] = _num(plant, Plant.wall_time)
        out["steps_per_s"] = _num(plant, Plant.steps_per_second)
        gap = _num(plant, Plant.air_gap)
        out["air_gap_m"] = gap
        out["peak_displacement"] = read_peaks(plant)
        if (vib := read_vibration(plant)) is not None:  # ISO 14839-2 grade of the run's last second (its end)
            out["vibration"] = vib
    ctl = nodes.get("controller", {}).get("values", {})
    if ctl:
        keys = (Controller.samples_answered, Controller.samples_lost, Controller.saturated_samples,
                Controller.max_current, Controller.ticks, Controller.missed_deadlines, Controller.skipped_ticks,
                Controller.sensor_losses)  # fmt: skip
        stats = {k.text: _num(ctl, k) for k in keys if k.text in ctl}
        stats.update({k: _num(ctl, k) for k in ctl if k.startswith(("compute ", "period error "))})
        out["controller"] = stats
    mon = nodes.get("monitor")
    if mon:
        v = mon["values"]
        out["stability"] = {"verdict": Monitor.verdict.read(v) or "none", "unstable": Monitor.unstable.read(v) is True,
                            "rho": _num(v, Monitor.rho), "rho_std": _num(v, Monitor.rho_std),
                            "rho_scatter": _num(v, Monitor.rho_scatter),
                            "periods_used": _num(v, Monitor.periods_used),
                            "flag_raised_at_s": _num(v, Monitor.flag_raised_at),
                            "model_rho": _num(v, Monitor.model_rho),
                            "model_mismatch": Monitor.model_mismatch.read(v) is True,
                            "message": mon["message"]}  # fmt: skip
    return out


def format_summary(s: dict) -> str:
    lines = []
    head = f"amb-rig run: {s.get('mode')}, {s.get('motion')}, {s.get('duration_s')} s at {s.get('rate_hz'):g} Hz"
    verdict = "INTERRUPTED" if s.get("interrupted") else ("OK" if s["ok"] else "FAILED")
    lines.append(f"{head}  [{verdict}]")
    if s.get("preflight"):
        lines.append(f"  preflight: {s['preflight']}")
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
