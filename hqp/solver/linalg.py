"""Small dense factorisations shared by the hierarchical solver (LAPACK through SciPy)."""

from __future__ import annotations

import numpy as np
from scipy.linalg import lapack

_dgeqp3 = lapack.dgeqp3
_dgeqrf = lapack.dgeqrf
_dorgqr = lapack.dorgqr
_dtrtrs = lapack.dtrtrs
_dgels = lapack.dgels
_ZERO = np.zeros(0)


def singular_values(M: np.ndarray) -> np.ndarray:
    """Singular values of an ``(m, r)`` matrix with ``m <= r``, largest first.

    Computed from the ``(m, m)`` triangular factor of ``M^T`` (same singular
    values), which is much cheaper than an SVD of ``M`` when ``m << r``.
    """
    m = M.shape[0]
    if m == 0:
        return _ZERO
    qr, _tau, _work, info = _dgeqrf(np.asfortranarray(M.T))
    return np.linalg.svd(np.triu(qr[:m, :m]), compute_uv=False)


class PivotedQR:
    """Rank-revealing QR of a projected level matrix ``M`` ``(m, r)``: ``M^T P = Q R``.

    Rank: the number of ``|R_ii|`` above ``rank_tol * max(|R_00|, scale)``;
    ``|R_00|`` is the largest row norm of ``M``, within ``sqrt(m)`` of its
    largest singular value, and ``scale`` the largest entry of the level's
    unprojected rows (so rows that the levels above already fixed count as zero).
    """

    __slots__ = ("M", "qr", "piv", "tau", "rank", "_Q")

    def __init__(self, M: np.ndarray, rank_tol: float, scale: float) -> None:
        self.M = M
        qr, jpvt, tau, _work, info = _dgeqp3(np.asfortranarray(M.T))
        self.qr = qr
        self.piv = jpvt - 1
        self.tau = tau
        d = np.abs(np.diagonal(qr))
        top = max(float(d[0]) if d.size else 0.0, scale)
        self.rank = int(np.count_nonzero(d > rank_tol * top))
        self._Q: np.ndarray | None = None

    def Q(self) -> np.ndarray:
        """Full orthogonal factor ``(r, r)``."""
        if self._Q is None:
            r, m = self.qr.shape
            if m >= r:
                a = np.array(self.qr[:, :r], order="F")
                tau = self.tau
            else:
                a = np.zeros((r, r), order="F")
                a[:, :m] = self.qr
                tau = np.zeros(r)
                tau[: self.tau.size] = self.tau
            self._Q = _dorgqr(a, tau)[0]
        return self._Q

    def null(self) -> np.ndarray:
        """Orthonormal basis ``(r, r - rank)`` of the null space of ``M``."""
        return self.Q()[:, self.rank:]

    def lstsq(self, rhs: np.ndarray) -> np.ndarray:
        """Solve ``M y = rhs`` in the least-squares sense (minimum norm up to the rank cut)."""
        k = self.rank
        r = self.qr.shape[0]
        if k == 0:
            return np.zeros(r)
        rp = rhs[self.piv]
        if self.qr.shape[1] == k:
            # square lower-triangular R^T: one triangular solve
            z = _dtrtrs(self.qr[:k, :k], rp, trans=1)[0]
        else:
            # more rows than rank: least squares on the (m, k) trapezoid R[:k]^T
            L = np.tril(self.qr[:k, :].T)
            z = _dgels(L, rp)[1][:k]
        return self.Q()[:, :k] @ z

    def singular_values(self) -> np.ndarray:
        """Singular values of ``M`` (those of ``R``), largest first."""
        m = self.qr.shape[1]
        R = np.triu(self.qr[: min(m, self.qr.shape[0]), :])
        return np.linalg.svd(R, compute_uv=False)




_dgelsy = lapack.dgelsy


