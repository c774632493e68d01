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
    "eta_prox": 1e-12,
}
"""DAQP settings: tight primal tolerance, a forced proximal outer loop
(``eps_prox > 0``) run to a tight stop (``eta_prox``): DAQP needs a positive
definite Hessian, and the least-squares Hessians of a hierarchy are only
semidefinite. Proximal-point iterations
``min f(v) + eps/2 ||v - v_prev||^2`` converge to an exact minimiser of ``f``
(no bias, unlike a fixed regularisation)."""


EPS_PROX_SEQUENCE = (1e-6, 1e-4, 1e-2, -1.0)
"""Proximal weights tried in turn: a small forced one (accurate on semidefinite
least squares), then larger ones (degenerate vertices), then DAQP's automatic choice."""


class DaqpBackend(QPBackend):
    """DAQP through ``qpsolvers.solve_problem`` with its proximal outer loop."""

    name = "daqp"
    needs_pd = True

    def solve(self, slot, H, g, E, e, C, lo, up):  # noqa: D102 - documented in the base
        G, h = one_sided(C, lo, up)
        has_eq = E is not None and E.shape[0] > 0
        problem = qpsolvers.Problem(H, g, G, h, E if has_eq else None, e if has_eq else None)
        sol = None
        for eps_prox in EPS_PROX_SEQUENCE:
            sol = qpsolvers.solve_problem(
                problem, solver="daqp", **{**SETTINGS, "eps_prox": eps_prox})
            if sol.found and sol.x is not None:
                return np.asarray(sol.x, dtype=float), True
        return np.full(H.shape[0], np.nan), False

