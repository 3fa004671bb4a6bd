"""The ``pdr`` command imports only the plugin a command line names (pdr.cli module doc)."""

from __future__ import annotations

import argparse

import pytest

from pdr.cli import build_parser, main
from tests.fresh_process import python_json

COMMANDS = {"allan", "bench", "calibrate", "classify", "convert", "eval", "foot", "inspect", "phyphox", "serve",
            "simulate", "site", "track", "train", "users", "worker"}
EVAL_TARGETS = {"classifier", "coop", "foot", "heading", "ipin", "ms", "placement", "pocket-heading", "steps"}
BENCH_TARGETS = {"classify", "faults", "load", "phone", "processor", "server", "track"}


def _choices(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return dict(sub.choices)


def test_a_command_line_without_a_known_command_registers_every_command_and_target() -> None:
    for argv in ([], ["--help"], ["inspec", "x"], ["-v"]):
        commands = _choices(build_parser(argv))
        assert set(commands) == COMMANDS, argv
    # A command named without a target lists every target.
    assert set(_choices(_choices(build_parser(["eval"]))["eval"])) == EVAL_TARGETS
    assert set(_choices(_choices(build_parser(["bench", "--help"]))["bench"])) == BENCH_TARGETS


def test_a_named_command_registers_only_itself_and_its_named_target() -> None:
    assert set(_choices(build_parser(["-v", "inspect", "--formats"]))) == {"inspect"}
    commands = _choices(build_parser(["eval", "ipin", "DIR", "--json"]))
    assert set(commands) == {"eval"}
    assert set(_choices(commands["eval"])) == {"ipin"}
    # An unknown target keeps every target, so that argparse's error lists them.
    assert set(_choices(_choices(build_parser(["eval", "nope"]))["eval"])) == EVAL_TARGETS


def test_unknown_command_error_lists_every_command(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        main(["inspec", "x"])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "invalid choice: 'inspec'" in err
    assert "'inspect'" in err and "'serve'" in err


def test_inspect_does_not_import_the_heavy_plugins() -> None:
    heavy = ("sklearn", "xgboost", "flask", "sqlalchemy", "matplotlib", "scipy.signal", "scipy.optimize",
             "classifiers", "server", "rich")
    code = ("import json, sys; from pdr.cli import build_parser; build_parser(['inspect', 'LOG']); "
            f"print(json.dumps([m for m in {heavy!r} if m in sys.modules]))")
    assert python_json(code) == []


def test_classify_registers_without_scikit_learn() -> None:
    # `pdr classify` on a hand-held log builds the modes from the phone pipeline: registering the command once
    # imported scikit-learn and XGBoost (1-2 s) through the training and evaluation commands' module.
    code = ("import json, sys; from pdr.cli import build_parser; build_parser(['classify', 'LOG', '--out', 'X']); "
            "print(json.dumps([m for m in ('sklearn', 'xgboost', 'classifiers.cli', 'classifiers.artifacts') "
            "if m in sys.modules]))")
    assert python_json(code) == []


def test_help_lists_every_command_without_importing_the_plugins() -> None:
    heavy = ("numba", "scipy", "sklearn", "flask", "matplotlib", "classifiers.cli", "server.cli", "pdr.cli.track",
             "pdr.cli.eval_walks", "pdr.cli.bench_phone",
             "pdr.cli.allan", "pdr.pipeline", "rich")   # rich: imported by a progress bar drawn on a terminal only
    code = ("import json, sys; from pdr.cli import build_parser; p = build_parser(['--help']); "
            "sub = next(a for a in p._actions if a.dest == 'command'); "
            f"print(json.dumps([sorted(sub.choices), [m for m in {heavy!r} if m in sys.modules]]))")
    names, imported = python_json(code)
    assert set(names) == COMMANDS
    assert imported == []


def _helps(parser: argparse.ArgumentParser) -> dict[str, str]:
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return {a.dest: str(a.help) for a in sub._choices_actions}


def test_the_help_read_from_a_plugins_source_is_the_help_it_registers() -> None:
    listed = _helps(build_parser([]))
    for name in COMMANDS:
        assert listed[name] == _helps(build_parser([name]))[name], name
    listed_targets = _helps(_choices(build_parser(["eval"]))["eval"])
    for target in EVAL_TARGETS:
        loaded = _helps(_choices(build_parser(["eval", target]))["eval"])
        assert listed_targets[target] == loaded[target], target


def test_numpys_unused_submodules_load_on_first_use_only() -> None:
    """numba's kernel loading imports scipy.linalg, whose array-API layer reads every numpy attribute: after
    :func:`pdr.cli.lazy_numpy.defer_numpy_extras` that runs no extra's code, and an extra still works when used.
    """
    code = ("import json, sys, numpy; from pdr.cli.lazy_numpy import EXTRAS, defer_numpy_extras; "
            "defer_numpy_extras(); import scipy.linalg.cython_blas; "
            "lazy = [m for m in EXTRAS if type(sys.modules[m]).__name__ == '_LazyModule']; "
            "ok = numpy.ma.masked_invalid(numpy.array([1.0, numpy.nan])).count() == 1; "
            "print(json.dumps([lazy, type(sys.modules['numpy.ma']).__name__, bool(ok)]))")
    lazy, ma_type, ok = python_json(code)
    assert "numpy.f2py" in lazy and "numpy.testing" in lazy
    assert ma_type == "module" and ok


def test_defer_numpy_extras_does_not_import_numpy() -> None:
    code = ("import sys; from pdr.cli.lazy_numpy import defer_numpy_extras; defer_numpy_extras(); "
            "print(str('numpy' in sys.modules).lower())")
    assert python_json(code) is False


def test_numba_blas_loads_without_the_scipy_linalg_package() -> None:
    """:func:`pdr.cli.numba_blas.load_numba_blas`: a compiled kernel that calls LAPACK runs without ``scipy.linalg``
    being imported, and a later ``import scipy.linalg`` runs the package with the same BLAS module.
    """
    code = ("import json, sys, numpy as np; from pdr.cli.numba_blas import load_numba_blas; "
            "loaded = load_numba_blas(); "
            "from pdr.filters.small_linalg import solve_symmetric; "
            "x = solve_symmetric(np.array([[1.0, 2.0], [2.0, 1.0]]), np.array([[3.0], [3.0]])); "
            "before = 'scipy.linalg' in sys.modules; blas = sys.modules['scipy.linalg.cython_blas']; "
            "import scipy.linalg; "
            "print(json.dumps([loaded, before, x.ravel().tolist(), sys.modules['scipy.linalg.cython_blas'] is blas, "
            "scipy.linalg.solve(np.array([[1.0, 2.0], [2.0, 1.0]]), np.array([3.0, 3.0])).tolist()]))")
    loaded, before, x, same, y = python_json(code, timeout_s=300)
    assert loaded and not before
    assert x == [1.0, 1.0]      # the indefinite matrix goes through LAPACK's LU
    assert same and y == pytest.approx([1.0, 1.0])
