"""quadprog backend through qpsolvers (Goldfarb-Idnani, needs a positive definite H)."""

from __future__ import annotations

import numpy as np
import qpsolvers

from hqp.solver.backend import QPBackend, one_sided

REGULARIZATION_SEQUENCE = (1e-11, 1e-9, 1e-8)
"""Relative diagonal shifts added to ``H`` (times ``max(1, max diag H)``), tried
in turn: quadprog factorises ``H`` by Cholesky, and its dual steps fail on
nearly dependent active rows when ``H`` is badly conditioned. The hierarchical
solver works in the reduced coordinates of the optimal set, so the shift only
acts on directions the level's cost leaves free; it biases a level's cost by
about ``shift * ||v||^2``, inside the contract's ``1e-6`` relative tolerance
for solutions of moderate norm."""


class QuadprogBackend(QPBackend):
    """quadprog through ``qpsolvers.solve_problem`` with a tiny relative regularisation."""

    name = "quadprog"
    needs_pd = True

    def solve(self, slot, H, g, E, e, C, lo, up):  # noqa: D102 - documented in the base
        G, h = one_sided(C, lo, up)
        has_eq = E is not None and E.shape[0] > 0
        for rel in REGULARIZATION_SEQUENCE:
            problem = qpsolvers.Problem(
                _regularized(H, rel), g, G, h, E if has_eq else None, e if has_eq else None)
            try:
                sol = qpsolvers.solve_problem(problem, solver="quadprog")
            except qpsolvers.ProblemError:
                continue
            if sol.found and sol.x is not None:
                return np.asarray(sol.x, dtype=float), True
        return np.full(H.shape[0], np.nan), False


def _regularized(H: np.ndarray, rel: float) -> np.ndarray:
    """``H + rel * max(1, max diag H) * I`` (a new array)."""
    scale = max(1.0, float(np.max(np.diag(H)))) if H.size else 1.0
    H = H.copy()
    H[np.diag_indices_from(H)] += rel * scale
    return H
