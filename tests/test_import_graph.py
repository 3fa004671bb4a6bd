"""The import graph of pdr, classifiers and server (tools/import_graph.py): no cycles, no product import of the
CLI, the evaluation or the benchmarks (docs/architecture.md, "rules").
"""

from __future__ import annotations

from pathlib import Path
from types import ModuleType

import pytest

from tests.conftest import REPO_ROOT, load_tool


@pytest.fixture(scope="module")
def tool() -> ModuleType:
    return load_tool("import_graph")


@pytest.fixture(scope="module")
def graph(tool: ModuleType) -> dict[str, set[str]]:
    return tool.import_graph(REPO_ROOT)


def test_the_tool_finds_cycles_and_only_cycles(tool: ModuleType) -> None:
    g = {"a": {"b"}, "b": {"c"}, "c": {"a", "d"}, "d": {"e"}, "e": set(), "f": {"f"}}
    assert tool.cycles(g) == [["a", "b", "c"]]
    assert tool.cycles({"a": {"b"}, "b": set()}) == []


def test_the_tool_reads_function_level_imports_and_skips_type_checking(tool: ModuleType, tmp_path: Path) -> None:
    for root in tool.ROOTS:
        (tmp_path / root).mkdir()
        (tmp_path / root / "__init__.py").write_text("")
    (tmp_path / "pdr" / "a.py").write_text("def f():\n    from pdr import b\n")
    (tmp_path / "pdr" / "b.py").write_text("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    import pdr.a\n"
                                           "from . import c\n")
    (tmp_path / "pdr" / "c.py").write_text("import pdr.a\n")
    g = tool.import_graph(tmp_path)
    assert g["pdr.a"] == {"pdr.b"} and g["pdr.b"] == {"pdr.c"} and g["pdr.c"] == {"pdr.a"}
    assert tool.cycles(g) == [["pdr.a", "pdr.b", "pdr.c"]]


def test_a_nested_package_counts_as_its_pdr_subpackage(tool: ModuleType, tmp_path: Path) -> None:
    """``pdr.foot.zupt.kernel`` importing ``pdr.foot.drift`` while ``pdr.foot.dual`` imports ``pdr.foot.zupt`` is
    layering inside ``pdr.foot``, not a cycle between subpackages; a real one between ``pdr.foot`` and ``pdr.phone``
    through the nested package still is."""
    for d in ("pdr", "classifiers", "server", "pdr/foot", "pdr/foot/zupt", "pdr/phone"):
        (tmp_path / d).mkdir()
        (tmp_path / d / "__init__.py").write_text("")
    (tmp_path / "pdr" / "foot" / "drift.py").write_text("")
    (tmp_path / "pdr" / "foot" / "zupt" / "kernel.py").write_text("from pdr.foot import drift\n")
    (tmp_path / "pdr" / "foot" / "dual.py").write_text("from pdr.foot.zupt import kernel\n")
    files = tool.package_graph(tool.import_graph(tmp_path), tmp_path)
    assert files["pdr.foot"] == set() and tool.cycles(files) == []
    (tmp_path / "pdr" / "phone" / "steps.py").write_text("from pdr.foot import dual\n")
    (tmp_path / "pdr" / "foot" / "zupt" / "kernel.py").write_text(
        "from pdr.foot import drift\nimport pdr.phone.steps\n")
    assert tool.cycles(tool.package_graph(tool.import_graph(tmp_path), tmp_path)) == [["pdr.foot", "pdr.phone"]]


def test_no_module_import_cycles(tool: ModuleType, graph: dict[str, set[str]]) -> None:
    assert "pdr.phone.pipeline" in graph and "server.processing" in graph
    assert tool.cycles(graph) == []


def test_no_import_cycles_between_pdr_subpackages(tool: ModuleType, graph: dict[str, set[str]]) -> None:
    packages = tool.package_graph(graph, REPO_ROOT)
    assert {"pdr", "pdr.phone", "pdr.foot", "pdr.fusion", "pdr.evaluation"} <= set(packages)
    assert [c for c in tool.cycles(packages) if c[0].startswith("pdr")] == []


def test_product_code_imports_neither_cli_nor_evaluation_nor_benchmarks(tool: ModuleType,
                                                                        graph: dict[str, set[str]]) -> None:
    assert tool.forbidden_imports(graph) == []
    # The check would see one: the CLI imports the evaluation, a product module importing the CLI is refused.
    assert tool.forbidden_imports({"pdr.foot.x": {"pdr.cli.foot"}, "pdr.cli.track": {"pdr.evaluation.scoring"}}) == [
        ("pdr.foot.x", "pdr.cli.foot")]
