"""The package layout's import rules, read from the source (AST, nothing imported).

* no import cycle among the project's modules at import time (module-level imports; those
  under ``if TYPE_CHECKING:`` and inside functions do not run at import);
* ``teleop/`` (the library) imports neither ``sim/`` nor ``services/`` at module level; inside
  functions only the CLI layer (``teleop/cli.py``, ``teleop/commands/``) may, to wire them in;
* ``teleop.diagnose`` (system identification) and ``teleop.analysis`` (stability, sweeps) do
  not import each other.
"""

from __future__ import annotations

import ast
import functools
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("teleop", "sim", "services")


def _module_name(path: Path) -> str:
    parts = path.relative_to(ROOT).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _is_type_checking(node: ast.If) -> bool:
    t = node.test
    return (isinstance(t, ast.Name) and t.id == "TYPE_CHECKING") or (
        isinstance(t, ast.Attribute) and t.attr == "TYPE_CHECKING")


def _imports(tree: ast.Module, module: str) -> tuple[set[str], set[str]]:
    """(module-level imports, imports inside functions) of one module, as dotted names."""
    top: set[str] = set()
    lazy: set[str] = set()
    package = module if module in PACKAGES else module.rsplit(".", 1)[0]

    def names(node: ast.Import | ast.ImportFrom) -> list[str]:
        if isinstance(node, ast.Import):
            return [a.name for a in node.names]
        base = node.module or ""
        if node.level:
            up = package.split(".")[: len(package.split(".")) - node.level + 1]
            base = ".".join([*up, base] if base else up)
        return [base] + [f"{base}.{a.name}" for a in node.names]

    def visit(node: ast.AST, in_function: bool) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.If) and _is_type_checking(child):
                for c in child.orelse:
                    visit(c, in_function)
                continue
            if isinstance(child, ast.Import | ast.ImportFrom):
                (lazy if in_function else top).update(names(child))
            visit(child, in_function or isinstance(
                child, ast.FunctionDef | ast.AsyncFunctionDef | ast.Lambda))

    visit(tree, False)
    return top, lazy


@functools.cache
def _graph() -> tuple[dict[str, set[str]], dict[str, set[str]]]:
    files = {(_module_name(p)): p for pkg in PACKAGES for p in (ROOT / pkg).rglob("*.py")}
    top: dict[str, set[str]] = {}
    lazy: dict[str, set[str]] = {}
    for mod, path in files.items():
        t, z = _imports(ast.parse(path.read_text(), str(path)), mod)
        # keep project modules only; 'from pkg import mod' names the module itself
        top[mod] = {n for n in t if n in files and n != mod}
        lazy[mod] = {n for n in z if n in files and n != mod}
    return top, lazy


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Every strongly connected component with more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out: list[list[str]] = []

    def strong(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                strong(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            strong(v)
    return out


def _under(mod: str, pkg: str) -> bool:
    return mod == pkg or mod.startswith(pkg + ".")


def test_no_import_cycle_at_import_time() -> None:
    top, _ = _graph()
    assert _cycles(top) == []


def test_cycle_finder_finds_a_planted_cycle() -> None:
    top, _ = _graph()
    planted = {k: set(v) for k, v in top.items()}
    planted["teleop.errors"].add("teleop.diagnose.fit")  # fit -> ... -> errors -> fit
    planted["teleop.diagnose.fit"].add("teleop.errors")
    assert any("teleop.errors" in c and "teleop.diagnose.fit" in c for c in _cycles(planted))


def test_library_never_imports_sim_or_services_at_module_level() -> None:
    top, _ = _graph()
    bad = sorted((m, n) for m, deps in top.items() if _under(m, "teleop") for n in deps
                 if _under(n, "sim") or _under(n, "services"))
    assert bad == []


def test_only_the_cli_layer_reaches_sim_or_services() -> None:
    _, lazy = _graph()
    bad = sorted((m, n) for m, deps in lazy.items() if _under(m, "teleop")
                 and not (m == "teleop.cli" or _under(m, "teleop.commands")) for n in deps
                 if _under(n, "sim") or _under(n, "services"))
    assert bad == []


def test_diagnose_and_analysis_are_separate() -> None:
    top, lazy = _graph()
    bad = sorted((m, n) for g in (top, lazy) for m, deps in g.items() for n in deps
                 if (_under(m, "teleop.diagnose") and _under(n, "teleop.analysis"))
                 or (_under(m, "teleop.analysis") and _under(n, "teleop.diagnose")))
    assert bad == []
    assert "teleop.diagnose.diagnose" in top and "teleop.analysis.stability" in top
