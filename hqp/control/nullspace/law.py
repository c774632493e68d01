r"""The seed papers' prioritised null-space torque law on plain matrices (seed 003 eq. 11-23).

Fixed base, ``M qdd + h = tau``::

    tau = sum_k J_k|prec(k)^T F_k,      J_k|prec(k) = J_k N_prec(k)               (eq. 14-15)
    F_k = Lambda_k|prec(k) (a_k - J_k qdd_<k)                                     (eq. 21)

with ``Lambda_k|prec(k)^-1`` inverted on its range only when singular (eq. 22-23). Standing on
its feet, the same recursion runs in torque space with ``M^-1`` replaced by the
support-consistent ``Phi = (S N_s) M^-1 (S N_s)^T`` (Sentis, Park, Khatib, IEEE T-RO 2010).
The derivation, the whitened implementation and what links the law to the HQP solution are
in docs/design/nullspace.md.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg as sla

from hqp.errors import InvalidInput, check_array

EIG_TOL = 1e-12
"""Default relative threshold on the eigenvalues of ``Lambda^-1`` (eq. 22): an eigenvalue is
zero when below ``EIG_TOL`` times the largest eigenvalue of the task's unprojected
``J* Phi J*^T``."""

PHI_TOL = 1e-10
"""Relative threshold for the rank of the support-consistent ``Phi`` and of ``Lambda_s^-1``."""


@dataclass(frozen=True)
class LawLevel:
    """What the law did on one level.

    Attributes:
        name: The level's name.
        eigenvalues: Eigenvalues of ``Lambda_k|prec(k)^-1`` (eq. 22), descending, ``(m,)``
            [units of the rows per N m, e.g. 1/(kg m^2) for a position task on a fixed base].
        rank: Number of eigenvalues kept (above the threshold).
        threshold: Eigenvalue threshold used on this level.
        residual: ``J_k qdd - a_k`` at the final accelerations, ``(m,)``.
        force: ``F_k`` ``(m,)`` (eq. 21 or 23).
        target_norm: ``|a_k|`` (scale of the satisfaction test).

    """

    name: str
    eigenvalues: np.ndarray
    rank: int
    threshold: float
    residual: np.ndarray
    force: np.ndarray
    target_norm: float = 0.0

    @property
    def eig_min(self) -> float:
        """Smallest eigenvalue of ``Lambda^-1`` (0 for a level without rows)."""
        return float(self.eigenvalues[-1]) if self.eigenvalues.size else 0.0

    @property
    def singular(self) -> bool:
        """Whether an eigenvalue fell below the threshold (eq. 22)."""
        return self.rank < self.eigenvalues.size

    @property
    def satisfied(self) -> bool:
        """Whether ``J_k qdd = a_k`` holds: residual norm at most ``1e-6 * max(1, |a_k|)``."""
        return bool(np.linalg.norm(self.residual) <= 1e-6 * max(1.0, self.target_norm))


@dataclass(frozen=True)
class LawSolution:
    """Result of the prioritised torque law.

    Attributes:
        tau: Actuated torques ``(na,)`` [N m] (``na = nv`` on a fixed base).
        qdd: Joint accelerations ``(nv,)`` the torques produce (with the support held).
        f: Support forces in the coordinates of the support rows ``(ns,)`` (empty without
            support): ``M qdd + h = S^T tau + J_s^T f``.
        levels: One :class:`LawLevel` per level, highest priority first.
        tau_internal: Internal-force part of ``tau`` (in ``null(Phi)``) ``(na,)``.
        phi: Torque-space inverse inertia ``Phi`` ``(na, na)`` (``M^-1`` on a fixed base).
        phi_pinv: ``Phi^+`` ``(na, na)``.
        torque_to_qdd: ``B = M^-1 N_s^T S^T`` ``(nv, na)``: ``qdd = B tau + qdd0``.
        qdd0: Support-consistent acceleration without torques ``(nv,)``.
        whiten: ``W`` ``(nv, r)`` with ``Lambda_k|prec(k)^-1 = (J_k W Z_k)(J_k W Z_k)^T``
            (``r = rank Phi``; ``W = R^-1`` with ``M = R^T R`` on a fixed base).
        bases: ``Z_k`` ``(r, d_k)`` orthonormal bases of the whitened null space above each
            level ``k`` and one more after the last level (``N_prec(k)`` of eq. 19 becomes the
            orthogonal projector ``Z_k Z_k^T`` in whitened coordinates).
        null_spaces: ``N*_prec(k)`` ``(na, na)`` of eq. 19 for each level and one more after
            the last (``method="literal"`` only; empty otherwise).
        method: ``"whitened"`` or ``"literal"``.
        timings: Wall-clock seconds (``"law"``).

    """

    tau: np.ndarray
    qdd: np.ndarray
    f: np.ndarray
    levels: tuple[LawLevel, ...]
    tau_internal: np.ndarray
    phi: np.ndarray
    phi_pinv: np.ndarray
    torque_to_qdd: np.ndarray
    qdd0: np.ndarray
    whiten: np.ndarray
    bases: tuple[np.ndarray, ...]
    null_spaces: tuple[np.ndarray, ...] = ()
    method: str = "whitened"
    timings: dict[str, float] = field(default_factory=dict)

    def task_jacobian(self, J: np.ndarray) -> np.ndarray:
        """Support-consistent Jacobian ``J* = J B Phi^+`` ``(m, na)`` of rows ``J`` ``(m, nv)``."""
        return J @ self.torque_to_qdd @ self.phi_pinv

    def inverse_inertia(self, J: np.ndarray, level: int) -> np.ndarray:
        """``Lambda^-1`` ``(m, m)`` of rows ``J`` projected on the null space above ``level``.

        ``J*_|prec Phi J*_|prec^T`` with ``J*_|prec = J* N*_prec(level)`` (eq. 15-16); its
        eigenvalues are the feasibility measure of a single task of a level.
        """
        if self.method == "literal":
            Jp = self.task_jacobian(J) @ self.null_spaces[level]
            return Jp @ self.phi @ Jp.T
        Jh = J @ self.whiten @ self.bases[level]
        return Jh @ Jh.T


def _sym_pinv(A: np.ndarray, rel_tol: float, ref: float | None = None) -> tuple[
    np.ndarray, np.ndarray, int, float
]:
    """Pseudo-inverse of a symmetric PSD matrix by eigen-decomposition (eq. 22-23).

    Returns:
        ``(A^+, eigenvalues descending, rank, threshold)``.

    """
    m = A.shape[0]
    if m == 0:
        return np.zeros((0, 0)), np.zeros(0), 0, 0.0
    w, U = np.linalg.eigh(0.5 * (A + A.T))
    w = w[::-1]
    U = U[:, ::-1]
    scale = float(w[0]) if ref is None else float(ref)
    threshold = rel_tol * max(scale, 0.0)
    if threshold <= 0.0:
        threshold = np.finfo(float).tiny
    keep = w > threshold
    r = int(np.count_nonzero(keep))
    Ur = U[:, :r]
    pinv = (Ur / w[:r]) @ Ur.T
    return pinv, np.maximum(w, 0.0), r, threshold


def prioritized_torques(
    M: np.ndarray,
    h: np.ndarray,
    levels: Sequence[tuple[np.ndarray, np.ndarray]],
    *,
    S: np.ndarray | None = None,
    support: tuple[np.ndarray, np.ndarray] | None = None,
    names: Sequence[str] | None = None,
    eig_tol: float = EIG_TOL,
    internal_forces: str = "none",
    method: str = "whitened",
    support_weights: Callable[[np.ndarray], np.ndarray] | None = None,
    weight_passes: int = 3,
) -> LawSolution:
    """Compute the prioritised torque law on plain matrices (seed 003 eq. 11-23, Sentis 2010).

    Args:
        M: Joint-space inertia ``(nv, nv)`` (symmetric positive definite).
        h: Coriolis, centrifugal and gravity forces ``b + g`` ``(nv,)`` [N m].
        levels: Per level, highest priority first, ``(J_k (m_k, nv), a_k (m_k,))``: the task
            rows ``J_k qdd = a_k`` (``a_k = xdd_ref - dJ v``). Levels with 0 rows are allowed.
        S: Actuation selection ``(na, nv)`` (default: identity, fully actuated).
        support: Support rows ``(J_s (ns, nv), b_s (ns,))``: ``J_s qdd = b_s`` held by the
            contact forces ``f`` with ``M qdd + h = S^T tau + J_s^T f`` (``None``: no contact).
        names: Level names for the report.
        eig_tol: Relative eigenvalue threshold of eq. 22 (see :data:`EIG_TOL`).
        internal_forces: ``"none"`` (the plain law, no torque in ``null(Phi)``) or
            ``"min-norm"`` (add the internal-force torque that minimises ``||f||``).
        method: ``"whitened"`` (default: eq. 11-23 in inertia-whitened coordinates, see the
            docs/design/nullspace.md; singular values instead of squared ones, so about twice the
            digits) or ``"literal"`` (eq. 15-21 as written, the recursion of eq. 19 on
            ``(na, na)`` projectors).
        support_weights: For ``"min-norm"``: a function of the support forces ``f (ns,)``
            returning positive weights ``(ns,)``; the internal forces then minimise
            ``sum_i w_i(f) f_i^2``, by ``weight_passes`` passes of iteratively reweighted least
            squares starting from the unweighted choice (default: unit weights).
        weight_passes: Number of reweighting passes.

    Returns:
        The torques, accelerations, support forces and a per-level report.

    Raises:
        InvalidInput: Shapes do not match, non-finite entries, ``M`` not positive definite,
            bad ``eig_tol`` or ``internal_forces``.

    """
    t_start = time.perf_counter()
    M, h, S, checked, names = _checked(M, h, S, levels, names, eig_tol, internal_forces, method)
    d = _support_dynamics(M, h, S, support)
    if method == "literal":
        tau, records, null_spaces = _literal(checked, names, d.B, d.Phi, d.Phi_pinv, d.qdd0,
                                             eig_tol)
        bases: list[np.ndarray] = []
    else:
        y, records, bases = _whitened(checked, names, d.Wh, d.qdd0, eig_tol)
        tau = d.Tm @ y
        null_spaces = []

    # Internal forces: torques in null(Phi) change f, not qdd.
    tau_int = np.zeros(S.shape[0])
    if internal_forces == "min-norm" and d.Js.shape[0] and d.Z_int.shape[1]:
        tau_int = _internal_force_torque(d, h, S, tau, support_weights, weight_passes)
        tau = tau + tau_int

    qdd = d.qdd0 + d.B @ tau
    if d.Js.shape[0]:
        f = d.Lambda_s @ (d.bs - d.Js @ d.Minv @ (S.T @ tau - h))
    else:
        f = np.zeros(0)
    levels_out = tuple(
        LawLevel(name, eig, rank, thr, J @ qdd - a, F, float(np.linalg.norm(a)))
        for (name, eig, rank, thr, F), (J, a) in zip(records, checked)
    )
    return LawSolution(
        tau=tau,
        qdd=qdd,
        f=f,
        levels=levels_out,
        tau_internal=tau_int,
        phi=d.Phi,
        phi_pinv=d.Phi_pinv,
        torque_to_qdd=d.B,
        qdd0=d.qdd0,
        whiten=d.Wh,
        bases=tuple(bases),
        null_spaces=tuple(null_spaces),
        method=method,
        timings={"law": time.perf_counter() - t_start},
    )


def _checked(
    M: np.ndarray,
    h: np.ndarray,
    S: np.ndarray | None,
    levels: Sequence[tuple[np.ndarray, np.ndarray]],
    names: Sequence[str] | None,
    eig_tol: float,
    internal_forces: str,
    method: str,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[tuple[np.ndarray, np.ndarray]],
           Sequence[str]]:
    """Check the law's inputs; return them as float arrays: ``(M, h, S, levels, names)``."""
    M = check_array(M, (None, None), "prioritized_torques: M")
    nv = M.shape[0]
    if M.shape != (nv, nv):
        raise InvalidInput(f"prioritized_torques: M must be square, got {M.shape}")
    h = check_array(h, (nv,), "prioritized_torques: h")
    S = np.eye(nv) if S is None else check_array(S, (None, nv), "prioritized_torques: S")
    if not (np.isfinite(eig_tol) and 0.0 < eig_tol < 1.0):
        raise InvalidInput(f"prioritized_torques: eig_tol must be in (0, 1), got {eig_tol}")
    if internal_forces not in ("none", "min-norm"):
        raise InvalidInput(
            f"prioritized_torques: internal_forces must be 'none' or 'min-norm', "
            f"got {internal_forces!r}"
        )
    if method not in ("whitened", "literal"):
        raise InvalidInput(
            f"prioritized_torques: method must be 'whitened' or 'literal', got {method!r}"
        )
    checked: list[tuple[np.ndarray, np.ndarray]] = []
    for k, (J, a) in enumerate(levels):
        J = check_array(J, (None, nv), f"prioritized_torques: level {k} J")
        a = check_array(a, (J.shape[0],), f"prioritized_torques: level {k} a")
        checked.append((J, a))
    if names is None:
        names = [f"level {k}" for k in range(len(checked))]
    elif len(names) != len(checked):
        raise InvalidInput("prioritized_torques: names and levels differ in length")
    return M, h, S, checked, names


