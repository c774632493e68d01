"""Accuracy against the solver contract: each level's cost over the tightest solution.

The cost of level ``k`` at ``x`` is ``||A_k x - b_k||^2 + ||dist(C_k x, [lower_k, upper_k])||^2``
(docs/reference/contracts.md, "The solver"). Among the solutions that several solvers return
for the same levels, the *tightest* is the lexicographic minimum of their cost vectors (level 0
first). Ties are decided on the *residual norms* ``sqrt(cost)``: two solutions tie on a level
when their residual norms there differ by at most ``1e-9 * max(1, residual)``.

A solver's excess on level ``k`` is its cost there minus the tightest solution's
(:func:`excess`). Its *contract excess* (:func:`relative_excess`, the benchmarks'
``cost_excess``) is the largest of these relative to ``max(1, tightest cost)`` over the levels
down to the first one where the solver is strictly ahead of the reference (residual lower by
more than the tie): below that level the reference is not an optimum for it to be measured
against, since the reference bought its lower costs with slack on a level above. Peers that
solve another problem (DAQP's hierarchy, the null-space law) are measured on every level.

The reference is the best solution found, not an exact optimum, and on ill-conditioned steps
its slack on a higher level moves the lower levels' costs by more than the contract's 1e-6.
Measured on recorded steps (``tests/test_bench_suites.py``): with ties on the costs (an earlier
version, ``1e-9 * max(1, cost)``, which lets a residual of up to 3e-5 pass as a tie), a
cascade/ProxQP point that violated the dynamics rows by 3.8e-7 became the reference and every
exact solution showed a spurious posture excess of up to 1.3e-5; with ties on residuals alone,
an OSQP point 2.7e-8 tighter on the contact limits became the reference although it violated
the joint limits by 1.1e-4, and bought a lower posture cost with that (spurious 4.9e-6).
Both are 0 by the contract excess above.
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


def relative_excess(ex: np.ndarray, ref: np.ndarray, *, stop_when_ahead: bool = True) -> float:
    """Contract excess: the largest relative excess down to where the solver gets ahead.

    Args:
        ex: Excess cost per level over the tightest solution ``(L,)`` (:func:`excess`).
        ref: The tightest solution's costs ``(L,)``.
        stop_when_ahead: ``False`` counts every level (for a peer that solves another
            problem, e.g. DAQP's hierarchy: its lower costs below a level where it is ahead
            are not bought by rounding).

    Returns:
        ``max_k ex_k / max(1, ref_k)`` over the levels ``k`` down to the first level where the
        solver's residual norm is below the reference's by more than the tie
        (``TIE_RTOL * max(1, residual)``); the levels below it are not counted (see the module
        docstring). ``0.0`` for no level.

    """
    ex = np.asarray(ex, dtype=float)
    ref = np.asarray(ref, dtype=float)
    if ex.size == 0:
        return 0.0
    rel = ex / np.maximum(1.0, np.abs(ref))
    stop = ex.size
    for k in range(ex.size if stop_when_ahead else 0):
        r_ref = math.sqrt(max(float(ref[k]), 0.0))
        r_own = math.sqrt(max(float(ref[k] + ex[k]), 0.0))
        if r_own < r_ref - TIE_RTOL * max(1.0, r_ref):
            stop = k + 1
            break
    return float(np.max(rel[:stop]))


class ExcessTracker:
    """Largest excesses of each solver over a sequence of steps.

    Per step, :meth:`add` picks the tightest of the contract's solutions and records, per
    solver, the excess on each level (largest over the steps: ``level``) and the contract
    excess of :func:`relative_excess` (largest over the steps: ``contract``; every level
    counted for solvers outside the contract's set).
    """

    def __init__(self) -> None:
        self.level: dict[str, np.ndarray] = {}
        self.contract: dict[str, float] = {}

    def add(self, costs: Mapping[str, np.ndarray], contract: Mapping[str, np.ndarray]) -> None:
        """Record one step.

        Args:
            costs: Level costs ``(L,)`` of every solver on the step.
            contract: Those of the contract's solvers (the reference is chosen among them).

        """
        ref = tightest(contract)
        for name, ex in excess(costs, contract).items():
            self.level[name] = ex if name not in self.level else np.maximum(self.level[name], ex)
            rel = relative_excess(ex, ref, stop_when_ahead=name in contract)
            self.contract[name] = max(self.contract.get(name, -math.inf), rel)
