"""Lint, types, layers and import cycles, part of the test suite so CI enforces them.

Every tool comes from the test extra (`pip install -e '.[test]'`) and is found through the interpreter running
the tests, never through PATH: a tool that is missing is a failure, not a skip.
"""

from __future__ import annotations

import subprocess
import sys
from collections.abc import Iterable, Mapping
from pathlib import Path

import grimp

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ["gcs_swarm", "sitl_sim", "swarm_common"]
VENV_BIN = Path(sys.executable).parent


def _run(args: list[str]) -> subprocess.CompletedProcess[str]:
    return subprocess.run(args, cwd=ROOT, capture_output=True, text=True, timeout=600)


def test_ruff_lint_clean() -> None:
    result = _run([sys.executable, "-m", "ruff", "check", "."])
    assert result.returncode == 0, result.stdout + result.stderr


def test_ruff_format_clean() -> None:
    result = _run([sys.executable, "-m", "ruff", "format", "--check", "."])
    assert result.returncode == 0, result.stdout + result.stderr


def test_mypy_packages() -> None:
    result = _run([sys.executable, "-m", "mypy", "--ignore-missing-imports", "--no-error-summary", *PACKAGES])
    assert result.returncode == 0, result.stdout + result.stderr


def test_import_layers_of_the_architecture_hold() -> None:
    """The contracts of pyproject.toml's [tool.importlinter] (docs/architecture.md's table of who may import
    whom)."""
    lint_imports = VENV_BIN / "lint-imports"
    assert lint_imports.is_file(), (
        f"{lint_imports} is missing: pip install -e '.[test]' installs import-linter"
    )
    result = _run([str(lint_imports), "--no-cache"])
    assert result.returncode == 0, result.stdout + result.stderr


def strongly_connected_components(successors: Mapping[str, Iterable[str]]) -> list[list[str]]:
    """Tarjan's strongly connected components of the directed graph `successors` (node -> the nodes it
    points to; every node a key), iterative so deep import chains cannot overflow the stack. Each component
    sorted."""
    index: dict[str, int] = {}
    lowlink: dict[str, int] = {}
    on_stack: set[str] = set()
    stack: list[str] = []
    components: list[list[str]] = []
    for root in successors:
        if root in index:
            continue
        index[root] = lowlink[root] = len(index)
        stack.append(root)
        on_stack.add(root)
        work = [(root, iter(successors[root]))]
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is not None:
                if child not in index:
                    index[child] = lowlink[child] = len(index)
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(successors[child])))
                elif child in on_stack:
                    lowlink[node] = min(lowlink[node], index[child])
                continue
            work.pop()
            if work:
                parent = work[-1][0]
                lowlink[parent] = min(lowlink[parent], lowlink[node])
            if lowlink[node] == index[node]:
                component = []
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    component.append(member)
                    if member == node:
                        break
                components.append(sorted(component))
    return components


def test_strongly_connected_components_of_a_known_graph() -> None:
    """By hand: a -> b -> c -> a is one cycle, d -> e -> d another, f only points into the first."""
    graph = {"a": ["b"], "b": ["c"], "c": ["a"], "d": ["e"], "e": ["d", "a"], "f": ["a"], "g": []}
    components = sorted(strongly_connected_components(graph))
    assert components == [["a", "b", "c"], ["d", "e"], ["f"], ["g"]]


def test_no_import_cycles_between_modules() -> None:
    """Every import counts, those under `if TYPE_CHECKING:` too: a cycle there still ties the modules'
    designs together. A strongly connected component of more than one module is a cycle."""
    graph = grimp.build_graph(*PACKAGES, exclude_type_checking_imports=False, cache_dir=None)
    modules = set(graph.modules)
    successors = {m: sorted(graph.find_modules_directly_imported_by(m) & modules) for m in sorted(modules)}
    cycles = [c for c in strongly_connected_components(successors) if len(c) > 1]
    assert not cycles, "import cycles: " + "; ".join(" <-> ".join(c) for c in cycles)
