"""Peers of the contract solver measured by the benchmark: DAQP's hierarchy, the null-space law.

* :func:`daqp_hierarchy`: DAQP's native hierarchical mode (``daqp.solve(None, None, ...,
  break_points=...)``). It solves a *different* problem (ARCHITECTURE.md): each level
  minimises the row-normalised violations ``sum_i dist(c_i x, [l_i, u_i])^2 / ||c_i||^2``;
  it is timed beside the contract's algorithms and its level-cost excess against the contract
  is reported.
* :func:`nullspace_law_x`: the papers' prioritised torque law
  (:func:`hqp.nullspace.prioritized_torques`) on the equality task rows of a recorded step,
  mapped to the step's decision vector ``x = [qdd | wrenches]`` so that the contract's level
  costs can be evaluated at it.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from hqp.solver import Level
from hqp.solver.level import check_level

DAQP_INF = 1e30
"""DAQP's infinity for absent bounds."""


class DaqpHierarchy:
    """DAQP's hierarchical least-squares mode on contract levels (stacked once per call).

    Equality rows have DAQP's sense 5 (active, immutable); inequality rows sense 0; one break
    point after each non-empty level.
    """

    name = "daqp-hier"

    def solve(self, levels: Sequence[Level]) -> tuple[np.ndarray, int]:
        """Solve; return ``x`` ``(n,)`` and DAQP's exit flag (1 optimal, 2 soft-optimal).

        Raises:
            InvalidLevel: Malformed levels (as the contract solver).

        """
        import daqp

        rows: list[np.ndarray] = []
        up: list[np.ndarray] = []
        lo: list[np.ndarray] = []
        sense: list[np.ndarray] = []
        breaks: list[int] = []
        n = None
        total = 0
        for k, level in enumerate(levels):
            lv = check_level(level, k, n)
            n = lv.A.shape[1]
            m = 0
            if lv.m_eq:
                rows.append(lv.A)
                up.append(lv.b)
                lo.append(lv.b)
                sense.append(np.full(lv.m_eq, 5, dtype=np.int32))
                m += lv.m_eq
            if lv.m_in:
                keep = lv.bounded
                rows.append(lv.C[keep])
                up.append(np.minimum(lv.upper[keep], DAQP_INF))
                lo.append(np.maximum(lv.lower[keep], -DAQP_INF))
                sense.append(np.zeros(int(keep.sum()), dtype=np.int32))
                m += int(keep.sum())
            if m:
                total += m
                breaks.append(total)
        if n is None or not rows:
            return np.zeros(0 if n is None else n), 1
        A = np.ascontiguousarray(np.concatenate(rows))
        x, _fval, flag, _info = daqp.solve(
            None, None, A, np.concatenate(up), np.concatenate(lo), np.concatenate(sense),
            np.asarray(breaks, dtype=np.int32))
        return np.asarray(x, dtype=float), int(flag)


def nullspace_law_x(step: object) -> np.ndarray:
    """Run the null-space law on a recorded step; return ``x = [qdd | wrenches]``.

    The law (:func:`hqp.nullspace.prioritized_torques`, support-consistent form, whitened,
    min-norm internal forces) gives ``qdd``; the wrenches are the least-norm solution of the
    step's physics level (floating-base dynamics, released slots at zero) at that ``qdd``, i.e.
    the contact wrenches that make the law's accelerations consistent with the dynamics.

    Args:
        step: A :class:`hqp.bench.recorded.RecordedStep`.

    """
    from hqp.nullspace import prioritized_torques

    s = step
    law = prioritized_torques(s.M, s.h, list(s.law_levels), S=s.S, support=s.support,
                              internal_forces="min-norm")
    return law_to_x(s, law.qdd)


def nullspace_law_solve(step: object) -> object:
    """One solve of the law on a recorded step (timed by the benchmark)."""
    from hqp.nullspace import prioritized_torques

    s = step
    return prioritized_torques(s.M, s.h, list(s.law_levels), S=s.S, support=s.support,
                               internal_forces="min-norm")


def law_to_x(step: object, qdd: np.ndarray) -> np.ndarray:
    """Complete the law's ``qdd`` ``(nv,)`` into ``x`` ``(n,)`` (least-norm wrenches of level 0)."""
    s = step
    x = np.zeros(s.n)
    x[: s.nv] = qdd
    if s.n == s.nv:
        return x
    top = s.levels[0]
    if top.A is None:
        return x
    A = np.asarray(top.A)
    b = np.asarray(top.b) if top.b is not None else np.zeros(A.shape[0])
    w, *_ = np.linalg.lstsq(A[:, s.nv:], b - A[:, : s.nv] @ qdd, rcond=None)
    x[s.nv:] = w
    return x
