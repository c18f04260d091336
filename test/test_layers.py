"""The package's layers (docs/conventions.md, Layers): the core and the simulator are ROS-free, the wire
sits below io, nothing below the nodes imports a node module, and no two modules import each other."""

from __future__ import annotations

import ast
import itertools
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "gait_biofeedback"
ROS = ("rclpy", "builtin_interfaces", "diagnostic_msgs", "geometry_msgs", "sensor_msgs", "std_msgs",
       "std_srvs", "visualization_msgs", "rosgraph_msgs", "rcl_interfaces", "gait_biofeedback_msgs")


def _modules() -> dict[str, Path]:
    out = {}
    for path in PACKAGE.rglob("*.py"):
        parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
        out[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    return out


def _imports(path: Path) -> set[str]:
    """Every module a file imports, at the top or inside a function."""
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            found.add(node.module)
            found.update(f"{node.module}.{alias.name}" for alias in node.names)
    return found


def _layer_violations(prefix: str, forbidden: tuple[str, ...], allowed: tuple[str, ...] = ()) -> list[str]:
    bad = []
    for name, path in _modules().items():
        if not name.startswith(prefix) or name in allowed:
            continue
        for imported in _imports(path):
            if imported.split(".")[0] in ROS and "ros" in forbidden:
                bad.append(f"{name} imports {imported}")
            if any(imported == f or imported.startswith(f + ".") for f in forbidden):
                bad.append(f"{name} imports {imported}")
    return bad


def test_core_and_simulator_are_ros_free_and_import_nothing_above_them():
    above = ("ros", "gait_biofeedback.wire", "gait_biofeedback.io", "gait_biofeedback.nodes",
             "gait_biofeedback.analyze", "gait_biofeedback.report", "gait_biofeedback.graph",
             "gait_biofeedback.cli", "gait_biofeedback.batch", "gait_biofeedback.parameters",
             "gait_biofeedback.dashboard", "gait_biofeedback.sim")
    assert _layer_violations("gait_biofeedback.core", above) == []
    # the simulator's bags and the faults injected into them: io and wire, above it
    recording = ("gait_biofeedback.sim.recording", "gait_biofeedback.sim.faults")
    assert _layer_violations("gait_biofeedback.sim", above[:-1], allowed=recording) == []


def test_nothing_below_the_nodes_imports_a_node_module():
    below = ("gait_biofeedback.core", "gait_biofeedback.sim", "gait_biofeedback.wire", "gait_biofeedback.io",
             "gait_biofeedback.report", "gait_biofeedback.analyze", "gait_biofeedback.batch",
             "gait_biofeedback.parameters", "gait_biofeedback.dashboard")
    for prefix in below:
        assert _layer_violations(prefix, ("gait_biofeedback.nodes", "gait_biofeedback.graph")) == [], prefix
    assert _layer_violations("gait_biofeedback.wire", ("gait_biofeedback.io", "gait_biofeedback.analyze",
                                                       "gait_biofeedback.report")) == []


def test_no_import_circle_among_the_modules():
    modules = _modules()
    graph = {name: {m for m in _imports(path) if m in modules and m != name}
             for name, path in modules.items()}

    def cycle_from(start: str) -> list[str] | None:
        stack = [(start, [start])]
        while stack:
            node, path = stack.pop()
            for nxt in graph[node]:
                if nxt == start:
                    return [*path, start]
                if nxt not in path and len(path) < 12:
                    stack.append((nxt, [*path, nxt]))
        return None

    cycles = [c for name in modules if not name.endswith("__init__") and (c := cycle_from(name))]
    # a package __init__ that re-exports its submodules is not a circle
    real = [c for c in cycles if not any(a.startswith(b + ".") or b.startswith(a + ".")
                                         for a, b in itertools.pairwise(c))]
    assert real == []
