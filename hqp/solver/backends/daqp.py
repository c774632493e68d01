"""DAQP backend (dual active set, exact on its active set), called natively."""

from __future__ import annotations

from ctypes import c_int

import daqp
import numpy as np

from hqp.solver.backends import QPBackend

SETTINGS = {
    "primal_tol": 1e-10,
    "dual_tol": 1e-12,
    "iter_limit": 2000,
    "eta_prox": 1e-12,
}
"""DAQP settings: tight primal tolerance, a forced proximal outer loop
(``eps_prox > 0``, see :data:`EPS_PROX_SEQUENCE`) run to a tight stop
(``eta_prox``): DAQP needs a positive definite Hessian, and the least-squares
Hessians of a hierarchy are only semidefinite. Proximal-point iterations
``min f(v) + eps/2 ||v - v_prev||^2`` converge to an exact minimiser of ``f``
(no bias, unlike a fixed regularisation)."""


EPS_PROX_SEQUENCE = (1e-6, 1e-4, 1e-2, 1.0, -1.0)
"""Proximal weights tried in turn (the hierarchy normalises ``H`` to a largest
entry near 1): a small forced one (accurate on semidefinite least squares),
then larger ones, then DAQP's automatic choice. Small weights leave the
proximal subproblems nearly singular where ``H`` is (the reduced Hessian of an
equality-only level that leaves force directions free), and on real
whole-body stacks (friction-cone, torque and joint-limit rows nearly dependent
after projection, large gradients) DAQP's dual iterations then report
infeasibility within a few dozen iterations; a weight of 1 keeps every
subproblem well conditioned, and the proximal-point iterations still converge
to an exact minimiser, only in more (cheap) outer iterations."""

ATTEMPTS = tuple((SETTINGS["primal_tol"], e) for e in EPS_PROX_SEQUENCE) + tuple(
    (1e-8, e) for e in EPS_PROX_SEQUENCE)
"""``(primal_tol, eps_prox)`` tried in turn: the tight primal tolerance first,
then ``1e-8``. Carried rows of a hierarchy can leave feasible sets only about
``1e-9`` thick (implicit equalities, :data:`hqp.solver.carried.CARRY_MARGIN`),
where DAQP's dual steps with a ``1e-10`` primal tolerance cycle into false
infeasibility; a failed attempt costs a few dozen iterations. The hierarchy
widens its carried bounds to contain the returned point, so a ``1e-8``
violation only moves a bound by that much."""

QUICK_ATTEMPTS = tuple(a for a in ATTEMPTS if a[1] == EPS_PROX_SEQUENCE[0])
"""The attempts of :meth:`DaqpBackend.solve_quick`: the small proximal weight at both primal
tolerances. The larger weights are expensive where they are reached (the failing level QPs
of a pushed robot) and rarely succeed there (``_ext.qp_stats`` counts them): the basis
algorithm's first pass tries these only, and a level they cannot solve sends the solve to
the absorbing second pass (:meth:`hqp.solver.basis.BasisAlgorithm.solve`), which has every
attempt."""

_DAQP_INF = 1e30
"""DAQP's infinite bound."""

_EQUALITY = 5
"""DAQP constraint sense of an equality row (active and immutable)."""


class DaqpBackend(QPBackend):
    """DAQP through its own ``daqp.solve`` with two-sided rows and its proximal outer loop.

    Two-sided rows ``lo <= C v <= up`` go to DAQP as they are (qpsolvers' one-sided
    form doubles them into pairs of opposite rows, which DAQP's dual steps treat
    as nearly dependent constraints); equality rows get DAQP's equality sense.
    """

    name = "daqp"
    needs_pd = True

    def solve(self, slot, H, g, E, e, C, lo, up):  # noqa: D102 - documented in the base
        return self._solve(H, g, E, e, C, lo, up, ATTEMPTS)

    def solve_quick(self, slot, H, g, E, e, C, lo, up):  # noqa: D102 - documented in the base
        return self._solve(H, g, E, e, C, lo, up, QUICK_ATTEMPTS)

    def _solve(self, H, g, E, e, C, lo, up, attempts):
        nv = H.shape[0]
        rows, upper, lower, sense = [], [], [], []
        if E is not None and E.shape[0]:
            rows.append(E)
            upper.append(e)
            lower.append(e)
            sense.append(np.full(E.shape[0], _EQUALITY, dtype=c_int))
        if C is not None and C.shape[0]:
            rows.append(C)
            upper.append(np.minimum(up, _DAQP_INF))
            lower.append(np.maximum(lo, -_DAQP_INF))
            sense.append(np.zeros(C.shape[0], dtype=c_int))
        if rows:
            A = np.ascontiguousarray(np.concatenate(rows))
            bu = np.ascontiguousarray(np.concatenate(upper), dtype=float)
            bl = np.ascontiguousarray(np.concatenate(lower), dtype=float)
            sn = np.ascontiguousarray(np.concatenate(sense), dtype=c_int)
        else:
            A = np.zeros((0, nv))
            bu = bl = np.zeros(0)
            sn = np.zeros(0, dtype=c_int)
        Hc = np.ascontiguousarray(H, dtype=float)
        gc = np.ascontiguousarray(g, dtype=float)
        for primal_tol, eps_prox in attempts:
            x, _fval, exitflag, _info = daqp.solve(
                Hc, gc, A, bu, bl, sn, **{**SETTINGS, "primal_tol": primal_tol},
                eps_prox=eps_prox)
            if exitflag >= 1 and np.isfinite(x).all():
                return np.asarray(x, dtype=float).copy(), True
        return np.full(nv, np.nan), False
