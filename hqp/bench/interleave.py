"""Interleaved timing of several configurations in one process (fair ratios on a loaded machine).

Every configuration is a callable doing one unit of work (one control step, one solve). The
callables are run in rounds: in each round every configuration runs ``batch`` calls, in a
rotated order, each call timed with :func:`time.perf_counter`. A slow period of the machine
(other processes on the same cores) therefore hits every configuration alike, and the ratios
between their medians stay meaningful even when the absolute times drift. Each call is also
timed in CPU time of the process (:func:`time.process_time`), which leaves out the periods
when the process waits for a core: on a shared machine it is the steadier figure.

Method: ``warmup`` untimed calls of each configuration first (caches, persistent QPs, warm
starts); then rounds until every configuration has at least ``min_samples`` timed calls and
its running median has moved by less than ``rtol`` over the last round (the median has
settled), or ``max_seconds`` have passed.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class Samples:
    """Timed samples of one configuration.

    Attributes:
        samples: Wall-clock durations of the timed calls ``(N,)`` [s].
        settled: Whether the median settled before the time budget ran out.
        cpu: CPU time of the process during each call ``(N,)`` [s] (empty if not measured).

    """

    samples: np.ndarray
    settled: bool
    cpu: np.ndarray = field(default_factory=lambda: np.zeros(0))

    @property
    def cpu_median_ms(self) -> float:
        """Median CPU time [ms] (``nan`` if not measured)."""
        return float(np.median(self.cpu) * 1e3) if self.cpu.size else float("nan")

    @property
    def median_ms(self) -> float:
        """Median duration [ms]."""
        return float(np.median(self.samples) * 1e3) if self.samples.size else float("nan")

    @property
    def p95_ms(self) -> float:
        """95th percentile [ms]."""
        return float(np.percentile(self.samples, 95) * 1e3) if self.samples.size else float("nan")


def interleaved(
    fns: Mapping[str, Callable[[], object]],
    *,
    warmup: int = 20,
    batch: int = 10,
    min_samples: int = 60,
    rtol: float = 0.02,
    max_seconds: float = 30.0,
    progress: Callable[[str], None] | None = None,
) -> dict[str, Samples]:
    """Time configurations in interleaved rounds until their medians settle.

    Args:
        fns: One callable per configuration name (one unit of work each).
        warmup: Untimed calls of each configuration before timing.
        batch: Timed calls of a configuration per round.
        min_samples: Fewest timed calls per configuration.
        rtol: The median has settled when a round moves it by less than this fraction.
        max_seconds: Time budget of the timed rounds (all configurations together) [s].
        progress: Called with a short status line after each round.

    Returns:
        The timings by configuration name.

    """
    names = list(fns)
    clock = time.perf_counter
    for name in names:
        fn = fns[name]
        for _ in range(warmup):
            fn()
    samples: dict[str, list[float]] = {name: [] for name in names}
    cpu: dict[str, list[float]] = {name: [] for name in names}
    cpu_clock = time.process_time
    last_median = dict.fromkeys(names, np.nan)
    settled = dict.fromkeys(names, False)
    start = clock()
    r = 0
    while True:
        order = names[r % len(names):] + names[: r % len(names)]
        for name in order:
            fn = fns[name]
            out = samples[name]
            out_cpu = cpu[name]
            for _ in range(batch):
                c0 = cpu_clock()
                t0 = clock()
                fn()
                t1 = clock()
                out_cpu.append(cpu_clock() - c0)
                out.append(t1 - t0)
        r += 1
        for name in names:
            med = float(np.median(samples[name]))
            prev = last_median[name]
            settled[name] = (len(samples[name]) >= min_samples and np.isfinite(prev)
                             and abs(med - prev) <= rtol * prev)
            last_median[name] = med
        if progress is not None:
            progress(f"round {r}: {sum(settled.values())}/{len(names)} settled")
        if all(settled.values()) or clock() - start > max_seconds:
            break
    return {name: Samples(np.asarray(samples[name]), settled[name], np.asarray(cpu[name]))
            for name in names}
