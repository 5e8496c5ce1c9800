"""amb_dynamics has no import cycle: its modules' imports (module level and inside functions) form a DAG.

The graph is read from the sources with ast (nothing is imported), so an import hidden in a function to dodge a
cycle at load time (as estimate <-> estimate_opt once did) counts too.
"""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = "amb_dynamics"
ROOT = Path(__file__).resolve().parents[1] / "src" / "amb_dynamics" / PACKAGE


def module_name(path: Path, root: Path) -> str:
    parts = list(path.relative_to(root.parent).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def import_graph(sources: dict[str, tuple[str, bool]]) -> dict[str, set[str]]:
    """Edges module -> modules of the package it imports; ``sources``: name -> (code, is_package)."""
    names = set(sources)
    graph: dict[str, set[str]] = {name: set() for name in names}
    for name, (code, is_pkg) in sources.items():
        here = name if is_pkg else name.rpartition(".")[0]  # the package relative imports start from
        for node in ast.walk(ast.parse(code)):
            targets: list[str] = []
            if isinstance(node, ast.Import):
                targets = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom):
                if node.level:
                    base = here.rsplit(".", node.level - 1)[0] if node.level > 1 else here
                    mod = f"{base}.{node.module}" if node.module else base
                else:
                    mod = node.module or ""
                # "from . import x" names a submodule when one exists, else an attribute of mod
                subs = [f"{mod}.{alias.name}" for alias in node.names if f"{mod}.{alias.name}" in names]
                targets = subs or [mod]
            for target in targets:
                while target and target not in names:  # a.b.c (an attribute) -> a.b
                    target = target.rpartition(".")[0]
                if target and target != name:
                    graph[name].add(target)
    return graph


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                found.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def package_sources() -> dict[str, tuple[str, bool]]:
    return {
        module_name(p, ROOT): (p.read_text(), p.name == "__init__.py")
        for p in ROOT.rglob("*.py")
        if "__pycache__" not in p.parts
    }


def test_detector_finds_a_call_time_cycle():
    # positive control: the old estimate <-> estimate_opt pair, one side importing inside a function
    sources = {
        "pkg": ("", True),
        "pkg.estimate": ("def fit():\n    from .estimate_opt import refine\n    return refine()\n", False),
        "pkg.estimate_opt": ("from .estimate import MapFit\n", False),
        "pkg.errors": ("", False),
    }
    assert cycles(import_graph(sources)) == [["pkg.estimate", "pkg.estimate_opt"]]
    sources["pkg.estimate_opt"] = ("from . import errors\n", False)
    assert cycles(import_graph(sources)) == []


def test_amb_dynamics_has_no_import_cycle():
    sources = package_sources()
    graph = import_graph(sources)
    assert len(graph) >= 25 and f"{PACKAGE}.estimator.fit" in graph  # the walk saw the whole package
    assert f"{PACKAGE}.estimator.refine" in graph[f"{PACKAGE}.estimator.fit"]
    assert cycles(graph) == []


def test_nodes_do_not_import_scipy_signal_at_start():
    """scipy.signal takes ~1.4 s to import here (more than the rest of a node's imports together), and every node
    and amb-rig start by importing amb_dynamics' controller code: the few functions that need scipy.signal import
    it when called."""
    import subprocess
    import sys

    for module in ("amb_plant.node", "amb_controller.node", "base_motion.node", "stability_monitor.node",
                   "amb_bringup.rig"):  # fmt: skip
        code = f"import sys, {module}; print('scipy.signal' in sys.modules)"
        out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
        assert out.returncode == 0 and out.stdout.strip() == "False", (module, out.stdout, out.stderr[-1000:])
