"""The ``recorded`` suite: real control problems replayed through every solver.

For each recorded source (behavior or scenario on one robot, :mod:`hqp.bench.recorded`), the
steps' level matrices are solved by:

- ``<algorithm>/<backend>``: :class:`hqp.solver.HierarchicalSolver`, basis and cascade on every
  installed backend (one persistent solver per configuration, cycling over the source's steps
  as a control loop would);
- ``daqp-hier``: DAQP's native hierarchy (:class:`hqp.bench.peers.DaqpHierarchy`);
- ``nullspace``: the papers' torque law on the same step's task rows
  (:func:`hqp.bench.peers.nullspace_law_solve`; its inequalities are not enforced).

Timing: :func:`hqp.bench.interleave.interleaved` (every configuration of a source in the same
rounds). Accuracy: each level's cost at the returned ``x`` minus the tightest contract solution
of the same step (:mod:`hqp.bench.accuracy`), largest over the steps (``level_cost_excess``);
``cost_excess`` is the largest over the steps of the step's contract excess
(:func:`hqp.bench.accuracy.relative_excess`: relative to ``max(1, tightest cost)``, down to the
first level where the configuration is strictly ahead of the reference). Basis rows also carry
``speedup_vs_cascade`` (cascade median / basis median, same backend); every row carries
``over_nullspace`` (its median / the law's median on the same steps).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from hqp.bench.accuracy import ExcessTracker, level_costs
from hqp.bench.interleave import Samples, interleaved
from hqp.bench.peers import DaqpHierarchy, law_to_x, nullspace_law_solve
from hqp.bench.recorded import RecordedStep, available, load
from hqp.solver import ALGORITHMS, HierarchicalSolver, available_backends, supports


def _cycler(steps: Sequence[RecordedStep], fn: Callable[[RecordedStep], object]
            ) -> Callable[[], object]:
    """Return a callable that solves the next step on each call (cycling)."""
    state = {"i": 0}

    def call() -> object:
        s = steps[state["i"] % len(steps)]
        state["i"] += 1
        return fn(s)

    return call


def configurations(backends: Sequence[str] | None = None, algorithms: Sequence[str] = ALGORITHMS,
                   peers: bool = True) -> list[str]:
    """Names of the configurations measured (``<algorithm>/<backend>``, peers)."""
    bk = list(backends) if backends is not None else available_backends()
    names = [f"{a}/{b}" for a in algorithms for b in bk if supports(b, a)]
    if peers:
        names += ["daqp-hier", "nullspace"]
    return names


def _solver_fn(name: str) -> Callable[[RecordedStep], np.ndarray]:
    if name == "daqp-hier":
        peer = DaqpHierarchy()
        return lambda s: peer.solve(s.levels)[0]
    if name == "nullspace":
        return lambda s: law_to_x(s, nullspace_law_solve(s).qdd)  # type: ignore[attr-defined]
    algorithm, backend = name.split("/")
    solver = HierarchicalSolver(backend, algorithm)
    return lambda s: solver.solve(s.levels).x


def _timed_fn(name: str) -> Callable[[RecordedStep], object]:
    """Return what is timed: the solve only (the law without the mapping to ``x``)."""
    if name == "nullspace":
        return nullspace_law_solve
    if name == "daqp-hier":
        peer = DaqpHierarchy()
        return lambda s: peer.solve(s.levels)
    algorithm, backend = name.split("/")
    solver = HierarchicalSolver(backend, algorithm)
    return lambda s: solver.solve(s.levels)


SLOW_SECONDS = 0.25
"""A configuration whose solves take more CPU time than this in the accuracy pass (median) is
not timed again: its row reports the accuracy pass's times (``"probe_only": true``)."""


def accuracy(
    steps: Sequence[RecordedStep], names: Sequence[str]
) -> tuple[dict[str, np.ndarray], dict[str, float], dict[str, str], dict[str, Samples]]:
    """Excesses (largest over the steps) of each configuration, and failures.

    Returns:
        ``(excess per level by name (L,), contract excess by name (see
        :func:`hqp.bench.accuracy.relative_excess`), error message by failed name, timings of
        the accuracy pass's solves by name)``.

    """
    import time

    fns = {}
    failed: dict[str, str] = {}
    for name in names:
        try:
            fns[name] = _solver_fn(name)
        except Exception as exc:  # noqa: BLE001 - an unavailable configuration is reported
            failed[name] = f"{type(exc).__name__}: {exc}"
    L = len(steps[0].levels)
    tracker = ExcessTracker()
    probe: dict[str, list[float]] = {name: [] for name in fns}
    probe_cpu: dict[str, list[float]] = {name: [] for name in fns}
    for s in steps:
        costs: dict[str, np.ndarray] = {}
        for name, fn in fns.items():
            if name in failed:
                continue
            try:
                c0 = time.process_time()
                t0 = time.perf_counter()
                x = fn(s)
                probe[name].append(time.perf_counter() - t0)
                probe_cpu[name].append(time.process_time() - c0)
            except Exception as exc:  # noqa: BLE001 - a solver failure is a result
                failed[name] = f"t={s.t:.3f}: {type(exc).__name__}: {exc}"
                continue
            c = level_costs(s.levels, x) if np.all(np.isfinite(x)) else np.full(L, np.inf)
            costs[name] = c
        contract = {k: v for k, v in costs.items() if "/" in k and np.all(np.isfinite(v))}
        if not contract:
            continue
        tracker.add(costs, contract)
    worst = {k: tracker.level.get(k, np.full(L, -np.inf)) for k in fns if k not in failed}
    rel = {k: tracker.contract.get(k, -np.inf) for k in worst}
    return (worst, rel, failed,
            {k: Samples(np.asarray(v), False, np.asarray(probe_cpu[k])) for k, v in probe.items()})


