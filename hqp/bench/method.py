"""The benchmark method shared by every suite.

One process measures every configuration of a suite: each callable is warmed
up, then timed in batches until the median settles (its relative change
between batches falls below ``settle``) or a time budget runs out. Medians and
95th percentiles come from the same samples; suites put ratios beside the
absolute times.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Timing:
    """Wall-clock statistics of one measured callable.

    Attributes:
        median_ms: Median duration of one call [ms].
        p95_ms: 95th percentile [ms].
        reps: Number of timed calls.
        settled: Whether the median settled before the budget ran out.
        cpu_median_ms: Median CPU time of the calling thread per call [ms]: close
            to ``median_ms`` on an idle machine, and robust to other processes
            competing for the cores (wall-clock times are not).

    """

    median_ms: float
    p95_ms: float
    reps: int
    settled: bool
    cpu_median_ms: float = float("nan")


def measure(
    fn: Callable[[], object],
    *,
    warmup: int = 3,
    batch: int = 10,
    min_reps: int = 20,
    max_reps: int = 2000,
    budget_s: float = 1.0,
    settle: float = 0.02,
) -> Timing:
    """Time ``fn()``: warm-up, then batches until the median settles.

    Args:
        fn: The call to time (its result is ignored).
        warmup: Untimed calls first (caches, persistent solvers, imports).
        batch: Calls per batch; the median is compared after each batch.
        min_reps: Minimum timed calls.
        max_reps: Maximum timed calls.
        budget_s: Time budget for the timed calls [s] (at least one batch runs).
        settle: Relative change of the median between two batches below which
            it is considered settled.

    Returns:
        The :class:`Timing` (milliseconds).

    """
    clock = time.perf_counter
    cpu = time.thread_time
    for _ in range(warmup):
        fn()
    samples: list[float] = []
    cpu_samples: list[float] = []
    previous = None
    settled = False
    start = clock()
    while len(samples) < max_reps:
        for _ in range(batch):
            c0 = cpu()
            t0 = clock()
            fn()
            samples.append(clock() - t0)
            cpu_samples.append(cpu() - c0)
        median = float(np.median(samples))
        if len(samples) >= min_reps and previous is not None:
            if abs(median - previous) <= settle * previous:
                settled = True
                break
        previous = median
        if clock() - start > budget_s and len(samples) >= min(min_reps, batch):
            break
    arr = np.array(samples) * 1e3
    return Timing(
        median_ms=float(np.median(arr)),
        p95_ms=float(np.percentile(arr, 95)),
        reps=len(samples),
        settled=settled,
        cpu_median_ms=float(np.median(cpu_samples)) * 1e3,
    )
