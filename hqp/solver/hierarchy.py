"""The strict lexicographic solver: basis algorithm and plain cascade.

Both algorithms return the contract's solution (ARCHITECTURE.md, "Contract:
the solver"): level ``k`` minimises

    ||A_k x - b_k||^2 + ||dist(C_k x, [lower_k, upper_k])||^2

over the optimal set of levels ``0..k-1``; after the last level the solver
minimises ``(x - t)^T M (x - t)`` and then ``||x||^2`` over the final optimal
set. These two final steps are run as two extra internal levels with
``A = M^{1/2}``, ``b = M^{1/2} t`` and ``A = I``, ``b = 0``.

**Basis algorithm** (Escande, Mansard, Wieber, IJRR 2014; Kanoun et al. 2011).
The optimal set of the levels solved so far is kept as
``{x0 + Z y : gl <= G (x0 + Z y) <= gu}`` with ``Z`` ``(n, r)`` orthonormal.
For level ``k`` with ``A_k Z``, ``C_k Z``:

1. Least squares: ``y = (A_k Z)^+ (b_k - A_k x0)`` by SVD (rank decided by
   ``rank_tol`` times the level's scale).
2. If ``x0 + Z y`` satisfies the level's and the carried inequalities, the
   level is solved: no QP.
3. Otherwise a QP in the reduced coordinates and one slack per inequality row,

       min_{y, w} ||A_k Z y - (b_k - A_k x0)||^2 + ||w||^2
       s.t.       lower_k - C_k x0 <= C_k Z y - w <= upper_k - C_k x0,
                  gl - G x0 <= G Z y <= gu - G x0,

   which is exact: for fixed ``y`` the best ``w`` is the distance of
   ``C_k x`` to its interval, so the optimal cost is the level's cost.
4. The cost is strictly convex in ``(A_k x, w)``, so the equality residual and
   every row's violation are the same at every optimum. The equality rows and
   the violated rows become equalities: ``Z`` shrinks to ``Z N`` with ``N`` the
   null space of ``[A_k Z; C_k[violated] Z]`` and ``x0`` moves to the optimum.
   Satisfied inequality rows are carried as inequalities, their bounds widened
   to contain the optimum (which only absorbs the QP tolerance).

**Cascade** (the baseline): each level is one QP over the full ``x`` and the
level's slacks, earlier levels held as constraints: equality rows at their
values at the current point (which lies in their optimal set, so redundant
rows stay consistent under the QP tolerance) and inequality rows with bounds
widened to contain their optimal violation (``C x - w* in [l, u]``). Backends
that need linearly independent equalities (active-set solvers) receive only
the independent rows.
Same backend, same persistent per-level QPs and warm starts.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Sequence
from typing import Any

import numpy as np

from hqp.errors import InvalidInput, InvalidLevel, SolverFailure, UnknownName, check_array
from hqp.solver.backend import QPBackend, make_backend
from hqp.solver.level import CheckedLevel, Level, check_level
from hqp.solver.solution import ROW_TOL, SATISFIED_COST, LevelReport, Solution

logger = logging.getLogger(__name__)

ALGORITHMS = ("basis", "cascade")
"""Names of the lexicographic algorithms."""

FEAS_TOL = 1e-9
"""Feasibility tolerance (times ``max(1, |bound|)``) when checking whether a
least-squares point satisfies inequalities, and when deciding that a row is
violated after a QP (and becomes an equality)."""



class _Internal:
    """Marker of the internal final levels (metric, minimum norm)."""

    NONE = 0
    METRIC = 1
    NORM = 2


def _check_rank_tol(rank_tol: float) -> float:
    try:
        tol = float(rank_tol)
    except (TypeError, ValueError):
        raise InvalidInput(f"rank_tol: expected a float, got {rank_tol!r}") from None
    if not np.isfinite(tol) or tol <= 0.0 or tol >= 1.0:
        raise InvalidInput(f"rank_tol: expected 0 < rank_tol < 1, got {rank_tol!r}")
    return tol


def _check_levels(levels: Sequence[Level], n_hint: int | None) -> tuple[list[CheckedLevel], int]:
    if isinstance(levels, Level):
        raise InvalidLevel("levels: expected a sequence of Level, got a single Level")
    try:
        levels = list(levels)
    except TypeError:
        raise InvalidLevel(
            f"levels: expected a sequence of Level, got {type(levels).__name__}"
        ) from None
    n = n_hint
    checked: list[CheckedLevel] = []
    for k, level in enumerate(levels):
        lv = check_level(level, k, n)
        if lv.A.shape[1] or lv.C.shape[1] or lv.m_eq or lv.m_in:
            n = lv.A.shape[1]
        checked.append(lv)
    if n is None:
        raise InvalidLevel(
            "levels: cannot infer the number of variables n (no level holds A or C, "
            "and no final_metric or final_target was given)"
        )
    # Resize the empty levels seen before n was known.
    for k, lv in enumerate(checked):
        if lv.A.shape[1] != n and lv.m_eq == 0 and lv.m_in == 0:
            checked[k] = CheckedLevel(
                np.zeros((0, n)), lv.b, np.zeros((0, n)), lv.lower, lv.upper, lv.name
            )
    return checked, n


def _metric_sqrt(M: np.ndarray) -> np.ndarray:
    """Return ``R`` with ``R^T R = M`` for a symmetric PSD ``M`` (zero-weight rows dropped)."""
    try:
        return np.linalg.cholesky(M).T
    except np.linalg.LinAlgError:
        pass
    d, V = np.linalg.eigh(M)
    keep = d > 1e-14 * max(1.0, float(d[-1]))
    return np.sqrt(d[keep])[:, None] * V[:, keep].T


def _final_levels(
    n: int, final_metric: Any, final_target: Any
) -> list[tuple[CheckedLevel, int]]:
    """Build the internal levels of the final metric and the minimum norm."""
    target = None
    if final_target is not None:
        target = check_array(final_target, (n,), "final_target")
    eye = np.eye(n)
    empty = np.zeros((0, n))
    none = np.zeros(0)
    out: list[tuple[CheckedLevel, int]] = []
    if final_metric is None:
        if target is not None:
            out.append((CheckedLevel(eye, target, empty, none, none, "final"), _Internal.NORM))
    else:
        M = check_array(final_metric, (n, n), "final_metric")
        scale = max(1.0, float(np.abs(M).max()))
        if np.abs(M - M.T).max() > 1e-9 * scale:
            raise InvalidInput("final_metric: not symmetric")
        if n and np.linalg.eigvalsh(M)[0] < -1e-9 * scale:
            raise InvalidInput("final_metric: not positive semidefinite")
        R = _metric_sqrt(0.5 * (M + M.T))
        t = np.zeros(n) if target is None else target
        out.append((CheckedLevel(R, R @ t, empty, none, none, "final"), _Internal.METRIC))
    out.append((CheckedLevel(eye, np.zeros(n), empty, none, none, "norm"), _Internal.NORM))
    return out


def _dist(cx: np.ndarray, lo: np.ndarray, up: np.ndarray) -> np.ndarray:
    """Signed distance of ``cx`` outside ``[lo, up]`` (0 inside)."""
    return np.where(cx > up, cx - up, np.where(cx < lo, cx - lo, 0.0))


def _bound_tol(lo: np.ndarray, up: np.ndarray, rel: float) -> tuple[np.ndarray, np.ndarray]:
    """Per-row tolerances ``rel * max(1, |bound|)`` (finite where the bound is infinite)."""
    tl = rel * np.maximum(1.0, np.abs(np.where(np.isfinite(lo), lo, 0.0)))
    tu = rel * np.maximum(1.0, np.abs(np.where(np.isfinite(up), up, 0.0)))
    return tl, tu


def _within(cx: np.ndarray, lo: np.ndarray, up: np.ndarray) -> bool:
    tl, tu = _bound_tol(lo, up, FEAS_TOL)
    return bool(np.all(cx >= lo - tl) and np.all(cx <= up + tu))


def _mth_singular(s: np.ndarray, m: int, r: int, thr: float) -> float:
    """Return the ``m``-th singular value of an ``(m, r)`` matrix with singular values ``s``."""
    if m == 0:
        return float("inf")
    if m > r or m > s.size:
        return 0.0
    v = float(s[m - 1])
    return v if v > thr else 0.0


class HierarchicalSolver:
    """A persistent lexicographic solver (keep one per control loop).

    The backend keeps one persistent QP per level (``proxsuite``: updated and
    warm started while its dimensions hold), so repeated solves of hierarchies
    of the same shapes reuse their factorisations and active sets.

    Args:
        backend: QP backend name (see :func:`hqp.solver.available_backends`).
        algorithm: ``"basis"`` (default) or ``"cascade"`` (the baseline).
        rank_tol: Relative rank threshold for the null-space bases, ``0 < rank_tol < 1``.
        compute_sigma: Compute ``sigma_min`` in the cascade's reports (the basis
            algorithm gets it from its own factorisations at no cost).

    Raises:
        UnknownBackend: Unknown or uninstalled backend.
        UnknownName: Unknown algorithm.
        InvalidInput: ``rank_tol`` out of range.

    """

    def __init__(
        self,
        backend: str = "proxsuite",
        algorithm: str = "basis",
        rank_tol: float = 1e-9,
        compute_sigma: bool = True,
    ) -> None:
        if algorithm not in ALGORITHMS:
            raise UnknownName("algorithm", str(algorithm), ALGORITHMS)
        self.rank_tol = _check_rank_tol(rank_tol)
        self.backend_name = backend
        self.algorithm = algorithm
        self.compute_sigma = compute_sigma
        self._backend: QPBackend = make_backend(backend)

    def reset(self) -> None:
        """Forget the persistent QPs (the next solve starts cold)."""
        self._backend.reset()

    def solve(
        self,
        levels: Sequence[Level],
        final_metric: Any = None,
        final_target: Any = None,
    ) -> Solution:
        """Solve the hierarchy.

        Args:
            levels: Levels, highest priority first.
            final_metric: Symmetric positive semidefinite ``(n, n)`` or ``None`` (identity).
            final_target: ``(n,)`` or ``None`` (zero).

        Returns:
            The lexicographic optimum with one report per level.

        Raises:
            InvalidLevel: A malformed level (the message names the level and the field).
            InvalidInput: A malformed final metric or target.
            SolverFailure: A backend returned NaN or inf on a well-formed problem.

        """
        t_start = time.perf_counter()
        n_hint = None
        for value in (final_target, final_metric):
            if value is not None:
                shape = np.shape(value)
                n_hint = int(shape[0]) if len(shape) else None
        checked, n = _check_levels(levels, n_hint)
        internal = _final_levels(n, final_metric, final_target)
        all_levels = [(lv, _Internal.NONE) for lv in checked] + internal
        if self.algorithm == "basis":
            x, sigmas, qp_count, times = self._solve_basis(all_levels, n)
        else:
            x, qp_count, times = self._solve_cascade(all_levels, n)
            sigmas = None
        if not np.all(np.isfinite(x)):
            raise SolverFailure(
                f"backend {self.backend_name!r} returned a non-finite solution "
                f"({self.algorithm} algorithm)"
            )
        if sigmas is None and self.compute_sigma:
            sigmas = _sigma_recursion(checked, x, self.rank_tol)
        reports = tuple(
            _report(lv, x, np.nan if sigmas is None else sigmas[k])
            for k, lv in enumerate(checked)
        )
        L = len(checked)
        timings = {f"level_{k}": times[k] for k in range(L)}
        timings["final"] = float(sum(times[L:]))
        timings["total"] = time.perf_counter() - t_start
        return Solution(
            x=x,
            levels=reports,
            timings=timings,
            backend=self.backend_name,
            algorithm=self.algorithm,
            qp_count=qp_count,
        )

    # ------------------------------------------------------------------ basis
    def _solve_basis(
        self, all_levels: list[tuple[CheckedLevel, int]], n: int
    ) -> tuple[np.ndarray, list[float], int, list[float]]:
        rank_tol = self.rank_tol
        backend = self._backend
        x = np.zeros(n)
        Z: np.ndarray | None = None  # None: identity
        r = n
        G = np.zeros((0, n))
        gl = np.zeros(0)
        gu = np.zeros(0)
        sigmas: list[float] = []
        pending: list[tuple[CheckedLevel, Any, Any, Any]] = []
        times: list[float] = []
        qp_count = 0
        for k, (lv, kind) in enumerate(all_levels):
            t0 = time.perf_counter()
            A, b, C = lv.A, lv.b, lv.C
            me, mi = A.shape[0], C.shape[0]
            if r == 0 or me + mi == 0:
                if kind == _Internal.NONE:
                    pending.append((lv, None, None, None))
                times.append(time.perf_counter() - t0)
                continue
            Zb = Z
            carried = G.shape[0] > 0
            Ak = A if Z is None else A @ Z
            bk = b - A @ x
            # 1. least squares on the equality rows
            svd_a = None
            if kind == _Internal.NORM:
                # A = I and Z orthonormal: (I Z)^+ = Z^T, nothing left free afterwards.
                y = bk if Z is None else Z.T @ bk
                nullA = np.zeros((0, r))
                rank_a = r
            elif me:
                U, s, Vt = np.linalg.svd(Ak, full_matrices=True)
                scale = max(float(s[0]) if s.size else 0.0, float(np.abs(A).max()))
                thr = rank_tol * scale
                rank_a = int(np.count_nonzero(s > thr))
                y = Vt[:rank_a].T @ ((U[:, :rank_a].T @ bk) / s[:rank_a])
                nullA = Vt[rank_a:]
                svd_a = (s, thr)
            else:
                y = np.zeros(r)
                nullA = None
                rank_a = 0
            xl = x + (y if Z is None else Z @ y)
            # 2. does the least-squares point satisfy the inequalities?
            feasible = True
            if mi:
                cx = C @ xl
                feasible = _within(cx, lv.lower, lv.upper)
            if feasible and carried:
                feasible = _within(G @ xl, gl, gu)
            violated = None
            if not feasible:
                # 3. QP in the reduced coordinates (and the level's slacks)
                qp_count += 1
                Gk = G if Z is None else G @ Z
                gx = G @ x
                H11 = Ak.T @ Ak
                g1 = -(Ak.T @ bk)
                if mi == 0:
                    v, ok = backend.solve(k, H11, g1, None, None,
                                          Gk if carried else None,
                                          gl - gx if carried else None,
                                          gu - gx if carried else None)
                    y = v
                else:
                    Ck = C if Z is None else C @ Z
                    cx0 = C @ x
                    nv = r + mi
                    H = np.zeros((nv, nv))
                    H[:r, :r] = H11
                    H[np.arange(r, nv), np.arange(r, nv)] = 1.0
                    g = np.zeros(nv)
                    g[:r] = g1
                    p = G.shape[0]
                    Cq = np.zeros((mi + p, nv))
                    Cq[:mi, :r] = Ck
                    Cq[np.arange(mi), np.arange(r, nv)] = -1.0
                    Cq[mi:, :r] = Gk
                    lo = np.concatenate([lv.lower - cx0, gl - gx])
                    up = np.concatenate([lv.upper - cx0, gu - gx])
                    v, ok = backend.solve(k, H, g, None, None, Cq, lo, up)
                    y = v[:r]
                if not ok:
                    logger.debug("level %d: backend %s did not converge", k, backend.name)
                if not np.all(np.isfinite(y)):
                    raise SolverFailure(
                        f"level {k}: backend {backend.name!r} returned a non-finite solution"
                    )
                xl = x + (y if Z is None else Z @ y)
                if mi:
                    cx = C @ xl
                    d = _dist(cx, lv.lower, lv.upper)
                    tl, tu = _bound_tol(lv.lower, lv.upper, FEAS_TOL)
                    violated = (d > tu) | (d < -tl)
                    if not violated.any():
                        violated = None
            # 4. shrink the basis: equality rows and violated rows are fixed
            if violated is not None:
                Ck = C if Z is None else C @ Z
                E = np.concatenate([Ak, Ck[violated]]) if me else Ck[violated]
                U2, s2, Vt2 = np.linalg.svd(E, full_matrices=True)
                scale = max(float(s2[0]) if s2.size else 0.0,
                            float(np.abs(A).max()) if me else 0.0,
                            float(np.abs(C[violated]).max()))
                thr2 = rank_tol * scale
                rank_e = int(np.count_nonzero(s2 > thr2))
                null = Vt2[rank_e:]
            else:
                null = nullA
            x = xl
            if null is not None:
                Z = null.T if Z is None else Z @ null.T
                r = Z.shape[1]
            # carried inequality rows: widen to contain x (absorbs the QP tolerance)
            if carried:
                gx = G @ x
                np.minimum(gl, gx, out=gl)
                np.maximum(gu, gx, out=gu)
            if mi:
                keep = np.ones(mi, dtype=bool) if violated is None else ~violated
                keep &= np.isfinite(lv.lower) | np.isfinite(lv.upper)
                if keep.any():
                    ck = cx[keep]
                    G = np.concatenate([G, C[keep]])
                    gl = np.concatenate([gl, np.minimum(lv.lower[keep], ck)])
                    gu = np.concatenate([gu, np.maximum(lv.upper[keep], ck)])
            if kind == _Internal.NONE:
                pending.append((lv, Ak, Zb, svd_a))
            times.append(time.perf_counter() - t0)
        # sigma_min at the solution (its active rows), from the projections above
        for lv, Ak, Zb, svd_a in pending:
            if Ak is None:
                m = lv.m_eq + (int(np.count_nonzero(_active_rows(lv, lv.C @ x))) if lv.m_in else 0)
                sigmas.append(0.0 if m else float("inf"))
            else:
                sigmas.append(_sigma_level(lv, Ak, Zb, x, svd_a, rank_tol))
        return x, sigmas, qp_count, times

    # ---------------------------------------------------------------- cascade
    def _solve_cascade(
        self, all_levels: list[tuple[CheckedLevel, int]], n: int
    ) -> tuple[np.ndarray, int, list[float]]:
        backend = self._backend
        independent = getattr(backend, "needs_independent_eq", False)
        x = np.zeros(n)
        E = np.zeros((0, n))  # held equality rows of earlier levels
        G = np.zeros((0, n))  # held inequality rows of earlier levels
        gl = np.zeros(0)
        gu = np.zeros(0)
        times: list[float] = []
        qp_count = 0
        for k, (lv, _kind) in enumerate(all_levels):
            t0 = time.perf_counter()
            A, b, C = lv.A, lv.b, lv.C
            me, mi = A.shape[0], C.shape[0]
            if me + mi == 0:
                times.append(time.perf_counter() - t0)
                continue
            p = G.shape[0]
            q = E.shape[0]
            nv = n + mi
            H = np.zeros((nv, nv))
            H[:n, :n] = A.T @ A
            H[np.arange(n, nv), np.arange(n, nv)] = 1.0
            g = np.zeros(nv)
            g[:n] = -(A.T @ b)
            Eq = np.zeros((q, nv))
            Eq[:, :n] = E
            Cq = np.zeros((p + mi, nv))
            Cq[:p, :n] = G
            Cq[p:, :n] = C
            Cq[np.arange(p, p + mi), np.arange(n, nv)] = -1.0
            lo = np.concatenate([gl, lv.lower])
            up = np.concatenate([gu, lv.upper])
            # Earlier equality rows are held at their values at the current point,
            # which lies in their optimal set: redundant rows stay consistent.
            v, ok = backend.solve(("cascade", k), H, g,
                                  Eq if q else None, E @ x if q else None,
                                  Cq if p + mi else None, lo, up)
            qp_count += 1
            if not ok:
                logger.debug("level %d: backend %s did not converge", k, backend.name)
            if not np.all(np.isfinite(v)):
                raise SolverFailure(
                    f"level {k}: backend {backend.name!r} returned a non-finite solution"
                )
            x = v[:n].copy()
            if p:
                gx = G @ x
                np.minimum(gl, gx, out=gl)
                np.maximum(gu, gx, out=gu)
            if me:
                E = _append_independent(E, A, self.rank_tol) if independent else (
                    np.concatenate([E, A]))
            if mi:
                keep = np.isfinite(lv.lower) | np.isfinite(lv.upper)
                cx = C[keep] @ x
                G = np.concatenate([G, C[keep]])
                gl = np.concatenate([gl, np.minimum(lv.lower[keep], cx)])
                gu = np.concatenate([gu, np.maximum(lv.upper[keep], cx)])
            times.append(time.perf_counter() - t0)
        return x, qp_count, times


def solve(
    levels: Sequence[Level],
    backend: str = "proxsuite",
    final_metric: Any = None,
    final_target: Any = None,
    rank_tol: float = 1e-9,
    algorithm: str = "basis",
) -> Solution:
    """Solve a strict lexicographic hierarchy (ARCHITECTURE.md, "Contract: the solver").

    Level ``k`` minimises ``||A_k x - b_k||^2 + ||dist(C_k x, [lower_k, upper_k])||^2``
    over the minimisers of levels ``0..k-1``; then ``(x - final_target)^T
    final_metric (x - final_target)`` over the final optimal set, ties broken
    by minimum norm. With the defaults the result is the minimum-norm
    lexicographic optimum. An unsatisfied level is reported, not raised.

    Args:
        levels: Levels, highest priority (0) first.
        backend: QP backend: ``"proxsuite"`` (default), ``"osqp"``, ``"daqp"``, ``"quadprog"``.
        final_metric: Symmetric positive semidefinite ``(n, n)``; ``None`` = identity.
        final_target: ``(n,)``; ``None`` = zero.
        rank_tol: Rank threshold relative to the largest singular value of a
            projected level matrix (or the level's largest entry, if larger).
        algorithm: ``"basis"`` (null-space basis of the optimal set, default) or
            ``"cascade"`` (one QP per level over the full ``x``, the baseline).

    Returns:
        The :class:`Solution` (``x`` of shape ``(n,)``, one report per level, timings).

    Raises:
        InvalidLevel: Malformed level (message names the level and the field).
        InvalidInput: Malformed ``final_metric``, ``final_target`` or ``rank_tol``.
        UnknownBackend: Unknown or uninstalled backend.

    """
    return HierarchicalSolver(backend=backend, algorithm=algorithm, rank_tol=rank_tol).solve(
        levels, final_metric=final_metric, final_target=final_target
    )


def _active_rows(lv: CheckedLevel, cx: np.ndarray) -> np.ndarray:
    """Rows on, or beyond, a bound (report tolerance :data:`ROW_TOL`)."""
    tl, tu = _bound_tol(lv.lower, lv.upper, ROW_TOL)
    return (cx >= lv.upper - tu) | (cx <= lv.lower + tl)


def _sigma_level(
    lv: CheckedLevel,
    Ak: np.ndarray,
    Z: np.ndarray | None,
    x: np.ndarray,
    svd_a: tuple[np.ndarray, float] | None,
    rank_tol: float,
) -> float:
    """``sigma_min`` of one level: the m-th singular value of ``[A; C_active] Z``."""
    r = Ak.shape[1]
    me = lv.m_eq
    act = _active_rows(lv, lv.C @ x) if lv.m_in else None
    if act is not None and act.any():
        Ca = lv.C[act]
        M = np.concatenate([Ak, Ca if Z is None else Ca @ Z])
        s = np.linalg.svd(M, compute_uv=False)
        scale = max(float(s[0]) if s.size else 0.0, float(np.abs(Ca).max()),
                    float(np.abs(lv.A).max()) if me else 0.0)
        return _mth_singular(s, M.shape[0], r, rank_tol * scale)
    if svd_a is not None:
        return _mth_singular(svd_a[0], me, r, svd_a[1])
    return float("inf")


def _report(lv: CheckedLevel, x: np.ndarray, sigma: float) -> LevelReport:
    """Build the level's report at the solution ``x``."""
    res = lv.A @ x - lv.b
    if lv.m_in:
        cx = lv.C @ x
        viol = _dist(cx, lv.lower, lv.upper)
        tl, tu = _bound_tol(lv.lower, lv.upper, ROW_TOL)
        active = np.flatnonzero((cx >= lv.upper - tu) | (cx <= lv.lower + tl))
        violated = np.flatnonzero((viol > tu) | (viol < -tl))
    else:
        viol = np.zeros(0)
        active = violated = np.zeros(0, dtype=int)
    cost = float(res @ res + viol @ viol)
    return LevelReport(
        name=lv.name,
        cost=cost,
        satisfied=cost <= SATISFIED_COST,
        active=active,
        violated=violated,
        sigma_min=float(sigma),
        residual_eq=res,
        violation_in=viol,
    )


def _sigma_recursion(levels: list[CheckedLevel], x: np.ndarray, rank_tol: float) -> list[float]:
    """``sigma_min`` of every level at a given solution (used by the cascade).

    Follows the basis algorithm's definition: ``Z`` spans the null space of the
    equality rows and violated rows of the levels above.
    """
    n = x.shape[0]
    Z: np.ndarray | None = None
    r = n
    out = []
    for lv in levels:
        me, mi = lv.m_eq, lv.m_in
        if r == 0:
            m = me + (int(np.count_nonzero(_active_rows(lv, lv.C @ x))) if mi else 0)
            out.append(0.0 if m else float("inf"))
            continue
        Ak = lv.A if Z is None else lv.A @ Z
        svd_a = None
        if me:
            s = np.linalg.svd(Ak, compute_uv=False)
            svd_a = (s, rank_tol * max(float(s[0]) if s.size else 0.0, float(np.abs(lv.A).max())))
        out.append(_sigma_level(lv, Ak, Z, x, svd_a, rank_tol))
        rows = [lv.A]
        if mi:
            d = _dist(lv.C @ x, lv.lower, lv.upper)
            tl, tu = _bound_tol(lv.lower, lv.upper, ROW_TOL)
            rows.append(lv.C[(d > tu) | (d < -tl)])
        F = np.concatenate(rows)
        if F.shape[0] == 0:
            continue
        Fk = F if Z is None else F @ Z
        _, s, Vt = np.linalg.svd(Fk, full_matrices=True)
        scale = max(float(s[0]) if s.size else 0.0, float(np.abs(F).max()))
        null = Vt[int(np.count_nonzero(s > rank_tol * scale)):]
        Z = null.T if Z is None else Z @ null.T
        r = Z.shape[1]
    return out


def _append_independent(E: np.ndarray, A: np.ndarray, rank_tol: float) -> np.ndarray:
    """Rows of ``A`` appended to ``E`` one by one, skipping rows dependent on those kept."""
    rows = list(E)
    for a in A:
        if rows:
            M = np.array(rows)
            # distance of a to the row space of M
            coef, *_ = np.linalg.lstsq(M.T, a, rcond=None)
            resid = float(np.linalg.norm(a - M.T @ coef))
        else:
            resid = float(np.linalg.norm(a))
        if resid > 1e3 * rank_tol * max(1.0, float(np.linalg.norm(a))):
            rows.append(a)
    return np.array(rows).reshape(-1, E.shape[1])
