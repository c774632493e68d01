"""Peers of the contract solver measured by the benchmark: DAQP's hierarchy, the null-space law.

* :class:`DaqpHierarchy`: DAQP's native hierarchical mode (:mod:`hqp.bench.daqp_hier`:
  ``daqp.solve(..., break_points=...)``), the level data stacked at every solve. It solves
  a *different* problem (docs/reference/contracts.md): each level minimises the row-normalised
  violations ``sum_i dist(c_i x, [l_i, u_i])^2 / ||c_i||^2``;
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

from hqp.bench.daqp_hier import daqp_hierarchy_data, solve_daqp_hierarchy
from hqp.nullspace import prioritized_torques
from hqp.solver import Level


class DaqpHierarchy:
    """DAQP's hierarchy on contract levels (:mod:`hqp.bench.daqp_hier`), stacked on every call."""

    name = "daqp-hier"

    def solve(self, levels: Sequence[Level]) -> tuple[np.ndarray, int]:
        """Solve; return ``x`` ``(n,)`` and DAQP's exit flag (1 optimal, 2 soft-optimal).

        Raises:
            InvalidLevel: Malformed levels (as the contract solver).

        """
        return solve_daqp_hierarchy(daqp_hierarchy_data(levels))


def nullspace_law_x(step: object) -> np.ndarray:
    """Run the null-space law on a recorded step; return ``x = [qdd | wrenches]``.

    The law (:func:`hqp.nullspace.prioritized_torques`, support-consistent form, whitened,
    min-norm internal forces) gives ``qdd``; the wrenches are the least-norm solution of the
    step's physics level (floating-base dynamics, released slots at zero) at that ``qdd``, i.e.
    the contact wrenches that make the law's accelerations consistent with the dynamics.

    Args:
        step: A :class:`hqp.bench.recorded.RecordedStep`.

    """
    s = step
    law = prioritized_torques(s.M, s.h, list(s.law_levels), S=s.S, support=s.support,
                              internal_forces="min-norm")
    return law_to_x(s, law.qdd)


def nullspace_law_solve(step: object) -> object:
    """One solve of the law on a recorded step (timed by the benchmark)."""
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
