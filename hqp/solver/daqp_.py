"""DAQP backend through qpsolvers (dual active set, exact on its active set)."""

from __future__ import annotations

import numpy as np
import qpsolvers

from hqp.solver.backend import QPBackend, one_sided

SETTINGS = {
    "primal_tol": 1e-10,
    "dual_tol": 1e-12,
    "eps_prox": 1e-6,
    "iter_limit": 10000,
}
"""DAQP settings: tight primal tolerance, and a forced proximal outer loop
(``eps_prox > 0``): DAQP needs a positive definite Hessian, and the least-squares
Hessians of a hierarchy are only semidefinite. Proximal-point iterations
``min f(v) + eps/2 ||v - v_prev||^2`` converge to an exact minimiser of ``f``
(no bias, unlike a fixed regularisation)."""


class DaqpBackend(QPBackend):
    """DAQP through ``qpsolvers.solve_problem`` with its proximal outer loop."""

    name = "daqp"
    needs_pd = True

    def solve(self, slot, H, g, E, e, C, lo, up):  # noqa: D102 - documented in the base
        G, h = one_sided(C, lo, up)
        has_eq = E is not None and E.shape[0] > 0
        problem = qpsolvers.Problem(H, g, G, h, E if has_eq else None, e if has_eq else None)
        sol = qpsolvers.solve_problem(problem, solver="daqp", **SETTINGS)
        x = sol.x if sol.x is not None else np.full(H.shape[0], np.nan)
        return np.asarray(x, dtype=float), bool(sol.found)