@dataclass(frozen=True)
class _SupportDynamics:
    """Support-consistent dynamics (Sentis et al. 2010) and the law's whitening.

    ``qdd = B tau + qdd0``; ``Phi = S B`` ``(na, na)``; ``Lambda^-1 = (J Wh Z)(J Wh Z)^T``;
    ``tau = Tm y`` from whitened coordinates; ``Z_int`` spans ``null(Phi)``.
    """

    Js: np.ndarray
    bs: np.ndarray
    Minv: np.ndarray
    Lambda_s: np.ndarray
    B: np.ndarray
    qdd0: np.ndarray
    Phi: np.ndarray
    Phi_pinv: np.ndarray
    Wh: np.ndarray
    Tm: np.ndarray
    Z_int: np.ndarray


def _support_dynamics(M: np.ndarray, h: np.ndarray, S: np.ndarray,
                      support: tuple[np.ndarray, np.ndarray] | None) -> _SupportDynamics:
    """``N_s = I - Jbar_s J_s``, ``B = M^-1 N_s^T S^T``, ``qdd0``, ``Phi = S B`` and its factors."""
    nv, na = M.shape[0], S.shape[0]
    try:
        R = sla.cholesky(M, lower=False)  # M = R^T R
    except np.linalg.LinAlgError:
        raise InvalidInput("prioritized_torques: M is not positive definite") from None
    Rinv = sla.solve_triangular(R, np.eye(nv), lower=False)
    Minv = Rinv @ Rinv.T
    plain = support is None and na == nv and np.array_equal(S, np.eye(nv))

    if support is not None:
        Js = check_array(support[0], (None, nv), "prioritized_torques: support J_s")
        bs = check_array(support[1], (Js.shape[0],), "prioritized_torques: support b_s")
    else:
        Js, bs = np.zeros((0, nv)), np.zeros(0)
    if Js.shape[0]:
        MinvJsT = Minv @ Js.T
        Lambda_s, _, _, _ = _sym_pinv(Js @ MinvJsT, PHI_TOL)
        Jbar_s = MinvJsT @ Lambda_s  # (nv, ns)
        Ns = np.eye(nv) - Jbar_s @ Js
        NsMinv = Ns @ Minv  # = M^-1 N_s^T
        B = NsMinv @ S.T  # (nv, na)
        qdd0 = -NsMinv @ h + Jbar_s @ bs
    else:
        Lambda_s = np.zeros((0, 0))
        B = Minv @ S.T
        qdd0 = -Minv @ h
    Phi = S @ B
    Phi = 0.5 * (Phi + Phi.T)
    if plain:  # fixed base: Phi = M^-1 = R^-1 R^-T, whitening by the Cholesky factor
        Phi_pinv = M.copy()
        Wh, Tm = Rinv, R.T.copy()
        Z_int = np.zeros((na, 0))
    else:  # Phi = U diag(w) U^T: L = U_r diag(w_r)^(1/2), null(Phi) = span(U_n)
        w, U = np.linalg.eigh(Phi)
        keep = w > PHI_TOL * max(float(w[-1]), 0.0)
        Ur, wr = U[:, keep], w[keep]
        Phi_pinv = (Ur / wr) @ Ur.T
        Tm = Ur / np.sqrt(wr)  # (L^T)^+
        Wh = B @ Tm  # B Phi^+ L
        Z_int = U[:, ~keep]
    return _SupportDynamics(Js, bs, Minv, Lambda_s, B, qdd0, Phi, Phi_pinv, Wh, Tm, Z_int)