def lstsq(M: np.ndarray, rhs: np.ndarray, rank_tol: float, scale: float) -> np.ndarray:
    """Minimum-norm least-squares solution of ``M y ~ rhs`` (one LAPACK ``dgelsy`` call).

    Rank: complete orthogonal factorisation with column pivoting, with the
    threshold ``rank_tol * max(|R_00|, scale)`` as in :class:`PivotedQR`
    (``|R_00|`` estimated by the largest entry of ``M``, within a factor
    ``sqrt(r)`` of it).

    Args:
        M: Matrix ``(m, r)``.
        rhs: Right-hand side ``(m,)``.
        rank_tol: Relative rank threshold.
        scale: Largest entry of the unprojected rows (0 if unknown).

    Returns:
        ``y`` ``(r,)``.

    """
    m, r = M.shape
    if m == 0 or r == 0:
        return np.zeros(r)
    top = float(np.abs(M).max())
    if top == 0.0:
        return np.zeros(r)
    cond = rank_tol * max(1.0, scale / top)
    mx = max(m, r)
    b = np.zeros((mx, 1))
    b[:m, 0] = rhs
    lwork = 2 * mx + 64 * (r + 2)
    _v, x, _j, _rank, _info = _dgelsy(M, b, np.zeros(r, dtype=np.int32), cond, lwork,
                                      overwrite_a=0, overwrite_b=1)
    return x[:r, 0]


WEAK_COUNT_FLOOR = 1e-7
"""Relative singular value below which :func:`weak_filter` counts a direction as
rank-deficient: the eigenvalues of ``M M^T`` carry an absolute error of ``~eps * s_max^2``,
so ``s`` below ``~sqrt(eps) * s_max`` (1.5e-8) cannot be told from 0."""


def weak_filter(M: np.ndarray, rhs: np.ndarray, threshold: float, rank_tol: float,
                scale: float, centred: np.ndarray | None = None) -> tuple[np.ndarray, int]:
    """Filter the target of a level's weak directions (the level's ``weak_threshold``).

    With ``M = U S V^T`` (``M`` the level's equality rows projected on the optimal set
    above, ``(m, r)``), the component of ``rhs`` along each left singular vector ``u_i``
    whose singular value ``s_i`` is below ``threshold`` is scaled by ``(s_i / threshold)^2``:
    the least-squares step along ``v_i`` becomes ``s_i / threshold^2 * u_i^T rhs`` (bounded
    by ``|u_i^T rhs| / threshold``, continuous in ``s_i``, 0 at a singularity) instead of
    ``u_i^T rhs / s_i``. Directions at or above the threshold are untouched, so a level whose
    singular values all reach it keeps its exact target. Computed from the eigenvalues
    ``s_i^2`` of ``M M^T`` (``m`` is a task's few rows); accurate to
    ``eps * ||M||^2`` in ``s_i^2``, far below ``threshold^2`` for any useful threshold.

    Args:
        M: ``(m, r)`` projected equality rows.
        rhs: ``(m,)`` target residual ``b - A x0``.
        threshold: Singular-value threshold (``> 0``), in the level's row units.
        rank_tol: Relative rank threshold: singular values at or below
            ``max(rank_tol, WEAK_COUNT_FLOOR) * max(s_max, scale)`` are rank-deficient
            directions (:data:`WEAK_COUNT_FLOOR`: below it, ``s^2`` from ``M M^T`` is
            rounding), filtered (to 0, which changes no step) but not counted.
        scale: Largest entry of the level's unprojected rows.
        centred: The target residual at the minimum-norm point of the optimal set above
            (``b - A x_c``, ``x_c = x0 - Z Z^T x0``; ``None``: ``rhs``). The weak
            components are measured there, so that the filtered level does not depend on
            which point ``x0`` of that set the solver holds: ``rhs - U_w diag(1 - f)
            U_w^T centred``.

    Returns:
        ``(filtered rhs, number of weak directions above that floor)``.

    """
    m = M.shape[0]
    if m == 0 or rhs.size == 0:
        return rhs, 0
    lam, U = np.linalg.eigh(M @ M.T)
    t2 = threshold * threshold
    weak = lam < t2
    if not weak.any():
        return rhs, 0
    Uw = U[:, weak]
    lw = np.maximum(lam[weak], 0.0)
    shrink = 1.0 - lw / t2
    floor = max(rank_tol, WEAK_COUNT_FLOOR) * max(float(np.sqrt(max(lam[-1], 0.0))), scale)
    count = int(np.count_nonzero(lw > floor * floor))
    ref = rhs if centred is None else centred
    return rhs - Uw @ (shrink * (Uw.T @ ref)), count
