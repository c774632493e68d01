"""The ``hqp`` command line: one module of :mod:`hqp.app` per subcommand.

``hqp compare`` (:mod:`hqp.app.compare`), ``hqp run`` (:mod:`hqp.app.run`), ``hqp behaviors``
(:mod:`hqp.app.behaviors`), ``hqp bench`` (:mod:`hqp.app.bench`), ``hqp view``
(:mod:`hqp.app.view`), ``hqp sweep`` (:mod:`hqp.app.sweep`). Progress bars and logs go
to stderr; with ``--json`` stdout holds the JSON object alone, otherwise a readable table.
"""

from __future__ import annotations

import argparse
import logging
import os
import sys
from collections.abc import Sequence

try:  # MuJoCo sets up its OpenGL backend (MUJOCO_GL) when it is imported: fail in one line
    import mujoco  # noqa: F401
except (AttributeError, ImportError, OSError, RuntimeError) as exc:
    if "MUJOCO_GL" not in os.environ:
        raise
    print(f"hqp: error: MUJOCO_GL={os.environ['MUJOCO_GL']}: MuJoCo cannot load this OpenGL "
          f"backend ({type(exc).__name__}: {exc}); install it (osmesa: libosmesa6, egl: "
          "libegl1), choose another (egl, osmesa, glfw) or unset MUJOCO_GL", file=sys.stderr)
    raise SystemExit(2) from None

from hqp.app import behaviors, bench, compare, run, sweep, view
from hqp.errors import HQPError

SUBCOMMANDS = (bench.add_parser, compare.add_parser, run.add_parser, behaviors.add_parser,
               view.add_parser, sweep.add_parser)
"""One function per subcommand; each adds its parser and sets ``func``."""


def build_parser() -> argparse.ArgumentParser:
    """Build the ``hqp`` argument parser."""
    parser = argparse.ArgumentParser(
        prog="hqp", description="Whole-body control with a strict hierarchy of QPs.")
    parser.add_argument("-v", "--verbose", action="count", default=0,
                        help="more log output on stderr (-v info, -vv debug)")
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND")
    for add in SUBCOMMANDS:
        add(subparsers)
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
