"""Active-set warm start of one level problem, verified by its optimality conditions.

Both lexicographic algorithms solve, at every level, a problem of the form

    min_v  ||A v - b||^2 + ||dist(C v, [lo, up])||^2
    s.t.   E v = e,   gl <= G v <= gu

(the basis algorithm in the reduced coordinates ``v = y`` of the optimal set
above, without ``E``; the cascade over the full ``x`` with the held equality
rows as ``E``). Given a *guess* of its active set, namely

- ``s`` per level row: ``+1`` the row is violated above (its slack cost is
  ``(C_i v - up_i)^2``), ``-1`` violated below, ``0`` inside its band, and
- ``w`` per carried row: ``+1`` held at ``gu``, ``-1`` held at ``gl``, ``0`` free,

the problem becomes an equality-constrained least-squares problem, solved
exactly here by a null-space method (pivoted QR of the active constraint
rows, then least squares in their null space). The point is accepted only if
it satisfies the problem's optimality (KKT) conditions: rows guessed inside
their band are inside it, rows guessed violated are violated on the guessed
side (their slack multiplier is their violation), free carried rows are
within their bounds and held carried rows have multipliers of the right
sign. The problem is convex, so such a point is an exact minimiser.

When the guess fails, the guess is updated as in a primal-dual active-set
method (violated rows enter, rows with wrong-sign multipliers leave, level
rows take the side of their violation) for a few iterations; if none is
accepted, the caller solves the level's QP with its backend. The guess comes
from the previous solve of the same level (Escande, Mansard, Wieber, IJRR
2014, warm start of the hierarchical active set: the QPs of a control loop
change little between 1 ms steps, so the previous active set is usually the
optimal one), or, cold, from the least-squares point.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import nnls

from hqp.solver.linalg import _dgeqp3, _dorgqr, _dtrtrs, lstsq

_NO_ROWS = np.zeros(0, dtype=np.intp)

FEAS_TOL = 1e-9
"""Primal tolerance (times ``max(1, |bound|)``), as in the hierarchy's checks."""

DUAL_TOL = 1e-9
"""Dual tolerance on the multipliers of held carried rows, relative to the
scale of the cost's gradient (``max |M| * max(1, max |d|)`` for the stacked
least-squares rows ``M v ~ d``). Accepting a multiplier of ``-DUAL_TOL`` times
that scale leaves the level's cost at most that much times the distance to
the next bound above its optimum, inside the contract's ``1e-6``."""

MAX_ITER = 6
"""Active-set updates tried after the first guess before the backend QP."""

CONSISTENCY_TOL = 1e-9
"""Held rows that the QR finds dependent must be consistent to this
(times ``max(1, |bound|)``), else the guess is rejected."""


class Guess:
    """An active-set guess: ``s`` over the level rows, ``w`` over the carried rows (int8)."""

    __slots__ = ("s", "w")

    def __init__(self, s: np.ndarray, w: np.ndarray) -> None:
        self.s = s
        self.w = w


@dataclass(slots=True)
class LevelRows:
    """A level's rows in the coordinates ``v`` of its problem (``C v`` against its band).

    Attributes:
        A: Least-squares rows ``(ma, nv)``; ``b``: their targets ``(ma,)``.
        C: Level inequality rows ``(mc, nv)``.
        lo: Their lower bounds ``(mc,)`` (``-inf`` allowed); ``up``: upper bounds (``+inf``).
        los: Tolerance scales ``max(1, |lo|)`` ``(mc,)``; ``ups``: the same of ``up``.

    """

    A: np.ndarray
    b: np.ndarray
    C: np.ndarray
    lo: np.ndarray
    up: np.ndarray
    los: np.ndarray
    ups: np.ndarray


@dataclass(slots=True)
class CarriedRows:
    """Inequality rows carried from the levels above: ``gl <= G v <= gu``.

    Attributes:
        G: ``(p, nv)``; ``gl``, ``gu``: bounds ``(p,)``; ``gls``, ``gus``: their tolerance scales.

    """

    G: np.ndarray
    gl: np.ndarray
    gu: np.ndarray
    gls: np.ndarray
    gus: np.ndarray


