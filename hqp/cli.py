"""The ``hqp`` command line: one subcommand per function.

``hqp bench --suite SUITE [--json] [--plot DIR] [--quick]`` runs a benchmark
suite (:mod:`hqp.bench`); ``hqp compare``, ``hqp run`` and ``hqp behaviors``
are added by their own modules (:mod:`comparisons.command`,
:mod:`hqp.behaviors.command`). Progress bars and logs go to stderr; with
``--json`` stdout holds the JSON object alone, otherwise a readable table.
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
from collections.abc import Sequence
from typing import Any

from hqp.console import stdout_to_stderr  # re-exported: hqp.cli.stdout_to_stderr stays importable
from hqp.errors import HQPError

logger = logging.getLogger(__name__)


# ------------------------------------------------------------------ bench
def add_bench(subparsers: Any) -> None:
    """Add ``hqp bench``."""
    from hqp.bench import suite_names

    p = subparsers.add_parser(
        "bench", help="run a benchmark suite",
        description="Time solvers or whole control steps (warm-up, repetitions until the "
                    "median settles, median and p95 from one process).")
    p.add_argument("--suite", required=True, help=f"suite: {', '.join(suite_names())}")
    p.add_argument("--json", action="store_true", help="print the JSON object alone on stdout")
    p.add_argument("--plot", metavar="DIR", help="write PNG figures into DIR")
    p.add_argument("--quick", action="store_true",
                   help="a small, short subset (CI smoke test; times are not meaningful)")
    p.set_defaults(func=bench_command)


def bench_command(args: argparse.Namespace) -> int:
    """Run ``hqp bench``."""
    from hqp.bench import get_suite, run_suite
    from hqp.bench.report import format_table, write_plots

    get_suite(args.suite)  # unknown suites fail before any work

    def progress(message: str) -> None:
        logger.info(message)

    if args.json:
        with stdout_to_stderr() as out:
            result = run_suite(args.suite, quick=args.quick, progress=progress)
            if args.plot:
                write_plots(result, args.plot)
            out.write(json.dumps(result) + "\n")
        return 0
    result = run_suite(args.suite, quick=args.quick, progress=progress)
    if args.plot:
        for path in write_plots(result, args.plot):
            logger.info("wrote %s", path)
    print(format_table(result))
    return 0


# --------------------------------------------------- subcommands of others
def add_compare(subparsers: Any) -> None:
    """Add ``hqp compare`` (:mod:`comparisons.command`)."""
    from comparisons import command

    p = subparsers.add_parser("compare", help="run the papers' scenarios",
                              description=command.__doc__)
    command.add_arguments(p)
    p.set_defaults(func=lambda args: command.run(args))


def add_run(subparsers: Any) -> None:
    """Add ``hqp run`` (:mod:`hqp.behaviors.command`)."""
    from hqp.behaviors import command

    command.add_run_parser(subparsers)


def add_behaviors(subparsers: Any) -> None:
    """Add ``hqp behaviors`` (:mod:`hqp.behaviors.command`)."""
    from hqp.behaviors import command

    command.add_behaviors_parser(subparsers)


SUBCOMMANDS = (add_bench, add_compare, add_run, add_behaviors)
"""One function per subcommand; each adds its parser and sets ``func``."""


def build_parser() -> argparse.ArgumentParser:
    """Build the ``hqp`` argument parser (subcommands that fail to import are left out)."""
    parser = argparse.ArgumentParser(
        prog="hqp", description="Whole-body control with a strict hierarchy of QPs.")
    parser.add_argument("-v", "--verbose", action="count", default=0,
                        help="more log output on stderr (-v info, -vv debug)")
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND")
    for add in SUBCOMMANDS:
        try:
            add(subparsers)
        except ImportError as exc:  # a subcommand's module is not available
            logger.debug("subcommand %s unavailable: %s", add.__name__, exc)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``hqp`` console script; returns the exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
    level = logging.WARNING - 10 * min(args.verbose, 2)
    logging.basicConfig(stream=sys.stderr, level=level,
                        format="%(levelname)s %(name)s: %(message)s")
    if not getattr(args, "func", None):
        parser.print_help(sys.stderr)
        return 2
    try:
        return int(args.func(args) or 0)
    except HQPError as exc:
        print(f"hqp: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
