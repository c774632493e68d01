"""``hqp bench --suite SUITE [--json] [--plot DIR] [--quick]``: run a benchmark suite.

The suites are those of :mod:`hqp.bench`; with ``--json`` stdout holds the contract's object
``{"suite": ..., "rows": [...]}`` alone, otherwise a readable table at most 100 characters wide
(:func:`format_narrow`; ``--wide``: every column, :func:`hqp.bench.report.format_table`).
"""

from __future__ import annotations

import argparse
import json
import logging
from typing import Any

from hqp import robots
from hqp.app.console import stdout_to_stderr
from hqp.bench import get_suite, run_suite, suite_names
from hqp.bench.report import COLUMNS, format_table, write_plots
from hqp.tables import format_columns

logger = logging.getLogger(__name__)

WIDTH = 100
"""Widest line of the default table [characters]."""
NAMES = ("suite", "source", "robot", "solver")
"""Columns that name a row (always shown)."""


def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    """Add ``hqp bench``."""
    p = subparsers.add_parser(
        "bench", help="run a benchmark suite",
        description="Time solvers or whole control steps (warm-up, repetitions until the "
                    "median settles, median and p95 from one process).")
    p.add_argument("--suite", required=True, help=f"suite: {', '.join(suite_names())}")
    p.add_argument("--json", action="store_true", help="print the JSON object alone on stdout")
    p.add_argument("--plot", metavar="DIR", help="write PNG figures into DIR")
    p.add_argument("--wide", action="store_true",
                   help="print every column (default: the table fits 100 columns)")
    p.add_argument("--quick", action="store_true",
                   help="a small, short subset (CI smoke test; times are not meaningful)")
    p.add_argument("--robot", action="append", default=None,
                   help="robot name or robot TOML file (repeatable; controller suite: "
                        "instead of its robots)")
    p.set_defaults(func=command)
    return p


def command(args: argparse.Namespace) -> int:
    """Run ``hqp bench``."""
    get_suite(args.suite)  # unknown suites and robots fail before any work
    robot_list = getattr(args, "robot", None)
    for robot in robot_list or ():
        robots.check(robot)

    def progress(message: str) -> None:
        logger.info(message)

    if args.json:
        with stdout_to_stderr() as out:
            result = run_suite(args.suite, quick=args.quick, progress=progress, robots=robot_list)
            if args.plot:
                write_plots(result, args.plot)
            out.write(json.dumps(result) + "\n")
        return 0
    result = run_suite(args.suite, quick=args.quick, progress=progress, robots=robot_list)
    if args.plot:
        for path in write_plots(result, args.plot):
            logger.info("wrote %s", path)
    print(format_table(result) if args.wide else format_narrow(result))
    for entry in result.get("skipped", []):
        print(f"not measured: {entry['robot']} {entry['solver']}: {entry['skipped']}")
    return 0


def format_narrow(result: dict[str, Any], width: int = WIDTH) -> str:
    """Format the suite's rows within ``width`` characters: names first, then the timings."""
    rows = result.get("rows", [])
    cols = [(k, h) for k, h in COLUMNS if any(k in r for r in rows)]
    if not cols:
        return f"suite {result.get('suite')}: no rows"
    keep = sum(1 for k, _ in cols if k in NAMES)
    cols.sort(key=lambda c: c[0] not in NAMES)  # stable: names first, in their order
    lines, left_out = format_columns([h for _, h in cols],
                                     [[r.get(k) for k, _ in cols] for r in rows],
                                     width=width, keep=keep)
    lines = [f"suite: {result.get('suite')}", *lines]
    if left_out:
        lines.append(f"({len(left_out)} more columns: --wide, or --json for every field)")
    return "\n".join(lines)
