"""Module import graph of pdr, classifiers and server, built from the source's AST; counts import cycles.

Every ``import`` / ``from ... import`` statement counts, at module level and inside functions, except those under
``if TYPE_CHECKING:`` (never executed). An import of ``a.b.c`` is an edge to the deepest module of the three
packages it names (``from a.b import c`` is an edge to ``a.b.c`` when that is a module, else to ``a.b``).

A cycle is a strongly connected component of more than one node, between modules and between the subpackages of
``pdr`` (a module counted as its package: ``pdr.foot.dual`` -> ``pdr.foot``; a top-level module of ``pdr`` ->
``pdr``; a package nested in a subpackage of ``pdr``, e.g. ``pdr.foot.zupt`` or ``pdr.phone.attitude``, is a part of
that subpackage split by layer, kernel apart from driver, and counts as it: ``pdr.foot.zupt.kernel`` ->
``pdr.foot``; cycles between its modules are the module cycles). ``server``'s subpackages (``api``, ``web``,
``migrations``, ``bench``) are parts of one application that import its top-level modules and are imported by them
(the app factory registers the blueprints); they are listed but not counted.

Run ``python tools/import_graph.py`` from the checkout: prints the cycles and the forbidden imports (product code
importing ``pdr.cli``, ``pdr.evaluation`` or ``server.bench``); exit status 1 when there is any.
"""

from __future__ import annotations

import ast
import sys
from collections.abc import Iterable
from pathlib import Path

ROOTS = ("pdr", "classifiers", "server")
# Packages that only commands, evaluations and benchmarks may import (docs/architecture.md, "rules").
NON_PRODUCT = ("pdr.cli", "pdr.evaluation", "server.bench", "classifiers.cli")
FORBIDDEN_FOR_PRODUCT = ("pdr.cli", "pdr.evaluation", "server.bench")
# Modules that are commands themselves: they may import the evaluation side (they are the CLI's registrars).
COMMAND_MODULES = ("server.cli", "server.worker_cli", "classifiers.classify_cli", "classifiers.classify_bench")