def solve_guess(
    level: LevelRows,
    carried: CarriedRows | None,
    guess: Guess,
    rank_tol: float,
    scale: float,
    *,
    E: np.ndarray | None = None,
    e: np.ndarray | None = None,
    max_iter: int = MAX_ITER,
    ref: np.ndarray | None = None,
) -> tuple[np.ndarray | None, Guess, int]:
    """Solve the level problem from an active-set guess; ``None`` if no guess verifies.

    Args:
        level: The level's rows.
        carried: The carried rows, or ``None`` when none is carried.
        guess: Initial guess (``s`` ``(mc,)``, ``w`` ``(p,)``).
        rank_tol: Relative rank threshold of the factorisations.
        scale: Largest entry of the level's unprojected rows (rank decisions).
        E: Hard equality rows ``(me, nv)`` or ``None`` (the cascade's held rows).
        e: Their right-hand side ``(me,)`` or ``None``.
        max_iter: Guess updates tried after the first.
        ref: Reference point ``(nv,)``: where the least-squares rows leave
            directions free, the minimiser closest to it is taken (``None``:
            the minimum-norm one). The previous solve's point keeps rows that
            were inside their bands inside them on semidefinite levels.

    Returns:
        ``(v, guess, iterations)``: the verified minimiser ``(nv,)`` (or ``None``),
        the last guess (the verified one when ``v`` is not ``None``) and the
        number of equality-constrained solves.

    """
    A, b, C, lo, up, los = level.A, level.b, level.C, level.lo, level.up, level.los
    ups = level.ups
    if carried is None:
        G = gl = gu = gls = gus = None
    else:
        G, gl, gu, gls, gus = carried.G, carried.gl, carried.gu, carried.gls, carried.gus
    nv = A.shape[1]
    s = guess.s
    w = guess.w
    p = 0 if G is None else G.shape[0]
    mc = C.shape[0]
    me = 0 if E is None else E.shape[0]
    if mc:
        tl = FEAS_TOL * los
        tu = FEAS_TOL * ups
        lo_in = lo - tl  # band checks with their tolerance
        up_in = up + tu
        lo_out = lo + tl
        up_out = up - tu
    if p:
        gl_in = gl - FEAS_TOL * gls
        gu_in = gu + FEAS_TOL * gus
    # a stale guess (bounds change between control steps) may hold a row at a bound that is
    # now infinite: release those rows rather than solve for a non-finite point
    if mc:
        s = _release_stale(s, lo, up)
    if p:
        w = _release_stale(w, gl, gu)
    es = np.maximum(1.0, np.abs(e)) if me else None
    seen: set[bytes] = set()
    for it in range(max_iter + 1):
        key = s.tobytes() + w.tobytes()
        if key in seen:
            break  # cycling
        seen.add(key)
        # stacked least-squares rows M v ~ d and held rows K v = k
        M, d = _stack(A, b, C, lo, up, s) if mc and s.any() else (A, b)
        held = np.flatnonzero(w) if p else _NO_ROWS
        nheld = held.size
        rk = 0
        dep_g = _NO_ROWS
        if me or nheld:
            if nheld:
                wp = w[held] > 0
                Gh = G[held]
                kh = np.where(wp, gu[held], gl[held])
                khs = np.where(wp, gus[held], gls[held])
                if me:
                    K = np.concatenate((E, Gh))
                    k = np.concatenate((e, kh))
                    ks = np.concatenate((es, khs))
                else:
                    K, k, ks = Gh, kh, khs
            else:
                K, k, ks = E, e, es
            piv, rk, Q, R11, vp = _factor_held(K, k, nv, rank_tol)
            Q1 = Q[:, :rk]
            if rk < K.shape[0]:
                # dependent held rows get no multiplier: equality rows must be
                # consistent, carried rows only within their bounds (checked below)
                dep = piv[rk:]
                dep_e = dep[dep < me]
                if dep_e.size and (np.abs(K[dep_e] @ vp - k[dep_e])
                                   > CONSISTENCY_TOL * ks[dep_e]).any():
                    return None, Guess(s, w), it + 1
                dep_g = held[dep[dep >= me] - me]
            v = _in_null_space(M, d, vp, Q[:, rk:], rk, nv, ref, rank_tol, scale)
        else:
            v = _free_least_squares(M, d, nv, ref, rank_tol, scale)
        if not np.isfinite(v).all():
            break
        # primal checks and the next guess
        ok = True
        s_new = s
        if mc:
            ok, s_new = _check_level_rows(C @ v, s, lo_in, up_in, lo_out, up_out)
        w_new = w
        if p:
            wrong = None
            gv = G @ v
            if rk and nheld:
                wrong = _wrong_multipliers(M, d, v, K, me, piv, rk, R11, Q1, wp, held,
                                           _inside(gv, held, dep_g, wp, gl, gu, gls, gus))
            ok_w, w_new = _check_carried_rows(gv, w, gl_in, gu_in, dep_g, wrong)
            ok = ok and ok_w
        if ok:
            return v, Guess(s, w), it + 1
        s = s_new
        w = w_new
    return None, Guess(s, w), len(seen)


