"""Accuracy against the solver contract: each level's cost over the tightest solution.

The cost of level ``k`` at ``x`` is ``||A_k x - b_k||^2 + ||dist(C_k x, [lower_k, upper_k])||^2``
(ARCHITECTURE.md, "Contract: the solver"). Among the solutions that several solvers return for
the same levels, the *tightest* is the lexicographic minimum of their cost vectors (level 0
first). Ties are decided on the *residual norms* ``sqrt(cost)``: two solutions tie on a level
when their residual norms there differ by at most ``1e-9 * max(1, residual)``. (Deciding ties on
the costs themselves, as an earlier version did with ``1e-9 * max(1, cost)``, let a residual of
up to 3e-5 on a higher level pass as a tie; on ill-conditioned recorded steps a solution that
violated the dynamics rows by 3e-7 was then picked as the reference because it bought a lower
posture cost with that violation, and every exact solution showed a spurious excess there;
``tests/test_bench_suites.py``.) A solver's excess on level ``k`` is its cost there minus the
tightest solution's: 0 for a solver that meets the contract as well as the best one, positive
where it is looser. A negative excess on a lower level can only follow a positive excess on a
level above it (cost moved down the hierarchy).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np

from hqp.solver import Level
from hqp.solver.level import check_level

TIE_RTOL = 1e-9
"""Residual norms ``sqrt(cost)`` within ``TIE_RTOL * max(1, residual)`` are equal when picking
the tightest solution."""


def level_costs(levels: Sequence[Level], x: np.ndarray) -> np.ndarray:
    """Cost of every level at ``x`` ``(L,)``.

    Args:
        levels: The levels, highest priority first.
        x: A point ``(n,)``.

    """
    x = np.asarray(x, dtype=float)
    out = np.zeros(len(levels))
    for k, level in enumerate(levels):
        lv = check_level(level, k, x.size)
        r = lv.A @ x - lv.b if lv.m_eq else np.zeros(0)
        cost = float(r @ r)
        if lv.m_in:
            cx = lv.C @ x
            d = np.where(cx > lv.upper, cx - lv.upper, np.where(cx < lv.lower, cx - lv.lower, 0.0))
            cost += float(d @ d)
        out[k] = cost
    return out


def tightest(costs: Mapping[str, np.ndarray]) -> np.ndarray:
    """Lexicographic minimum of cost vectors (all of the same length ``L``).

    Raises:
        ValueError: No cost vector given.

    """
    if not costs:
        raise ValueError("tightest: no cost vector")
    cands = [np.asarray(c, dtype=float) for c in costs.values()]
    L = cands[0].size
    for k in range(L):
        residuals = [math.sqrt(max(c[k], 0.0)) for c in cands]
        best = min(residuals)
        tol = TIE_RTOL * max(1.0, best)
        cands = [c for c, r in zip(cands, residuals) if r <= best + tol]
    return cands[0]


def excess(costs: Mapping[str, np.ndarray], reference: Mapping[str, np.ndarray] | None = None
           ) -> dict[str, np.ndarray]:
    """Excess cost per level of each solver over the tightest solution.

    Args:
        costs: Cost vectors by solver name.
        reference: Cost vectors the tightest solution is chosen from (default: ``costs``);
            e.g. only the contract's solvers, so that a peer solving another problem (DAQP's
            hierarchy, the null-space law) is measured against the contract, not the reverse.

    Returns:
        ``cost - tightest`` by solver name, ``(L,)`` each.

    """
    ref = tightest(reference if reference is not None else costs)
    return {name: np.asarray(c, dtype=float) - ref for name, c in costs.items()}


def relative_excess(ex: np.ndarray, ref: np.ndarray) -> float:
    """Largest excess over the levels, each relative to ``max(1, tightest cost)``."""
    if ex.size == 0:
        return 0.0
    return float(np.max(ex / np.maximum(1.0, np.abs(ref))))
