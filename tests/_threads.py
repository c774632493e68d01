"""Whether a call releases the GIL: Python code of another thread runs during it."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable

import numpy as np


def assert_runs_beside_python(call: Callable[[], object], seconds: float = 0.3) -> None:
    """Call ``call`` in a worker thread for ``seconds`` while this thread runs Python.

    The worker stamps the time before and after each call; this thread stamps its own loop.
    Were the GIL held across a call, no stamp of this thread could fall inside one (it cannot
    run Python while the worker holds the GIL).
    """
    done = threading.Event()
    calls: list[tuple[float, float]] = []
    ticks: list[float] = []

    def run() -> None:
        t_end = time.perf_counter() + seconds
        while time.perf_counter() < t_end:
            t0 = time.perf_counter()
            call()
            calls.append((t0, time.perf_counter()))
        done.set()

    worker = threading.Thread(target=run)
    worker.start()
    while not done.is_set():
        ticks.append(time.perf_counter())
    worker.join()
    stamps = np.asarray(ticks)
    inside = sum(int(np.count_nonzero((stamps > a) & (stamps < b))) for a, b in calls)
    assert len(calls) >= 10 and inside > 0, (len(calls), inside)
