"""Console streams of the command line: keep stdout for the one JSON object.

It imports nothing of the project: every command module of :mod:`hqp.app` can import it.
"""

from __future__ import annotations

import contextlib
import os
import sys
from collections.abc import Iterator
from typing import Any

__all__ = ["stdout_to_stderr"]


@contextlib.contextmanager
def stdout_to_stderr() -> Iterator[Any]:
    """Send everything written to stdout, by Python or by C libraries, to stderr.

    Yields:
        A text stream on the original stdout, for the one JSON object.

    """
    sys.stdout.flush()
    try:
        saved = os.dup(1)
    except OSError:  # no real file descriptor (e.g. captured by a test harness)
        yield sys.stdout
        return
    os.dup2(2, 1)
    original = os.fdopen(os.dup(saved), "w")
    try:
        yield original
    finally:
        sys.stdout.flush()
        original.flush()
        original.close()
        os.dup2(saved, 1)
        os.close(saved)