def module_files(repo: Path) -> dict[str, Path]:
    """Dotted module name -> source file, for every ``.py`` file under the three packages."""
    out: dict[str, Path] = {}
    for root in ROOTS:
        for f in sorted((repo / root).rglob("*.py")):
            parts = list(f.relative_to(repo).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts = parts[:-1]
            out[".".join(parts)] = f
    return out


def _is_type_checking(test: ast.expr) -> bool:
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING")


def _imports(tree: ast.AST) -> Iterable[ast.Import | ast.ImportFrom]:
    """Import statements of a module, skipping ``if TYPE_CHECKING:`` bodies (their ``else`` still counts)."""
    stack: list[ast.AST] = [tree]
    while stack:
        node = stack.pop()
        if isinstance(node, ast.If) and _is_type_checking(node.test):
            stack.extend(node.orelse)
            continue
        if isinstance(node, ast.Import | ast.ImportFrom):
            yield node
        stack.extend(ast.iter_child_nodes(node))


def _deepest(name: str, modules: dict[str, Path]) -> str | None:
    parts = name.split(".")
    for k in range(len(parts), 0, -1):
        cand = ".".join(parts[:k])
        if cand in modules:
            return cand
    return None


def import_graph(repo: Path) -> dict[str, set[str]]:
    """Module -> the modules of the three packages it imports (self-edges dropped)."""
    modules = module_files(repo)
    graph: dict[str, set[str]] = {m: set() for m in modules}
    for mod, path in modules.items():
        is_pkg = path.name == "__init__.py"
        tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
        for node in _imports(tree):
            targets: list[str] = []
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            else:
                base = node.module or ""
                if node.level:
                    pkg = mod.split(".") if is_pkg else mod.split(".")[:-1]
                    pkg = pkg[: len(pkg) - (node.level - 1)]
                    base = ".".join(pkg + ([base] if base else []))
                targets = [f"{base}.{a.name}" if f"{base}.{a.name}" in modules else base for a in node.names]
            for t in targets:
                hit = _deepest(t, modules)
                if hit is not None and hit != mod:
                    graph[mod].add(hit)
    return graph


def package_of(mod: str, packages: set[str]) -> str:
    """The package a module belongs to (a package's ``__init__`` belongs to the package itself); within ``pdr``, the
    subpackage ``pdr.X`` (a nested package is a part of it).
    """
    pkg = mod if mod in packages else mod.rsplit(".", 1)[0]
    parts = pkg.split(".")
    return ".".join(parts[:2]) if parts[0] == "pdr" else pkg


def package_graph(graph: dict[str, set[str]], repo: Path) -> dict[str, set[str]]:
    """The module graph with each module replaced by its package."""
    files = module_files(repo)
    packages = {m for m, p in files.items() if p.name == "__init__.py"}
    out: dict[str, set[str]] = {}
    for mod, deps in graph.items():
        a = package_of(mod, packages)
        out.setdefault(a, set())
        for d in deps:
            b = package_of(d, packages)
            if b != a:
                out[a].add(b)
    return out


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one node (Tarjan, iterative), each sorted."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    on_stack: set[str] = set()
    stack: list[str] = []
    out: list[list[str]] = []
    counter = 0
    for start in sorted(graph):
        if start in index:
            continue
        work: list[tuple[str, Iterable[str]]] = [(start, iter(sorted(graph.get(start, ()))))]
        index[start] = low[start] = counter
        counter += 1
        stack.append(start)
        on_stack.add(start)
        while work:
            v, it = work[-1]
            advanced = False
            for w in it:
                if w not in index:
                    index[w] = low[w] = counter
                    counter += 1
                    stack.append(w)
                    on_stack.add(w)
                    work.append((w, iter(sorted(graph.get(w, ())))))
                    advanced = True
                    break
                if w in on_stack:
                    low[v] = min(low[v], index[w])
            if advanced:
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[v])
            if low[v] == index[v]:
                comp = []
                while True:
                    w = stack.pop()
                    on_stack.discard(w)
                    comp.append(w)
                    if w == v:
                        break
                if len(comp) > 1:
                    out.append(sorted(comp))
    return sorted(out)


def _under(mod: str, prefixes: Iterable[str]) -> bool:
    return any(mod == p or mod.startswith(p + ".") for p in prefixes)


def forbidden_imports(graph: dict[str, set[str]]) -> list[tuple[str, str]]:
    """(importer, imported) pairs where product code imports the CLI, the evaluation or the benchmarks."""
    bad = []
    for mod, deps in sorted(graph.items()):
        if _under(mod, NON_PRODUCT) or mod in COMMAND_MODULES:
            continue
        bad += [(mod, d) for d in sorted(deps) if _under(d, FORBIDDEN_FOR_PRODUCT)]
    return bad


def main(argv: list[str] | None = None) -> int:
    repo = Path(argv[0]) if argv else Path(__file__).resolve().parents[1]
    graph = import_graph(repo)
    mod_cycles = cycles(graph)
    pkg_cycles = cycles(package_graph(graph, repo))
    bad = forbidden_imports(graph)
    print(f"modules: {len(graph)}, imports: {sum(len(d) for d in graph.values())}")
    print(f"module cycles: {len(mod_cycles)}")
    for c in mod_cycles:
        print("  " + " <-> ".join(c))
    pdr_cycles = [c for c in pkg_cycles if c[0].split(".")[0] == "pdr"]
    print(f"pdr package cycles: {len(pdr_cycles)}")
    for c in pkg_cycles:
        print(("  " if c in pdr_cycles else "  (not counted) ") + " <-> ".join(c))
    print(f"forbidden imports: {len(bad)}")
    for a, b in bad:
        print(f"  {a} -> {b}")
    return 1 if (mod_cycles or pdr_cycles or bad) else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
