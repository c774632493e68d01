"""Console streams of the command line: stdout for the one JSON object, stderr for the rest.

:func:`stdout_to_stderr` keeps stdout for the JSON object, :func:`progress_bar` draws the
progress of a run on stderr, :func:`output_path_problem` says why a path cannot be written,
before a run starts. It imports nothing of the project: every command module of
:mod:`hqp.app` can import it.
"""

from __future__ import annotations

import contextlib
import os
import sys
import tempfile
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

from tqdm import tqdm

__all__ = ["fallback_note", "output_path_problem", "progress_bar", "stdout_to_stderr",
           "TABLE_WIDTH"]

TABLE_WIDTH = 100
"""Widest line of the command line's default tables [columns] (``--wide`` or ``--json``:
every column)."""
PROGRESS_DELAY = 2.0
"""A progress bar appears once a run has taken this long [s of wall-clock time]."""


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


@contextlib.contextmanager
def progress_bar(label: str, unit: str = "s",
                 delay: float = PROGRESS_DELAY) -> Iterator[Callable[[float, float], None]]:
    """Draw a progress bar on stderr for a run of simulated time (tqdm).

    It appears only on a terminal and only after ``delay`` seconds, and is closed (its line
    ended) before an error propagates, so an error message starts on a line of its own.

    Yields:
        ``progress(t, total)``: the run is at ``t`` of ``total`` [``unit``].

    """
    bar: tqdm | None = None

    def progress(t: float, total: float) -> None:
        nonlocal bar
        if bar is None:
            bar = tqdm(total=round(float(total), 3), desc=label, unit=unit, file=sys.stderr,
                       delay=delay, disable=None, dynamic_ncols=True, leave=False,
                       bar_format="{desc}: {percentage:3.0f}%|{bar}| {n:.1f}/{total:.1f} "
                                  "{unit} [{elapsed}<{remaining}]")
        bar.update(round(float(t), 3) - bar.n)

    try:
        yield progress
    finally:
        if bar is not None:
            bar.close()


def output_path_problem(path: str | Path) -> str | None:
    """Say, before a run, why no file can be written at ``path`` (``None``: it can).

    Its folder must exist (or be creatable below an existing, writable folder) and the path
    must not be a folder.
    """
    p = Path(path)
    if p.is_dir():
        return "is a folder; expected a file name"
    parent = p.parent
    while not parent.exists():
        parent = parent.parent
    if not parent.is_dir():
        return f"{str(parent)!r} is not a folder"
    try:
        with tempfile.TemporaryFile(dir=parent):
            pass
    except OSError as exc:
        return f"cannot write in {str(parent)!r} ({exc.strerror})"
    if p.exists() and not os.access(p, os.W_OK):
        return "the file exists and cannot be written"
    return None


def fallback_note(count: int) -> str:
    """Return the summary line of the level QPs quadprog took over (``-vv`` logs each)."""
    return (f"QP fallbacks: quadprog solved {count} level QP(s) the backend could not "
            "(-vv logs each)")
