"""Results of a hierarchical solve: the solution and one report per level."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

SATISFIED_COST = 1e-10
"""A level is *satisfied* when its optimal cost is at most this value (a
residual norm of 1e-5 in the level's units)."""

ROW_TOL = 1e-7
"""Row tolerance for reports: an inequality row is *active* when ``C_i x`` is
within ``ROW_TOL * max(1, |bound|)`` of a finite bound (or beyond it), and
*violated* when it lies farther than that outside ``[lower, upper]``."""


@dataclass(frozen=True)
class LevelReport:
    """What the solve achieved on one level (all quantities at the returned ``x``).

    Attributes:
        name: The level's name.
        cost: Optimal cost ``||A x - b||^2 + ||dist(C x, [lower, upper])||^2``.
        satisfied: ``cost <= SATISFIED_COST``.
        active: Indices of inequality rows on (or beyond) a bound, ``(k,)`` int.
        violated: Indices of inequality rows outside ``[lower, upper]`` by more than
            the row tolerance, ``(k,)`` int (a subset of ``active``).
        sigma_min: Smallest singular value of the level's matrix projected on the
            optimal set of the levels above: ``M Z`` where ``M`` stacks the
            equality rows and the active or violated inequality rows, ``Z`` an
            orthonormal basis of the directions the levels above leave free (the
            null space of their equality rows and violated rows; carried
            inequalities are not counted). It is the ``m``-th singular value for
            ``m`` rows, so it is 0 when ``m`` exceeds the free dimension, and it
            is reported as 0 when below the rank threshold (``rank_tol`` times the
            level's scale). ``nan`` when not computed (cascade without reports).
        residual_eq: ``A x - b``, ``(m_eq,)``.
        violation_in: Signed distance of ``C x`` outside ``[lower, upper]``
            (positive above ``upper``, negative below ``lower``, 0 inside), ``(m_in,)``.
        weak_directions: Number of directions of the level's projected equality rows whose
            singular value lies below the level's ``weak_threshold`` (and above
            ``1e-7`` of the largest, below which it counts as rank-deficient): their
            targets were scaled down (:class:`hqp.solver.Level`). 0 for a level without a
            threshold.

    """

    name: str
    cost: float
    satisfied: bool
    active: np.ndarray
    violated: np.ndarray
    sigma_min: float
    residual_eq: np.ndarray
    violation_in: np.ndarray
    weak_directions: int = 0


@dataclass(frozen=True)
class Solution:
    """The lexicographic optimum and its per-level reports.

    Attributes:
        x: Solution ``(n,)``.
        levels: One :class:`LevelReport` per level, highest priority first.
        timings: Wall-clock seconds: ``"total"``, ``"final"`` (the final metric
            and minimum-norm steps) and ``"level_<k>"`` for each level ``k``.
        backend: Name of the QP backend.
        algorithm: ``"basis"`` or ``"cascade"``.
        qp_count: Number of QP solves (levels settled by least squares alone need none).

    """

    x: np.ndarray
    levels: tuple[LevelReport, ...]
    timings: dict[str, float] = field(default_factory=dict)
    backend: str = ""
    algorithm: str = ""
    qp_count: int = 0

    @property
    def costs(self) -> np.ndarray:
        """Optimal cost of each level, ``(L,)``."""
        return np.array([lv.cost for lv in self.levels])

    @property
    def satisfied(self) -> bool:
        """Whether every level is satisfied."""
        return all(lv.satisfied for lv in self.levels)
