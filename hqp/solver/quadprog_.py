"""quadprog backend through qpsolvers (Goldfarb-Idnani, needs a positive definite H)."""

from __future__ import annotations

import numpy as np
import qpsolvers

from hqp.solver.backend import QPBackend, one_sided

REGULARIZATION = 1e-11
"""Relative diagonal shift added to ``H`` (times ``max(1, max diag H)``):
quadprog factorises ``H`` by Cholesky. The hierarchical solver works in the
reduced coordinates of the optimal set, so the shift only acts on directions
the level's cost leaves free; its effect on a level's cost is below
``1e-11 * ||v||^2`` relative, inside the contract's ``1e-6``."""


class QuadprogBackend(QPBackend):
    """quadprog through ``qpsolvers.solve_problem`` with a tiny relative regularisation."""

    name = "quadprog"
    needs_pd = True

    def solve(self, slot, H, g, E, e, C, lo, up):  # noqa: D102 - documented in the base
        H = _regularized(H, REGULARIZATION)
        G, h = one_sided(C, lo, up)
        has_eq = E is not None and E.shape[0] > 0
        problem = qpsolvers.Problem(H, g, G, h, E if has_eq else None, e if has_eq else None)
        sol = qpsolvers.solve_problem(problem, solver="quadprog")
        x = sol.x if sol.x is not None else np.full(H.shape[0], np.nan)
        return np.asarray(x, dtype=float), bool(sol.found)


def _regularized(H: np.ndarray, rel: float) -> np.ndarray:
    """``H + rel * max(1, max diag H) * I`` (a new array)."""
    scale = max(1.0, float(np.max(np.diag(H)))) if H.size else 1.0
    H = H.copy()
    H[np.diag_indices_from(H)] += rel * scale
    return H