def _internal_force_torque(
    d: _SupportDynamics,
    h: np.ndarray,
    S: np.ndarray,
    tau: np.ndarray,
    support_weights: Callable[[np.ndarray], np.ndarray] | None,
    weight_passes: int,
) -> np.ndarray:
    """Return the torque in ``null(Phi)`` that gives the least (weighted) support forces."""
    # f(tau) = Lambda_s (b_s - J_s M^-1 (S^T tau - h)); d f / d tau = -Lambda_s J_s M^-1 S^T
    Df = -d.Lambda_s @ (d.Js @ d.Minv @ S.T @ d.Z_int)
    f_plain = d.Lambda_s @ (d.bs - d.Js @ d.Minv @ (S.T @ tau - h))
    y_int = np.linalg.lstsq(Df, -f_plain, rcond=None)[0]
    for _ in range(weight_passes if support_weights is not None else 0):
        sw = np.sqrt(np.asarray(support_weights(f_plain + Df @ y_int), dtype=float))
        y_int = np.linalg.lstsq(sw[:, None] * Df, -sw * f_plain, rcond=None)[0]
    return d.Z_int @ y_int


def _whitened(
    levels: list[tuple[np.ndarray, np.ndarray]],
    names: Sequence[str],
    W: np.ndarray,
    qdd0: np.ndarray,
    eig_tol: float,
) -> tuple[np.ndarray, list[tuple], list[np.ndarray]]:
    """Eq. 14-23 in whitened coordinates ``y = L^T tau``.

    With ``J^ = J* L``: ``Lambda_k|prec(k)^-1 = J^_k Z_k Z_k^T J^_k^T`` (eq. 16), where
    ``Z_k Z_k^T = L^T N*_prec(k)^T L^+T`` is the (orthogonal) image of eq. 19; with the SVD
    ``J^_k Z_k = U diag(s) V^T``, the eigenvalues of eq. 22 are ``s^2`` and eq. 20-23 give
    ``L^T tau_k = J^_k|p^T F_k = Z_k V_r diag(1/s_r) U_r^T (a_k - J_k qdd_<k)``.
    """
    r = W.shape[1]
    y = np.zeros(r)
    Z = np.eye(r)
    bases = [Z]
    records = []
    for (J, a), name in zip(levels, names):
        m = J.shape[0]
        if m == 0:
            records.append((name, np.zeros(0), 0, 0.0, np.zeros(0)))
            bases.append(Z)
            continue
        Jh = J @ W
        ref = float(np.linalg.eigvalsh(Jh @ Jh.T)[-1])  # largest eigenvalue of J* Phi J*^T
        thr = max(eig_tol * ref, np.finfo(float).tiny)
        resid = a - J @ qdd0 - Jh @ y  # a_k - J_k qdd_<k
        if Z.shape[1] == 0:
            records.append((name, np.zeros(m), 0, thr, np.zeros(m)))
            bases.append(Z)
            continue
        U, sv, Vt = np.linalg.svd(Jh @ Z, full_matrices=True)
        eig = np.zeros(m)
        eig[: sv.size] = sv**2  # eq. 22: eigenvalues of Lambda^-1
        rank = int(np.count_nonzero(eig > thr))
        Ur, sr = U[:, :rank], sv[:rank]
        coef = (Ur.T @ resid) / sr
        F = Ur @ (coef / sr)  # eq. 23: U_r Sigma_r^-1 U_r^T (a_k - J_k qdd_<k)
        y = y + Z @ (Vt[:rank].T @ coef)  # L^T tau_k = J^_k|p^T F_k (eq. 20)
        Z = Z @ Vt[rank:].T  # eq. 19: what the level leaves free
        bases.append(Z)
        records.append((name, eig, rank, thr, F))
    return y, records, bases


