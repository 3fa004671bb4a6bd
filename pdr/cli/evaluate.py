"""``pdr eval TARGET`` and ``pdr bench TARGET``: targets come from the ``pdr.eval`` / ``pdr.bench`` groups."""

from __future__ import annotations

import argparse

from pdr.cli import register_group


def _target_command(subparsers: argparse._SubParsersAction, name: str, help_: str, group: str) -> None:
    p = subparsers.add_parser(name, help=help_)
    targets = p.add_subparsers(dest="target", metavar="TARGET")
    targets.required = True
    register_group(targets, group, level=1)


def register(subparsers: argparse._SubParsersAction) -> None:
    _target_command(subparsers, "eval", "evaluate accuracy against ground truth", "pdr.eval")


def register_bench(subparsers: argparse._SubParsersAction) -> None:
    _target_command(subparsers, "bench", "measure speed (samples/s, latency, memory)", "pdr.bench")
