"""The figures of `make bench` and the page they make, docs/performance.md.

A benchmark module records each figure it measures, with every repeated value, so that the page shows the
median and the range instead of one run's number::

    from report import record, record_ratio

    record("modes, 100 speeds", seconds_per_run, "s", goal="well under 1 s")
    record_ratio("chart vs solve_ivp", t_ivp_per_point, t_chart_per_point, goal=">= 100x")

``benchmarks/run_all.py`` runs the modules, sets the command that reproduces each module's figures
(:func:`set_source`) and writes the page (:func:`write_page`) with the machine, the date and the commit.
"""

from __future__ import annotations

import datetime
import os
import platform
import statistics
import subprocess
from dataclasses import dataclass, field
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
PAGE = REPO / "docs" / "performance.md"


@dataclass
class Figure:
    """One measured figure: every value of its repeated runs, its unit, goal and reproducing command."""

    name: str
    values: list[float]
    unit: str
    goal: str | None = None
    command: str = ""
    note: str = ""
    ratio: bool = False  # values are ratios of runs measured side by side

    @property
    def median(self) -> float:
        return float(statistics.median(self.values))

    def cell(self, x: float) -> str:
        """A number in a table cell: 4 significant digits, thousands separated."""
        if x == 0 or not (abs(x) < 1e-3 or abs(x) >= 1e6):
            return f"{x:,.4g}" if abs(x) < 1e4 else f"{x:,.0f}"
        return f"{x:.3g}"


@dataclass
class _State:
    figures: list[Figure] = field(default_factory=list)
    source: str = ""


_STATE = _State()


def set_source(module: str) -> None:
    """Name the benchmark module now running: its figures get the command that re-runs it."""
    _STATE.source = module


def record(
    name: str,
    values,
    unit: str,
    goal: str | None = None,
    command: str | None = None,
    note: str = "",
) -> Figure:
    """Record a figure from one value per repeated run (a number or a sequence of numbers).

    Parameters
    ----------
    name : str, what was measured (one line).
    values : float or sequence of float, one per run; the page shows their median and min-max range.
    unit : str, e.g. "s", "msg/s", "steps/s", "%".
    goal : str or None, the target as text (">= 2,000"), shown beside the figure.
    command : str or None, the command that reproduces it (default: run_all.py with the current module).
    note : str, a short remark shown in the table.
    """
    vals = [float(values)] if isinstance(values, int | float) else [float(v) for v in values]
    if not vals:
        raise ValueError(f"figure '{name}' has no values")
    cmd = command or (f".venv/bin/python benchmarks/run_all.py {_STATE.source}" if _STATE.source else "")
    fig = Figure(name, vals, unit, goal, cmd, note)
    _STATE.figures.append(fig)
    return fig


def record_ratio(name: str, numerators, denominators, goal: str | None = None, note: str = "", **kw) -> Figure:
    """Record the ratios of paired runs measured side by side (numerator_i / denominator_i), unit 'x'."""
    nums, dens = list(numerators), list(denominators)
    if len(nums) != len(dens) or not nums:
        raise ValueError(f"ratio '{name}': {len(nums)} numerators for {len(dens)} denominators")
    fig = record(name, [a / b for a, b in zip(nums, dens, strict=True)], "x", goal, note=note, **kw)
    fig.ratio = True
    return fig


def figures() -> list[Figure]:
    return list(_STATE.figures)


def reset() -> None:
    _STATE.figures.clear()
    _STATE.source = ""


def machine() -> dict:
    """CPU model, cores usable by this process, RAM (GiB), OS and Python of this machine."""
    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    ram = None
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemTotal:"):
                ram = int(line.split()[1]) / 2**20  # kB -> GiB
    except OSError:
        pass
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    return {
        "cpu": cpu,
        "cores": cores,
        "ram_gib": ram,
        "os": f"{platform.system()} {platform.release()}",
        "python": platform.python_version(),
    }


def commit() -> str:
    """The checked-out commit, with '-dirty' if tracked files differ from it ('unknown' outside git)."""
    try:
        head = subprocess.run(["git", "rev-parse", "HEAD"], cwd=REPO, capture_output=True, text=True, check=True)
        dirty = subprocess.run(["git", "status", "--porcelain", "-uno"], cwd=REPO, capture_output=True, text=True)
    except (OSError, subprocess.CalledProcessError):
        return "unknown"
    return head.stdout.strip() + ("-dirty" if dirty.stdout.strip() else "")


def render(figs: list[Figure], info: dict, when: str, rev: str, ran: list[str], skipped: list[str]) -> str:
    """The markdown page."""
    ram = f"{info['ram_gib']:.1f} GiB RAM" if info.get("ram_gib") else "RAM unknown"
    lines = [
        "# Performance",
        "",
        "Generated by `make bench` (`benchmarks/run_all.py`); do not edit by hand. Every figure is the median over",
        "the runs listed in its row, with the range (min-max) of those runs; ratios are of runs measured side by",
        "side in the same benchmark. The machine is shared by other work, so single runs vary: compare medians,",
        "and re-run a row with its command.",
        "",
        f"* machine: {info['cpu']}, {info['cores']} cores, {ram}; {info['os']}, Python {info['python']}",
        f"* date: {when}",
        f"* commit: `{rev}`",
        f"* benchmarks run: {', '.join(ran) or 'none'}" + (f"; not run: {', '.join(skipped)}" if skipped else ""),
        "",
        "| figure | median | range (runs) | unit | goal | command |",
        "|---|---|---|---|---|---|",
    ]
    for f in figs:
        rng = f"{f.cell(min(f.values))} - {f.cell(max(f.values))} ({len(f.values)})"
        name = (f.name + (f" ({f.note})" if f.note else "")).replace("|", "\\|")  # a bar would end the cell
        cmd = f"`{f.command}`" if f.command else ""
        lines.append(f"| {name} | {f.cell(f.median)} | {rng} | {f.unit} | {f.goal or ''} | {cmd} |".replace("\n", " "))
    return "\n".join(lines) + "\n"


def write_page(path: Path = PAGE, ran: list[str] | None = None, skipped: list[str] | None = None) -> Path:
    """Write the page of every figure recorded so far (atomically: a failed write leaves the old page)."""
    when = datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d %H:%M UTC")
    text = render(figures(), machine(), when, commit(), ran or [], skipped or [])
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".part")
    tmp.write_text(text)
    tmp.replace(path)
    return path
