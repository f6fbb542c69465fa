"""The package's architecture rules: layers and torch-free paths (import-linter), no import cycles
at module level (function-level imports included), no reading or writing of another module's
underscore attributes, and ruff's agreed rule set. Rules are in ``pyproject.toml``."""

from __future__ import annotations

import ast
import shutil
import subprocess
import sys
from pathlib import Path

import grimp
import pytest

ROOT = Path(__file__).resolve().parents[1]
SOURCE_DIRS = ("autoscoop", "tools", "benchmarks", "release", "experiments")


def _tool(name: str) -> str:
    path = Path(sys.executable).parent / name
    found = str(path) if path.exists() else shutil.which(name)
    if found is None:
        pytest.fail(f"{name} is not installed; `make test` installs it with the test extras")
    return found


def import_cycles(package: str) -> list[list[str]]:
    """Groups of modules of ``package`` that import each other, directly or through others."""
    graph = grimp.build_graph(package)
    modules = set(graph.modules)
    return find_cycles({m: sorted(set(graph.find_modules_directly_imported_by(m)) & modules) for m in modules})


def find_cycles(edges: dict[str, list[str]]) -> list[list[str]]:
    """Strongly connected groups of more than one node (Tarjan), each sorted; ``edges[a]`` lists what a imports."""
    modules = sorted(edges)
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    groups: list[list[str]] = []

    def visit(start: str) -> None:  # iterative, so deep graphs do not hit the recursion limit
        work = [(start, iter(edges[start]))]
        index[start] = low[start] = len(index)
        stack.append(start)
        on_stack.add(start)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is None:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[node])
                if low[node] == index[node]:
                    group = []
                    while True:
                        member = stack.pop()
                        on_stack.discard(member)
                        group.append(member)
                        if member == node:
                            break
                    if len(group) > 1:
                        groups.append(sorted(group))
            elif child not in index:
                index[child] = low[child] = len(index)
                stack.append(child)
                on_stack.add(child)
                work.append((child, iter(edges[child])))
            elif child in on_stack:
                low[node] = min(low[node], index[child])

    for module in modules:
        if module not in index:
            visit(module)
    return groups


def test_cycle_finder_finds_indirect_cycles() -> None:
    edges = {"a": ["b"], "b": ["c"], "c": ["a"], "d": ["a"], "e": ["f"], "f": ["e"], "g": []}
    assert sorted(find_cycles(edges)) == [["a", "b", "c"], ["e", "f"]]
    assert find_cycles({"a": ["b"], "b": [], "c": ["a", "b"]}) == []


def test_no_import_cycles() -> None:
    assert import_cycles("autoscoop") == []


def test_import_linter_contracts_hold() -> None:
    result = subprocess.run([_tool("lint-imports"), "--no-cache"], cwd=ROOT, capture_output=True, text=True)
    assert result.returncode == 0, result.stdout[-4000:] + result.stderr[-2000:]
    assert "0 broken" in result.stdout, result.stdout[-4000:]


def test_ruff_check_passes() -> None:
    result = subprocess.run([_tool("ruff"), "check", *SOURCE_DIRS, "tests"], cwd=ROOT, capture_output=True, text=True)
    assert result.returncode == 0, result.stdout[-4000:] + result.stderr[-2000:]


ALLOWED_RECEIVERS = {"self", "cls", "super"}
THIRD_PARTY_PRIVATE = {"_sigma", "_SubParsersAction"}
"""Underscore attributes of other packages that have no public way in (Stable-Baselines3's action
noise scale; argparse's sub-parser type, for annotations); listed here so each one is a decision, not an accident."""


def foreign_underscore_attributes(source: str) -> list[tuple[int, str]]:
    """``obj._name`` where ``obj`` is not ``self``/``cls`` (dunders and ``_``-prefixed locals aside)."""
    found = []
    for node in ast.walk(ast.parse(source)):
        if not isinstance(node, ast.Attribute):
            continue
        name = node.attr
        if not name.startswith("_") or (name.startswith("__") and name.endswith("__")):
            continue
        receiver = node.value
        if isinstance(receiver, ast.Name) and receiver.id in ALLOWED_RECEIVERS:
            continue
        if isinstance(receiver, ast.Call) and isinstance(receiver.func, ast.Name) and receiver.func.id == "super":
            continue
        if name in THIRD_PARTY_PRIVATE:
            continue
        found.append((node.lineno, ast.unparse(node)))
    return found


def test_underscore_finder_flags_foreign_access() -> None:
    hits = foreign_underscore_attributes("sim._root_qpos = 1\nself._x = 2\nobj.__class__\nself.window._accumulate\n")
    assert [text for _, text in hits] == ["sim._root_qpos", "self.window._accumulate"]


def test_no_module_touches_another_modules_underscore_attributes() -> None:
    offenders = []
    for folder in SOURCE_DIRS:
        for path in sorted((ROOT / folder).rglob("*.py")):
            for line, text in foreign_underscore_attributes(path.read_text()):
                offenders.append(f"{path.relative_to(ROOT)}:{line}: {text}")
    assert offenders == []
