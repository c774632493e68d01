"""The inequality rows carried from the levels solved so far to the levels below.

Both algorithms keep the satisfied inequality rows of the levels above as
``gl <= G x <= gu`` (the basis algorithm in the full ``x``, projected on its basis
when a level reads them; the cascade as the held rows of its QPs), their bounds
widened to contain the optimum and kept :data:`CARRY_MARGIN` away from it.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from hqp.solver.active_set import CarriedRows

CARRY_MARGIN = 1e-9
"""Margin (times ``max(1, |bound|)``) added to the bounds of inequality rows
carried to lower levels, and kept when a carried bound is widened to contain
a later optimum. Rows active at a level's optimum, and above all rows left
slightly violated (below :data:`hqp.solver.basis.FIX_TOL`), whose violation is
unique over the optimal set, are implicit equalities: with a zero-width (or
1e-9-wide) slab the lower levels' feasible sets are flat in those directions,
ProxQP then stalls for its whole iteration budget and DAQP reports them
infeasible (real whole-body stacks: friction-cone, torque and joint-limit
rows). A lower level can move such a row by at most this margin, i.e. raise
the level's cost by at most ``2 v m + m^2`` per row with ``v < FIX_TOL`` its
violation, far inside the contract's ``1e-6`` tolerance."""

FEAS_TOL = 1e-9
"""Feasibility tolerance (times ``max(1, |bound|)``) when checking whether a
least-squares point satisfies inequalities."""

_NO_ROWS = np.zeros(0, dtype=int)


def within(
    cx: np.ndarray, lo: np.ndarray, up: np.ndarray, lo_s: np.ndarray, up_s: np.ndarray
) -> bool:
    """Whether ``lo - tol <= cx <= up + tol`` with ``tol = FEAS_TOL * scale``."""
    return bool((cx >= lo - FEAS_TOL * lo_s).all() and (cx <= up + FEAS_TOL * up_s).all())


def inside(
    cx: np.ndarray, lo: np.ndarray, up: np.ndarray, lo_s: np.ndarray, up_s: np.ndarray
) -> bool:
    """Whether ``lo + tol <= cx <= up - tol`` with ``tol = FEAS_TOL * scale`` (strictly inside).

    The anchor's test (:meth:`hqp.solver.basis.BasisAlgorithm._anchored`): a point within the
    feasibility band of :func:`within` but not inside it (a row at its bound to rounding) is
    left to the active set, whose point does not depend on where the least squares started.
    """
    return bool((cx >= lo + FEAS_TOL * lo_s).all() and (cx <= up - FEAS_TOL * up_s).all())


def inequality_offsets(all_levels: Sequence[tuple[Any, Any]]) -> tuple[list[int], int]:
    """Index of each level's first inequality row among all of the hierarchy's, and their count."""
    offsets = []
    total_in = 0
    for lv, _kind in all_levels:
        offsets.append(total_in)
        total_in += lv.m_in
    return offsets, total_in


class Carried:
    """The carried rows ``gl <= G x <= gu`` over the full ``x`` ``(n,)``.

    Attributes:
        G: Rows ``(p, n)``; ``gl``, ``gu``: bounds ``(p,)``; ``gls``, ``gus``: their
            tolerance scales; ``gid``: each row's index among all inequality rows of the
            hierarchy (the warm start's memory is keyed on it).

    """

    __slots__ = ("G", "gl", "gu", "gls", "gus", "gid")

    def __init__(self, n: int) -> None:
        self.G = np.zeros((0, n))
        self.gl = np.zeros(0)
        self.gu = np.zeros(0)
        self.gls = np.zeros(0)
        self.gus = np.zeros(0)
        self.gid = _NO_ROWS

    @property
    def count(self) -> int:
        """Number of carried rows."""
        return self.G.shape[0]

    def contains(self, gx: np.ndarray) -> bool:
        """Whether ``G x`` (given as ``gx``) is within the bounds (:data:`FEAS_TOL`)."""
        return within(gx, self.gl, self.gu, self.gls, self.gus)

    def inside(self, gx: np.ndarray) -> bool:
        """Whether ``G x`` (given as ``gx``) is strictly inside the bounds (:func:`inside`)."""
        return inside(gx, self.gl, self.gu, self.gls, self.gus)

    def shifted(self, G: np.ndarray, gx: np.ndarray) -> CarriedRows:
        """Return the rows ``G`` (``self.G`` projected) with the bounds moved by ``-gx``."""
        return CarriedRows(G, self.gl - gx, self.gu - gx, self.gls, self.gus)

    def rows(self) -> CarriedRows:
        """Return the rows as they are (the cascade's coordinates)."""
        return CarriedRows(self.G, self.gl, self.gu, self.gls, self.gus)

    def widen(self, gx: np.ndarray) -> None:
        """Widen the bounds in place to contain ``gx``, keeping :data:`CARRY_MARGIN`.

        A bound that ``gx`` crosses (by the QP's tolerance) moves to ``gx`` plus the
        margin, so no carried row is left with a zero-width side.
        """
        below = gx < self.gl
        if below.any():
            self.gl[below] = gx[below] - CARRY_MARGIN * self.gls[below]
        above = gx > self.gu
        if above.any():
            self.gu[above] = gx[above] + CARRY_MARGIN * self.gus[above]

    def contain(self, gx: np.ndarray) -> None:
        """Widen the bounds in place to contain ``gx`` exactly (no margin)."""
        np.minimum(self.gl, gx, out=self.gl)
        np.maximum(self.gu, gx, out=self.gu)

    def add(self, rows: np.ndarray, values: np.ndarray, lower: np.ndarray, upper: np.ndarray,
            lo_scale: np.ndarray, up_scale: np.ndarray, ids: np.ndarray) -> None:
        """Carry ``rows`` (values ``values`` at the optimum), bounds widened to contain them.

        Args:
            rows: The rows ``(k, n)``.
            values: Their values at the optimum ``(k,)``.
            lower: Their lower bounds ``(k,)``.
            upper: Their upper bounds ``(k,)``.
            lo_scale: Tolerance scales of ``lower``.
            up_scale: Tolerance scales of ``upper``.
            ids: The rows' indices among all inequality rows of the hierarchy ``(k,)``.

        """
        self.G = np.concatenate((self.G, rows))
        self.gl = np.concatenate((self.gl, np.minimum(lower, values) - CARRY_MARGIN * lo_scale))
        self.gu = np.concatenate((self.gu, np.maximum(upper, values) + CARRY_MARGIN * up_scale))
        self.gls = np.concatenate((self.gls, lo_scale))
        self.gus = np.concatenate((self.gus, up_scale))
        self.gid = np.concatenate((self.gid, ids))
