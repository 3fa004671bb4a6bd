"""The ``pdr`` command: one entry point, subcommands contributed by each package.

Subcommands are declared as entry points in the ``pdr.commands`` group of ``pyproject.toml``; each
points at a ``register(subparsers)`` function that adds its parser and sets ``func`` (a callable
taking the parsed ``argparse.Namespace`` and returning an exit code). Targets of ``pdr eval`` come
from the ``pdr.eval`` group in the same way. pdr/ never imports server/ or classifiers/ directly.

Only the entry point a command line names is imported (``pdr inspect LOG`` loads neither scikit-learn nor Flask
nor the Allan-variance fits): each plugin module imports what its command runs, several seconds of imports in
all. An entry point's name is the (sub)command it adds. A command line that names none (``pdr --help``, a typo)
lists them all, so that help and "invalid choice" list every command: it reads each one's one-line help from its
module's source (:func:`_static_help`) instead of importing it, so that ``pdr --help`` stays under a second.
"""

from __future__ import annotations

import argparse
import ast
import functools
import gc
import importlib.util
import logging
import re
import sys
from collections.abc import Sequence
from importlib.metadata import EntryPoint, entry_points
from pathlib import Path

from pdr.cli.blas_threads import single_threaded_blas
from pdr.cli.collector import collection_paused, freeze_at_exit
from pdr.errors import InputError

log = logging.getLogger("pdr")


def _unavailable(name: str, error: Exception):  # noqa: ANN202
    def run(args: argparse.Namespace) -> int:
        print(f"error: the '{name}' command is not available in this installation ({error})", file=sys.stderr)
        return 2
    return run


#: The positional words of the command line being parsed (``("eval", "ipin", ...)``): the word at position
#: ``level`` picks the entry point :func:`register_group` loads at that level. Set by :func:`build_parser` only
#: while it runs.
_requested: tuple[str, ...] = ()


def register_group(subparsers: argparse._SubParsersAction, group: str, level: int = 0) -> None:
    """Add the entry points of ``group`` to ``subparsers``; a broken plugin becomes an error command.

    ``level`` is the position of this group's (sub)command among the command line's positional words (0 for
    ``pdr COMMAND``, 1 for ``pdr eval TARGET``): when that word names an entry point of the group, only that one
    is loaded (module doc).
    """
    eps = sorted(entry_points(group=group), key=lambda e: e.name)
    wanted = _requested[level] if level < len(_requested) else None
    named = [ep for ep in eps if ep.name == wanted]
    for ep in named or eps:
        summary = None if named else _static_help(ep)
        if summary is not None:
            # Listed only (help, an unknown command): its module is not imported. Chosen, it would be named.
            p = subparsers.add_parser(ep.name, help=summary)
            p.set_defaults(func=_unavailable(ep.name, RuntimeError("listed without loading")))
            continue
        try:
            ep.load()(subparsers)
        except (ImportError, AttributeError) as exc:
            p = subparsers.add_parser(ep.name, help=f"(unavailable: {exc})")
            p.set_defaults(func=_unavailable(ep.name, exc))


@functools.cache
def _module_source(module: str) -> str | None:
    """The source of ``module``, found without executing it (its parent packages are imported)."""
    try:
        spec = importlib.util.find_spec(module)
    except (ImportError, ValueError):
        return None
    if spec is None or not spec.origin or not spec.origin.endswith(".py"):
        return None
    try:
        return Path(spec.origin).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError):
        return None


def _function_def(module: str, name: str) -> ast.FunctionDef | None:
    """The top-level function ``name`` of ``module``, parsed alone: from its ``def`` line to the next line that
    starts in the first column (parsing whole modules was a third of ``pdr --help``'s time). None when not found
    or when that text does not parse by itself.
    """
    src = _module_source(module)
    start = re.search(rf"^def {re.escape(name)}\(", src, re.MULTILINE) if src else None
    if src is None or start is None:
        return None
    end = re.compile(r"\n\S").search(src, start.end())
    text = src[start.start():end.start() + 1] if end else src[start.start():]
    try:
        tree = ast.parse(text)
    except SyntaxError:
        return None
    func = tree.body[0] if tree.body else None
    return func if isinstance(func, ast.FunctionDef) else None


def _static_help(ep: EntryPoint) -> str | None:
    """The one-line help an entry point's ``register`` function gives its (sub)command, read from its source.

    Found when the function calls ``X.add_parser(NAME, help=TEXT)`` or ``helper(subparsers, NAME, TEXT, ...)``
    with NAME the entry point's name and TEXT a string literal; None otherwise (the module is then imported).
    This keeps ``pdr --help`` from importing every plugin (several seconds of imports).
    """
    func = _function_def(ep.module, ep.attr)
    if func is None:
        return None
    for call in (n for n in ast.walk(func) if isinstance(n, ast.Call)):
        args = [a.value if isinstance(a, ast.Constant) else None for a in call.args]
        helps = [k.value.value for k in call.keywords if k.arg == "help" and isinstance(k.value, ast.Constant)]
        if isinstance(call.func, ast.Attribute) and call.func.attr == "add_parser":
            if args[:1] == [ep.name] and helps and isinstance(helps[0], str):
                return helps[0]
        elif len(args) >= 3 and args[1] == ep.name and isinstance(args[2], str):
            return args[2]
    return None


def build_parser(argv: Sequence[str] = ()) -> argparse.ArgumentParser:
    """The ``pdr`` parser for the command line ``argv`` (only the entry points it names; all when it names none).

    The top-level options take no values, so the positional words are the arguments that do not start with '-'.
    """
    global _requested
    parser = argparse.ArgumentParser(
        prog="pdr", description="Pedestrian navigation backend: read logs, simulate, track, classify, serve.")
    parser.add_argument("-v", "--verbose", action="store_true", help="log progress to stderr")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    _requested = tuple(a for a in argv if not a.startswith("-"))
    try:
        register_group(sub, "pdr.commands")
    finally:
        _requested = ()
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the ``pdr`` command line; returns the process exit code."""
    words = list(sys.argv[1:] if argv is None else argv)
    single_threaded_blas()      # before numpy loads (pdr.cli.blas_threads)
    freeze_at_exit()            # the interpreter's last collections would walk every object (pdr.cli.collector)
    with collection_paused():   # the command's modules: many long-lived objects (pdr.cli.collector)
        parser = build_parser(words)
        gc.freeze()             # and not walked while the command runs (pdr.cli.collector)
    try:
        return _run(parser.parse_args(words))
    finally:
        gc.unfreeze()


def _run(args: argparse.Namespace) -> int:
    """Run the parsed command line's command; its exit code (an :class:`InputError`, and a path that cannot be opened,
    said in one line: exit 2).
    """
    logging.basicConfig(level=logging.INFO if args.verbose else logging.WARNING,
                        format="%(levelname)s %(name)s: %(message)s")
    try:
        return int(args.func(args) or 0)
    except InputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130
    except BrokenPipeError:
        # Output piped into a command that stopped reading (e.g. `| head`): not an error of ours.
        sys.stderr.close()
        return 0
    except OSError as exc:
        if exc.filename is None:
            raise
        # A path the user named that cannot be opened or written (e.g. --out in a missing folder): said in one line.
        print(f"error: {exc.filename}: {exc.strerror or exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