def run_source(steps: Sequence[RecordedStep], names: Sequence[str], *, quick: bool = False,
               progress: Callable[[str], None] | None = None) -> list[dict[str, Any]]:
    """Rows of one recorded source (same robot, same level shapes)."""
    ex, contract_excess, failed, probe = accuracy(steps, names)
    slow = {n for n in names if n not in failed and np.median(probe[n].cpu) > SLOW_SECONDS}
    timed = [n for n in names if n not in failed and n not in slow]
    fns = {n: _cycler(steps, _timed_fn(n)) for n in timed}
    settings = dict(warmup=2, batch=2, min_samples=4, max_seconds=2.0) if quick else dict(
        warmup=len(steps) * 2, batch=len(steps), min_samples=max(40, 4 * len(steps)),
        max_seconds=20.0)
    timings = interleaved(fns, progress=progress, **settings)  # type: ignore[arg-type]
    s0 = steps[0]
    base = {"suite": "recorded", "source": s0.source, "robot": s0.robot,
            "levels": len(s0.levels), "n": s0.n, "rows": s0.rows, "steps": len(steps)}
    rows: list[dict[str, Any]] = []
    for name in names:
        row = dict(base)
        algorithm, _, backend = name.partition("/")
        row.update(solver=name, algorithm=algorithm if backend else None,
                   backend=backend or None)
        if name in failed:
            row.update(median_ms=None, p95_ms=None, failed=failed[name])
            rows.append(row)
            continue
        t = timings[name] if name in timings else probe[name]
        if name in slow:
            row["probe_only"] = True
        e = ex[name]
        rel = contract_excess[name] if e.size else 0.0
        row.update(median_ms=round(t.median_ms, 4), p95_ms=round(t.p95_ms, 4),
                   settled=t.settled, samples=int(t.samples.size),
                   cpu_median_ms=round(t.cpu_median_ms, 4) if t.cpu.size else None,
                   level_cost_excess=[float(f"{v:.3g}") for v in e],
                   cost_excess=float(f"{rel:.3g}"))
        rows.append(row)
    _ratios(rows)
    return rows


def _ratios(rows: list[dict[str, Any]]) -> None:
    """Add ``speedup_vs_cascade`` to basis rows and ``over_nullspace`` to every row.

    Both from the wall-clock medians, and with ``_cpu`` from the CPU-time medians.
    """
    for key, suffix in (("median_ms", ""), ("cpu_median_ms", "_cpu")):
        med = {r["solver"]: r[key] for r in rows if r.get(key)}
        law = med.get("nullspace")
        for r in rows:
            m = r.get(key)
            if not m:
                continue
            if r.get("algorithm") == "basis":
                # native: against the Python algorithms on the same QP library (DAQP)
                bk = "daqp" if r["backend"] == "native" else r["backend"]
                c = med.get(f"cascade/{bk}")
                r["speedup_vs_cascade" + suffix] = round(c / m, 3) if c else None
                if r["backend"] == "native" and med.get("basis/daqp"):
                    r["speedup_vs_python_basis" + suffix] = round(med["basis/daqp"] / m, 3)
            if law:
                r["over_nullspace" + suffix] = round(m / law, 3)


def run(*, quick: bool = False, directory: str | Path | None = None,
        backends: Sequence[str] | None = None, sources: Sequence[str] | None = None,
        progress: Callable[[str], None] | None = None) -> list[dict[str, Any]]:
    """Run the ``recorded`` suite.

    Args:
        quick: One file, its first two steps, two configurations and the law, a few samples
            (for tests; times are not meaningful).
        directory: Recorded files (default: the package's).
        backends: Backends (default: every installed one).
        sources: Only files whose ``source`` is in this list.
        progress: Status lines (stderr).

    Returns:
        The rows (one per source and configuration).

    """
    files = available(directory)
    rows: list[dict[str, Any]] = []
    if quick:
        files = files[:1]
        names = ["basis/proxsuite", "cascade/proxsuite", "daqp-hier", "nullspace"]
    else:
        names = configurations(backends)
    for path in files:
        steps = load(path)
        if not steps or (sources and steps[0].source not in sources):
            continue
        if quick:
            steps = steps[:2]
        if progress is not None:
            progress(f"recorded: {path.name} ({len(steps)} steps, n = {steps[0].n})")
        rows.extend(run_source(steps, names, quick=quick, progress=None))
    return rows


def summary(rows: Sequence[dict[str, Any]], cpu: bool = False) -> dict[str, Any]:
    """Geometric-mean speed-ups of basis over cascade per backend, and HQP over the law.

    Args:
        rows: Rows of the suite.
        cpu: From the CPU-time medians (else wall-clock).

    """
    out: dict[str, Any] = {"speedup_vs_cascade": {}, "basis_over_nullspace": {}}
    by_backend: dict[str, list[float]] = {}
    over_law: dict[str, list[float]] = {}
    key = "_cpu" if cpu else ""
    for r in rows:
        if r.get("algorithm") == "basis" and r.get("speedup_vs_cascade" + key):
            by_backend.setdefault(r["backend"], []).append(r["speedup_vs_cascade" + key])
        if r.get("algorithm") == "basis" and r.get("over_nullspace" + key):
            over_law.setdefault(r["backend"], []).append(r["over_nullspace" + key])
    for b, v in by_backend.items():
        out["speedup_vs_cascade"][b] = round(float(np.exp(np.mean(np.log(v)))), 3)
    for b, v in over_law.items():
        out["basis_over_nullspace"][b] = round(float(np.exp(np.mean(np.log(v)))), 3)
    return out
