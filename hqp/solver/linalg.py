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
