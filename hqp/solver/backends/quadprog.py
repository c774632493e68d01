"""quadprog backend through qpsolvers (Goldfarb-Idnani, needs a positive definite H)."""

from __future__ import annotations

import numpy as np
import qpsolvers

from hqp.solver.backends import QPBackend, one_sided

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
        Eq = E if has_eq else None
        eq = e if has_eq else None
        # one regularised solve, kept if it meets the (unregularised) KKT conditions
        try:
            sol = qpsolvers.solve_problem(
                qpsolvers.Problem(_regularized(H, REGULARIZATION_SEQUENCE[0]), g, G, h, Eq, eq),
                solver="quadprog")
        except qpsolvers.ProblemError:
            sol = None
        if sol is not None and sol.found and sol.x is not None and _kkt_ok(
                H, g, G, h, Eq, eq, sol):
            return np.asarray(sol.x, dtype=float), True
        v = self._proximal(H, g, G, h, Eq, eq)
        if v is not None:
            return v, True
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

    @staticmethod
    def _proximal(H, g, G, h, E, e):
        """Proximal-point iterations ``min f(v) + rho/2 ||v - v_k||^2`` (``None`` on failure).

        quadprog works with ``H^{-1}``: on a level whose reduced Hessian is
        singular (an inequality-only level: zero block on the reduced
        coordinates), a tiny regularisation makes its dual steps lose about
        ``cond(H) * eps`` of accuracy, and it then reports success at points
        whose cost is far from optimal (the ``screwgun`` and ``reach`` real
        problems). With ``rho`` of the order of ``H``'s scale each subproblem is
        well conditioned, and the iterates converge to an exact minimiser of
        ``f`` (no bias): the iteration stops when a step moves ``v`` by less than
        :data:`PROX_STEP_TOL` (relative).
        """
        scale = max(1.0, float(np.max(np.diag(H)))) if H.size else 1.0
        rho = PROX_RHO * scale
        Hr = H.copy()
        Hr[np.diag_indices_from(Hr)] += rho
        v = np.zeros(H.shape[0])
        hs = None if h is None else h + PROX_RELAX * np.maximum(1.0, np.abs(h))
        for _ in range(PROX_MAX_ITER):
            sol = None
            for hh in (h, hs):
                # quadprog's dual steps can declare a feasible set only ~1e-9 thick
                # infeasible: then the bounds relaxed by PROX_RELAX
                try:
                    sol = qpsolvers.solve_problem(
                        qpsolvers.Problem(Hr, g - rho * v, G, hh, E, e), solver="quadprog")
                except (qpsolvers.ProblemError, ValueError):
                    return None
                if sol.found and sol.x is not None and np.isfinite(sol.x).all():
                    break
                if hh is None:
                    return None
            if sol is None or not sol.found or sol.x is None or not np.isfinite(sol.x).all():
                return None
            step = float(np.abs(sol.x - v).max())
            v = np.asarray(sol.x, dtype=float)
            if step <= PROX_STEP_TOL * max(1.0, float(np.abs(v).max())):
                return v
        return None


PROX_RHO = 1e-4
"""Proximal weight relative to ``max(1, max diag H)`` (the hierarchy normalises ``H``)."""

PROX_RELAX = 1e-9
"""Relative relaxation of the bounds when quadprog reports a thin feasible set infeasible."""

PROX_STEP_TOL = 1e-11
"""Relative step below which the proximal iterations have converged."""

PROX_MAX_ITER = 200
"""Proximal iterations before falling back to the regularised single solve."""


KKT_TOL = 1e-9
"""Relative tolerance of the KKT check of a quadprog solution (stationarity,
primal feasibility, multiplier signs, complementarity)."""


def _kkt_ok(H, g, G, h, E, e, sol) -> bool:
    """Whether quadprog's primal-dual solution meets the unregularised problem's KKT conditions.

    quadprog reports success at points far from optimal when ``H`` is nearly
    singular (its dual steps use ``H^{-1}``); its multipliers then fail these
    checks, which cost a few matrix-vector products.
    """
    x = np.asarray(sol.x, dtype=float)
    r = H @ x + g
    scale = max(1.0, float(np.abs(g).max()) if g.size else 0.0,
                float(np.abs(H).max()) * float(np.abs(x).max()) if x.size else 0.0)
    if G is not None:
        z = sol.z
        if z is None:
            return False
        gap = G @ x - h
        hs = np.maximum(1.0, np.abs(h))
        if (gap > KKT_TOL * hs).any() or (z < -KKT_TOL * scale).any():
            return False
        if (np.abs(z * gap) > KKT_TOL * scale * hs).any():
            return False
        r += G.T @ z
    if E is not None:
        if sol.y is None:
            return False
        r += E.T @ sol.y
    return bool(np.abs(r).max() <= KKT_TOL * scale) if r.size else True


def _regularized(H: np.ndarray, rel: float) -> np.ndarray:
    """``H + rel * max(1, max diag H) * I`` (a new array)."""
    scale = max(1.0, float(np.max(np.diag(H)))) if H.size else 1.0
    H = H.copy()
    H[np.diag_indices_from(H)] += rel * scale
    return H
