"""The ``pdr`` command: one entry point, subcommands contributed by each package.

Subcommands are declared as entry points in the ``pdr.commands`` group of ``pyproject.toml``; each
points at a ``register(subparsers)`` function that adds its parser and sets ``func`` (a callable
taking the parsed ``argparse.Namespace`` and returning an exit code). Targets of ``pdr eval`` come
from the ``pdr.eval`` group in the same way. pdr/ never imports server/ or classifiers/ directly.
"""

from __future__ import annotations

import argparse
import logging
import sys
from collections.abc import Sequence
from importlib.metadata import entry_points

from pdr.errors import InputError

log = logging.getLogger("pdr")


def _unavailable(name: str, error: Exception):  # noqa: ANN202
    def run(args: argparse.Namespace) -> int:
        print(f"error: the '{name}' command is not available in this installation ({error})", file=sys.stderr)
        return 2
    return run


def register_group(subparsers: argparse._SubParsersAction, group: str) -> None:
    """Add every entry point of ``group`` to ``subparsers``; a broken plugin becomes an error command."""
    for ep in sorted(entry_points(group=group), key=lambda e: e.name):
        try:
            ep.load()(subparsers)
        except (ImportError, AttributeError) as exc:
            p = subparsers.add_parser(ep.name, help=f"(unavailable: {exc})")
            p.set_defaults(func=_unavailable(ep.name, exc))


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="pdr", description="Pedestrian navigation backend: read logs, simulate, track, classify, serve.")
    parser.add_argument("-v", "--verbose", action="store_true", help="log progress to stderr")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    register_group(sub, "pdr.commands")
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the ``pdr`` command line; returns the process exit code."""
    parser = build_parser()
    args = parser.parse_args(argv)
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


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
