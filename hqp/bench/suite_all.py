"""The ``all`` suite: ``solver``, ``controller`` and ``recorded`` in one run (one process).

Every row keeps a ``suite`` field naming the suite it comes from; the solver suite's rows get
one added here when they lack it.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from hqp.bench import get_suite

PARTS = ("solver", "controller", "recorded")
"""The suites run by ``all``, in order."""


def run(*, quick: bool = False, progress: Callable[[str], None] | None = None
        ) -> list[dict[str, Any]]:
    """Run every suite of :data:`PARTS`; return their rows, each tagged with its suite."""
    rows: list[dict[str, Any]] = []
    for name in PARTS:
        if progress is not None:
            progress(f"all: suite {name}")
        for row in get_suite(name)(quick=quick, progress=progress or (lambda _m: None)):
            row.setdefault("suite", name)
            rows.append(row)
    return rows
