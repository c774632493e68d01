"""OSQP backend through qpsolvers, with polishing and tight tolerances."""

from __future__ import annotations

import numpy as np
import qpsolvers
import scipy.sparse as sp

from hqp.solver.backends import QPBackend, one_sided

SETTINGS = {
    "eps_abs": 1e-10,
    "eps_rel": 0.0,
    "polishing": True,
    "polish_refine_iter": 10,
    "max_iter": 200000,
    "verbose": False,
}
"""OSQP settings: the ADMM iterate is only accurate to ``eps``; polishing solves
the KKT system of the detected active set, which brings the cost within the
contract's tolerance."""


class OsqpBackend(QPBackend):
    """OSQP (ADMM) through ``qpsolvers.solve_problem``; inequalities kept two-sided."""

    name = "osqp"

    def solve(self, slot, H, g, E, e, C, lo, up):  # noqa: D102 - documented in the base
        nv = H.shape[0]
        G, h = one_sided(C, lo, up)
        problem = qpsolvers.Problem(
            sp.csc_matrix(H),
            g,
            None if G is None else sp.csc_matrix(G),
            h,
            None if E is None or E.shape[0] == 0 else sp.csc_matrix(E),
            None if E is None or E.shape[0] == 0 else e,
        )
        sol = qpsolvers.solve_problem(problem, solver="osqp", **SETTINGS)
        x = sol.x if sol.x is not None else np.full(nv, np.nan)
        return np.asarray(x, dtype=float), bool(sol.found)

