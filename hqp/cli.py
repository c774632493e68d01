"""The ``hqp`` console script (``pyproject.toml``): :mod:`hqp.app.cli`, re-exported."""

from __future__ import annotations

import sys

from hqp.app.cli import SUBCOMMANDS, build_parser, main
from hqp.app.console import stdout_to_stderr

__all__ = ["SUBCOMMANDS", "build_parser", "main", "stdout_to_stderr"]

if __name__ == "__main__":
    sys.exit(main())
