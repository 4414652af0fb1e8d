"""The layering the design promises: `models/` stands on its own, and no two project modules import each
other at module level (an import circle). Read from the source with `ast`, so nothing is imported."""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("worldmind_local", "models", "benchmarks")


def _modules() -> dict[str, Path]:
    found = {}
    for package in PACKAGES:
        for path in (ROOT / package).rglob("*.py"):
            name = ".".join(path.relative_to(ROOT).with_suffix("").parts)
            found[name.removesuffix(".__init__")] = path
    return found


def _top_level_imports(path: Path, known: dict[str, Path]) -> set[str]:
    """Project modules imported when `path` is imported (not inside functions or TYPE_CHECKING)."""
    out: set[str] = set()
    for node in ast.parse(path.read_text(encoding="utf-8")).body:
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.dump(node.test):
            continue
        if isinstance(node, ast.Import):
            out |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            out.add(node.module)
            out |= {f"{node.module}.{a.name}" for a in node.names}
    return {m for m in out if m in known}


def test_models_never_import_the_harness() -> None:
    modules = _modules()
    offenders = {name: sorted(d for d in _top_level_imports(path, modules) if d.startswith("worldmind_local"))
                 for name, path in modules.items() if name.startswith("models")}
    assert not {k: v for k, v in offenders.items() if v}
    # not even lazily, inside a function
    lazy = [name for name, path in modules.items() if name.startswith("models")
            and any(f"{kw} worldmind_local" in path.read_text(encoding="utf-8") for kw in ("import", "from"))]
    assert not lazy, f"models modules importing the harness: {lazy}"

def test_no_import_circles() -> None:
    modules = _modules()
    graph = {name: _top_level_imports(path, modules) for name, path in modules.items()}
    state: dict[str, int] = {}
    cycles: list[list[str]] = []

    def visit(node: str, stack: list[str]) -> None:
        state[node] = 1
        stack.append(node)
        for nxt in sorted(graph[node]):
            if state.get(nxt) == 1:
                cycles.append(stack[stack.index(nxt):] + [nxt])
            elif not state.get(nxt):
                visit(nxt, stack)
        stack.pop()
        state[node] = 2

    for name in sorted(graph):
        if not state.get(name):
            visit(name, [])
    assert not cycles, "\n".join(" -> ".join(c) for c in cycles)