def _stack(A: np.ndarray, b: np.ndarray, C: np.ndarray, lo: np.ndarray, up: np.ndarray,
           s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Return ``(M, d)``: the rows ``A`` and the level rows guessed violated, at their bounds."""
    sel = np.flatnonzero(s)
    M = np.concatenate((A, C[sel]))
    d = np.concatenate((b, np.where(s[sel] > 0, up[sel], lo[sel])))
    return M, d


def _factor_held(K: np.ndarray, k: np.ndarray, nv: int, rank_tol: float
                 ) -> tuple[np.ndarray, int, np.ndarray, np.ndarray, np.ndarray]:
    """Factorise the held rows ``K v = k`` by a pivoted QR of ``K^T``.

    Returns:
        ``(piv, rk, Q, R11, vp)``: the pivot order, the rank, the full orthogonal factor
        ``(nv, nv)`` (its first ``rk`` columns span the rows), the triangular block
        ``(rk, rk)`` and the minimum-norm solution ``vp`` of the independent rows.

    """
    qr, jpvt, tau, _work, _info = _dgeqp3(K.T.copy(order="F"))
    piv = jpvt - 1
    diag = np.abs(np.diagonal(qr))
    rk = 0
    if diag.size:
        rk = int(np.count_nonzero(diag > rank_tol * float(diag[0])))
    nk = K.shape[0]
    if rk < nv:
        a = np.zeros((nv, nv), order="F")
        a[:, :nk] = qr[:, :nv] if nk > nv else qr
        t = np.zeros(nv)
        t[: tau.size] = tau
        Q = _dorgqr(a, t)[0]
    else:
        Q = _dorgqr(np.array(qr[:, :nv], order="F"), tau[:nv])[0]
    R11 = qr[:rk, :rk]
    if rk:
        vp = Q[:, :rk] @ _dtrtrs(R11, k[piv[:rk]], lower=0, trans=1)[0]
    else:
        vp = np.zeros(nv)
    return piv, rk, Q, R11, vp


def _in_null_space(M: np.ndarray, d: np.ndarray, vp: np.ndarray, Q2: np.ndarray, rk: int,
                   nv: int, ref: np.ndarray | None, rank_tol: float, scale: float) -> np.ndarray:
    """Return ``vp + Q2 z`` minimising ``||M v - d||`` (closest to ``ref`` where ties)."""
    if M.shape[0] and rk < nv:
        MQ = M @ Q2
        rhs = d - M @ vp
        if ref is None:
            return vp + Q2 @ lstsq(MQ, rhs, rank_tol, scale)
        zr = Q2.T @ ref
        return vp + Q2 @ (zr + lstsq(MQ, rhs - MQ @ zr, rank_tol, scale))
    if rk < nv and ref is not None:
        return vp + Q2 @ (Q2.T @ ref)
    return vp


def _free_least_squares(M: np.ndarray, d: np.ndarray, nv: int, ref: np.ndarray | None,
                        rank_tol: float, scale: float) -> np.ndarray:
    """Return the minimiser of ``||M v - d||`` with nothing held (closest to ``ref``)."""
    if M.shape[0]:
        if ref is None:
            return lstsq(M, d, rank_tol, scale)
        return ref + lstsq(M, d - M @ ref, rank_tol, scale)
    return np.zeros(nv) if ref is None else ref.copy()


def _inside(gv: np.ndarray, held: np.ndarray, dep_g: np.ndarray, wp: np.ndarray,
            gl: np.ndarray, gu: np.ndarray, gls: np.ndarray, gus: np.ndarray) -> np.ndarray:
    """Return a mask over ``held``: the dependent held rows that lie inside their band.

    A held row the QR found dependent on the others is not solved for; where its value at
    the point is further than :data:`AT_BOUND_TOL` (times its scale) from the bound it is
    held at, it is inactive there and takes no multiplier.
    """
    inside = np.zeros(held.size, dtype=bool)
    if dep_g.size:
        dep = np.isin(held, dep_g)
        k = np.where(wp, gu[held], gl[held])
        ks = np.where(wp, gus[held], gls[held])
        inside = dep & (np.abs(gv[held] - k) > AT_BOUND_TOL * ks)
    return inside


def _wrong_multipliers(M: np.ndarray, d: np.ndarray, v: np.ndarray, K: np.ndarray, me: int,
                       piv: np.ndarray, rk: int, R11: np.ndarray, Q1: np.ndarray,
                       wp: np.ndarray, held: np.ndarray, inside: np.ndarray
                       ) -> np.ndarray | None:
    """Return the held carried rows to release (``None``: the multipliers have right signs).

    The multipliers of the independent held rows solve ``K^T mu = -grad`` with ``grad``
    the cost's gradient at ``v``; where they are not unique (dependent held rows),
    any set of the right signs over the rows *at their bound* will do
    (:func:`_signed_multipliers`). A dependent held row inside its band (``inside``) is
    inactive at ``v`` and takes none; when no such set exists, it is released together
    with the rows of wrong-sign multipliers.
    """
    grad = M.T @ (M @ v - d)
    mu = np.zeros(K.shape[0])
    mu[piv[:rk]] = _dtrtrs(R11, -(Q1.T @ grad), lower=0)[0]
    mug = mu[me:]
    dtol = DUAL_TOL * _dual_scale(M, d)
    bad_mu = np.where(wp, mug < -dtol, mug > dtol)
    if not bad_mu.any():
        return None
    if rk < K.shape[0]:
        at = np.concatenate((np.ones(me, dtype=bool), ~inside))
        if _signed_multipliers(K[at], me, wp[~inside], grad, dtol):
            return None
    return held[bad_mu | inside]


def _dual_scale(M: np.ndarray, d: np.ndarray) -> float:
    """Return ``max(1, max|M| max(1, max|d|))``, the scale :data:`DUAL_TOL` is relative to."""
    return max(1.0, float(np.abs(M).max()) * max(1.0, float(np.abs(d).max()))) if M.size \
        else 1.0


def _check_carried_rows(gv: np.ndarray, w: np.ndarray, gl_in: np.ndarray, gu_in: np.ndarray,
                        dep_g: np.ndarray, wrong: np.ndarray | None) -> tuple[bool, np.ndarray]:
    """Check the carried rows against the guess ``w``; return whether all pass and the next ``w``.

    Free rows (and held rows the QR found dependent) must be within their bounds (with
    their tolerance, ``gl_in``, ``gu_in``); violated ones are held at the bound they cross.
    Rows ``wrong`` (held with a wrong-sign multiplier) are released.
    """
    over = gv > gu_in
    under = gv < gl_in
    free = w == 0
    if dep_g.size:
        free[dep_g] = True
    viol = (over | under) & free
    if wrong is None and not viol.any():
        return True, w
    w_new = np.where(viol, over.astype(np.int8) - under.astype(np.int8), w).astype(np.int8)
    if wrong is not None:
        w_new[wrong] = 0
    return False, w_new


def _release_stale(side: np.ndarray, lo: np.ndarray, up: np.ndarray) -> np.ndarray:
    """Return ``side`` (``s`` or ``w``) with the rows held at an infinite bound set to 0."""
    if side.any():
        stale = ((side > 0) & ~np.isfinite(up)) | ((side < 0) & ~np.isfinite(lo))
        if stale.any():
            side = side.copy()
            side[stale] = 0
    return side


def _check_level_rows(cv: np.ndarray, s: np.ndarray, lo_in: np.ndarray, up_in: np.ndarray,
                      lo_out: np.ndarray, up_out: np.ndarray) -> tuple[bool, np.ndarray]:
    """Check the level rows against the guess ``s``; return whether all pass and the next ``s``.

    A row guessed inside its band must be within it (``lo_in <= cv <= up_in``, the bounds
    with their tolerance); a row guessed violated must be beyond its bound on that side
    (``cv > up_out`` or ``cv < lo_out``). Only the rows that fail change state, to the side
    they violate (0 inside).
    """
    out_up = cv > up_in
    out_lo = cv < lo_in
    bad = np.where(s == 0, out_up | out_lo, np.where(s > 0, cv < up_out, cv > lo_out))
    if not bad.any():
        return True, s
    return False, np.where(bad, out_up.astype(np.int8) - out_lo.astype(np.int8),
                           s).astype(np.int8)


def _signed_multipliers(
    K: np.ndarray, me: int, wp: np.ndarray, grad: np.ndarray, dtol: float
) -> bool:
    """Whether multipliers of the right signs exist for dependent held rows.

    With dependent held rows (a degenerate vertex: more rows held than the
    rank) the multipliers are not unique, and the triangular solve picks one
    set; the KKT conditions only need *some* set with the right signs:
    ``K^T mu = -grad`` with ``mu`` free on the ``me`` equality rows, ``>= 0`` on
    rows held at their upper bound and ``<= 0`` at their lower bound. Found by
    non-negative least squares on the sign-adjusted rows.
    """
    sign = np.where(wp, 1.0, -1.0)
    cols = [K[me:].T * sign]
    if me:
        cols = [K[:me].T, -K[:me].T] + cols
    _mu, res = nnls(np.concatenate(cols, axis=1), -grad, maxiter=50 * K.shape[0])
    return bool(res <= dtol * max(1.0, np.sqrt(grad.size)))


AT_BOUND_TOL = 1e-7
"""A held carried row within this (times its scale) of its bound takes a multiplier in
:func:`held_multipliers`; a held row the QR found dependent may lie inside its band, further
away: it is inactive (the polish's tolerance of an active row,
:data:`hqp.solver.warm.ACTIVE_TOL`)."""

ABSORB_TOL = 1e-6
"""A held carried row whose multiplier exceeds this (relative to the dual scale of
:data:`DUAL_TOL`) is active over the level's whole optimal set, and the basis algorithm
makes it an equality (:func:`held_multipliers`)."""


def held_multipliers(level: LevelRows, carried: CarriedRows, guess: Guess,
                     v: np.ndarray) -> np.ndarray | None:
    """Return the multipliers of the held carried rows at a verified point (``None``: unknown).

    At a minimiser ``v`` of the level problem with the active set ``guess``, the multipliers
    of the held rows at their bound (a held row dependent on the others may lie inside its
    band) solve ``sum_j mu_j sigma_j G_j = -grad`` with ``mu >= 0`` (``sigma_j`` the
    side ``w_j`` each row is held at, ``grad`` the cost's gradient): one dual solution,
    found by non-negative least squares (a vertex of the dual set where the held rows are
    dependent). By the saddle-point theorem, every minimiser of the level has every row of
    a positive multiplier at its bound: those rows are equalities over the level's optimal
    set. Rows not held get 0.

    Returns:
        ``mu`` ``(p,)`` divided by the dual scale ``max(1, max|M| max(1, max|d|))`` of the
        level's stacked rows ``M v ~ d`` (the scale :data:`DUAL_TOL` is relative to; the
        caller compares it with :data:`ABSORB_TOL`), or ``None`` where the NNLS residual
        exceeds :data:`DUAL_TOL` (the point is no minimiser to that tolerance: nothing is
        absorbed).

    """
    w = guess.w
    held = np.flatnonzero(w)
    p = carried.G.shape[0]
    if held.size:
        # a held row dependent on the others is only kept within its bounds (no multiplier,
        # solve_guess): only the rows at their bound enter the dual system
        up = w[held] > 0
        gap = np.abs(carried.G[held] @ v - np.where(up, carried.gu[held], carried.gl[held]))
        held = held[gap <= AT_BOUND_TOL * np.where(up, carried.gus[held], carried.gls[held])]
    if held.size == 0:
        return np.zeros(p)
    A, b, C = level.A, level.b, level.C
    M, d = _stack(A, b, C, level.lo, level.up, guess.s) if C.shape[0] and guess.s.any() \
        else (A, b)
    grad = M.T @ (M @ v - d)
    scale = _dual_scale(M, d)
    sign = np.where(w[held] > 0, 1.0, -1.0)
    mu_h, res = nnls(carried.G[held].T * sign, -grad, maxiter=50 * held.size)
    if res > DUAL_TOL * scale * max(1.0, np.sqrt(grad.size)):
        return None
    mu = np.zeros(p)
    mu[held] = mu_h / scale
    return mu


def guess_from_point(
    cv: np.ndarray | None,
    level: LevelRows,
    gv: np.ndarray | None,
    carried: CarriedRows | None,
    active_tol: float,
) -> Guess:
    """Return the active set of a point (level rows by the side they violate, carried rows held).

    Args:
        cv: ``C v`` ``(mc,)`` (``None`` without level rows).
        level: The level's rows (their bounds and tolerance scales are read).
        gv: ``G v`` ``(p,)`` (``None`` without carried rows).
        carried: The carried rows (bounds and scales read when ``gv`` is given).
        active_tol: A carried row within ``active_tol * scale`` of a bound is held.

    """
    lo, up, los, ups = level.lo, level.up, level.los, level.ups
    if cv is None or cv.size == 0:
        s = np.zeros(0, dtype=np.int8)
    else:
        # rows on a bound (within the tolerance) or beyond it: least-squares rows
        s = (cv >= up - active_tol * ups).astype(np.int8) - (
            cv <= lo + active_tol * los).astype(np.int8)
        both = (s == 0) & (cv >= up - active_tol * ups)
        if both.any():
            s[both] = np.where(cv[both] >= 0.5 * (lo[both] + up[both]), 1, -1)
    if gv is None or gv.size == 0 or carried is None:
        w = np.zeros(0, dtype=np.int8)
    else:
        gl, gu, gls, gus = carried.gl, carried.gu, carried.gls, carried.gus
        near_up = gv >= gu - active_tol * gus
        near_lo = gv <= gl + active_tol * gls
        w = near_up.astype(np.int8) - near_lo.astype(np.int8)
        both = near_up & near_lo
        if both.any():
            # a slab thinner than the tolerance: held at the nearer bound
            w[both] = np.where(gv[both] >= 0.5 * (gl[both] + gu[both]), 1, -1)
    return Guess(s, w)
