"""Benchmarks: ``raygs-viewer bench accuracy`` (what accuracy costs in time)."""

from __future__ import annotations

import argparse


def add_parser(commands) -> None:
    """Adds ``bench`` and its subcommands to the CLI's subparsers."""
    bench = commands.add_parser("bench", help="benchmarks (accuracy against time)")
    kinds = bench.add_subparsers(dest="bench", required=True, parser_class=type(bench))
    kinds.add_parser("accuracy", help="GPU time and error against ground truth of every accuracy option")


def command(args: argparse.Namespace) -> int:
    raise NotImplementedError("bench accuracy is being written")