def _literal(
    levels: list[tuple[np.ndarray, np.ndarray]],
    names: Sequence[str],
    B: np.ndarray,
    Phi: np.ndarray,
    Phi_pinv: np.ndarray,
    qdd0: np.ndarray,
    eig_tol: float,
) -> tuple[np.ndarray, list[tuple], list[np.ndarray]]:
    """Eq. 15-23 as written, in torque space (``Phi = M^-1``, ``J* = J`` on a fixed base)."""
    na = Phi.shape[0]
    tau = np.zeros(na)
    N = np.eye(na)
    null_spaces = [N.copy()]
    records = []
    qdd_prev = qdd0.copy()
    for (J, a), name in zip(levels, names):
        if J.shape[0] == 0:
            records.append((name, np.zeros(0), 0, 0.0, np.zeros(0)))
            null_spaces.append(N.copy())
            continue
        G = J @ B  # task acceleration per unit torque, = J* Phi
        Jstar = G @ Phi_pinv  # (m, na), J_k (S N_s)bar
        Jp = Jstar @ N  # eq. 15
        ref = float(np.linalg.eigvalsh(Jstar @ Phi @ Jstar.T)[-1])
        Lam, eig, rank, thr = _sym_pinv(Jp @ Phi @ Jp.T, eig_tol, ref)  # eq. 16, 22
        F = Lam @ (a - J @ qdd_prev)  # eq. 21 / 23
        tau_k = Jp.T @ F  # eq. 20
        tau += tau_k
        qdd_prev = qdd_prev + B @ tau_k
        N = N - (Phi @ Jp.T @ Lam) @ Jp  # eq. 19, recursively
        null_spaces.append(N.copy())
        records.append((name, eig, rank, thr, F))
    return tau, records, null_spaces
