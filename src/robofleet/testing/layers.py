"""The import graph of robofleet and its layering rules, read from the source.

Run ``python -m robofleet.testing.layers`` to print the graph's size, the imports between
packages, the import circles and the imports that break a rule (the architecture test
asserts there are none).

Layers, bottom to top (docs/architecture.md): ``core``; ``dynamics`` and ``viz`` (each
importing ``core`` only); the families; ``scenarios``; ``experiments``, ``envs`` and ``ros2``; ``testing``;
``cli``; the package's face ``robofleet/__init__.py`` and ``__main__.py``. A module imports its own package
and lower layers only; families never import each other.
"""

from __future__ import annotations

import ast
import sys
from collections import Counter, defaultdict
from dataclasses import dataclass
from pathlib import Path

PACKAGE = "robofleet"
FAMILY_PACKAGES = ("avoidance", "coordination", "flocking", "search")
LAYER = {"core": 0, "dynamics": 1, "viz": 1, **{f: 2 for f in FAMILY_PACKAGES}, "scenarios": 3,
         "experiments": 4, "envs": 4, "ros2": 4, "testing": 5, "cli": 6, "": 7}
ONLY_CORE = ("dynamics", "viz")


@dataclass(frozen=True)
class ImportGraph:
    """Module-level import edges between robofleet's modules (function-local ones included)."""

    modules: tuple[str, ...]
    edges: frozenset[tuple[str, str]]
    local_imports: int

    def cycles(self) -> list[list[str]]:
        """The strongly connected components with more than one module (Tarjan)."""
        graph = defaultdict(set)
        for a, b in self.edges:
            graph[a].add(b)
        index: dict[str, int] = {}
        low: dict[str, int] = {}
        stack: list[str] = []
        on_stack: set[str] = set()
        found: list[list[str]] = []

        def visit(v: str) -> None:
            index[v] = low[v] = len(index)
            stack.append(v)
            on_stack.add(v)
            for w in graph[v]:
                if w not in index:
                    visit(w)
                    low[v] = min(low[v], low[w])
                elif w in on_stack:
                    low[v] = min(low[v], index[w])
            if low[v] == index[v]:
                component = []
                while True:
                    w = stack.pop()
                    on_stack.discard(w)
                    component.append(w)
                    if w == v:
                        break
                if len(component) > 1:
                    found.append(sorted(component))

        for module in self.modules:
            if module not in index:
                visit(module)
        return found

    def package_edges(self) -> Counter:
        """``(package, package) -> count`` of edges between different packages."""
        return Counter((package_of(a), package_of(b)) for a, b in self.edges if package_of(a) != package_of(b))

    def violations(self) -> list[str]:
        """Edges that import upward, across families, or from dynamics/viz into anything but core."""
        out = []
        for a, b in sorted(self.edges):
            pa, pb = package_of(a), package_of(b)
            if pa == pb:
                continue
            if pa in ONLY_CORE and pb != "core":
                out.append(f"{a} -> {b}: {pa} may import core only")
            elif pa in FAMILY_PACKAGES and pb in FAMILY_PACKAGES:
                out.append(f"{a} -> {b}: families never import each other")
            elif LAYER.get(pb, 99) > LAYER.get(pa, -1):
                out.append(f"{a} -> {b}: imports upward ({pa} is below {pb})")
        return out


def package_of(module: str) -> str:
    """``robofleet.core.trace`` -> ``core``; the package's face (``robofleet`` and
    ``robofleet.__main__``, the ``python -m robofleet`` entry) -> ``""``."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 and parts[1] != "__main__" else ""


def read_graph(root: Path | None = None) -> ImportGraph:
    """The import graph of the package at ``root`` (default: the installed robofleet)."""
    root = Path(root) if root is not None else Path(__file__).resolve().parents[1]
    files = {module_name(f, root): f for f in sorted(root.rglob("*.py"))}
    edges, local = set(), 0
    for module, file in files.items():
        tree = ast.parse(file.read_text())
        for node in ast.walk(tree):
            for target in imported_modules(node, module, file.name == "__init__.py", files):
                if target != module:
                    edges.add((module, target))
        local += sum(isinstance(n, (ast.Import, ast.ImportFrom)) for fn in ast.walk(tree)
                     if isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef)) for n in ast.walk(fn))
    return ImportGraph(tuple(files), frozenset(edges), local)


def module_name(file: Path, root: Path) -> str:
    parts = list(file.relative_to(root.parent).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imported_modules(node: ast.AST, module: str, is_package: bool, known: dict[str, Path]) -> list[str]:
    """The robofleet modules an import statement names (``from a import b`` names ``a.b``
    when that is a module, else ``a``)."""
    if isinstance(node, ast.Import):
        return [a.name for a in node.names if a.name in known]
    if not isinstance(node, ast.ImportFrom):
        return []
    if node.level:
        base = module.split(".") if is_package else module.split(".")[:-1]
        base = base[: len(base) - (node.level - 1)]
        name = ".".join(base + ([node.module] if node.module else []))
    else:
        name = node.module or ""
    out = []
    for alias in node.names:
        candidate = f"{name}.{alias.name}"
        target = candidate if candidate in known else name
        if target in known:
            out.append(target)
    return out


def report(graph: ImportGraph) -> str:
    """The graph in words: size, package edges, circles and rule violations."""
    cycles = graph.cycles()
    lines = [f"modules {len(graph.modules)}, import edges {len(graph.edges)}, circles {len(cycles)}, "
             f"function-local imports {graph.local_imports}"]
    lines += [f"  circle: {' -> '.join(c)}" for c in cycles]
    lines.append("package edges (layer order bottom-up: " + ", ".join(sorted(LAYER, key=LAYER.get)) + "):")
    lines += [f"  {a or PACKAGE} -> {b or PACKAGE}: {n}" for (a, b), n in sorted(graph.package_edges().items())]
    violations = graph.violations()
    lines.append(f"rule violations: {len(violations)}")
    lines += [f"  {v}" for v in violations]
    return "\n".join(lines)


if __name__ == "__main__":
    print(report(read_graph(Path(sys.argv[1]) if len(sys.argv) > 1 else None)))
