r"""The seed papers' prioritised null-space torque law, on the same tasks as the HQP controller.

This module is the closed-form cross-check of :mod:`hqp.controller`: it turns the same task
rows into joint torques with the dynamically consistent null-space projections of the
hierarchy paper (seed 003, eq. 11-23), extended to a floating base standing on its feet with
the multi-contact form of Sentis, Park and Khatib ("Compliant control of multicontact and
center-of-mass behaviors in humanoid robots", IEEE T-RO 26(3), 2010).

Notation
========

``M`` ``(nv, nv)`` joint-space inertia (the seed's ``A``), ``h = b + g`` ``(nv,)`` Coriolis,
centrifugal and gravity forces, ``S`` ``(na, nv)`` the actuation selection (``U = [0 I]`` of
Sentis et al.; ``S = I`` on a fixed base), ``tau`` ``(na,)`` the actuated torques. A task ``k``
(levels numbered from 0 here, from 1 in the seed) is given by its equality rows on the
accelerations, exactly the ``qdd`` columns of the HQP rows of the task::

    J_k qdd = a_k,        a_k = xdd_ref_k - dJ_k v     (the reference minus the drift)

Fixed base: seed 003, eq. 11-23
===============================

``M qdd + h = tau``. The torque is a sum of prioritised controls (eq. 11-14)::

    tau = sum_k  N_prec(k)^T J_k^T F_k = sum_k J_k|prec(k)^T F_k,           (eq. 14, 20)
    J_k|prec(k) = J_k N_prec(k),                                              (eq. 15)
    Lambda_k|prec(k)^-1 = J_k|prec(k) M^-1 J_k|prec(k)^T,                     (eq. 16)
    N_prec(k) = I - sum_{i<k} Jbar_i|prec(i) J_i|prec(i),                     (eq. 19)
    Jbar_i|prec(i) = M^-1 J_i|prec(i)^T Lambda_i|prec(i).

The first identity uses ``N^T N^T = N^T``. Eq. 18 (``J_i M^-1 N_prec(k)^T = 0`` for every
``i`` in ``prec(k)``) makes the control of level ``k`` invisible to the levels above, and
``N M^-1 = M^-1 N^T`` gives ``J_k M^-1 N_prec(k)^T J_k^T = Lambda_k|prec(k)^-1``. With
``qdd_<k = M^-1 (tau_<k - h)`` the acceleration produced by the levels above (and the bias
forces), the task acceleration is then
``J_k qdd = J_k qdd_<k + Lambda_k|prec(k)^-1 F_k``, and the force of eq. 21,

    F_k = Lambda_k|prec(k) xdd_ref_k + mu_k|prec(k) + p_k|prec(k)
        = Lambda_k|prec(k) (a_k - J_k qdd_<k),                                (eq. 17, 21)

i.e. ``mu + p = -Lambda_k|prec(k) J_k M^-1 (tau_<k - h)`` (with ``-dJ_k v`` in ``a_k``),
compensates the Coriolis, centrifugal and gravity forces seen by the task together with the
coupling of the higher-priority controls, and yields ``J_k qdd = a_k`` (eq. 17). When the task
is singular within the hierarchy, ``Lambda_k|prec(k)^-1`` is singular and is inverted on its
range only (eq. 22-23)::

    Lambda_k|prec(k)^-1 = U_r Sigma_r U_r^T  (+ U_n 0 U_n^T),                  (eq. 22)
    F_k = U_r Sigma_r^-1 U_r^T (a_k - J_k qdd_<k).                            (eq. 23)

An eigenvalue counts as zero when it is below ``eig_tol`` times the largest eigenvalue of the
task's own (unprojected) ``J_k M^-1 J_k^T`` (default ``eig_tol = 1e-12``; eigenvalues of
``Lambda^-1`` scale as squared singular values, so this is a relative threshold of 1e-6 on the
singular values of the inertia-whitened Jacobian). The eigenvalues are the law's feasibility
measure (seed 003, sec. 4.3): they are reported per level (:class:`LawLevel`) and, for each
task, as ``TaskStatus.sigma_min``.

*Implementation.* ``method="literal"`` runs eq. 15-21 as written. The default,
``method="whitened"``, computes the same quantities in inertia-whitened coordinates: with
``M = R^T R`` and ``y = R^-T tau``, ``Jbar_k|p J_k|p`` becomes an orthogonal projector, so eq. 19
is carried as an orthonormal basis ``Z_k`` of what the levels above leave free
(``N_prec(k) = R^-1 Z_k Z_k^T R``), ``Lambda_k|prec(k)^-1 = (J_k R^-1 Z_k)(J_k R^-1 Z_k)^T``
(eq. 16) and its eigen-decomposition (eq. 22) is the SVD of ``J_k R^-1 Z_k``: the squared
singular values are the eigenvalues, the left singular vectors are ``U_r``, ``U_n``. The torques
are identical; the rounding error grows with ``cond(Lambda^-1)^(1/2)`` instead of
``cond(Lambda^-1)``, which matters on robots whose wrists are light (G1: ``cond(M) ~ 5e3``).

Constraint torques come first (eq. 10-12): the joint-limit constraint of the seed's
experiment (eq. 25, the joints that entered their activation zone are driven to a safety
position, :mod:`hqp.tasks.joint_limit_zone`) is the top level of the hierarchy, the
operational tasks are projected into its null space.

Floating base on its feet: Sentis, Park, Khatib 2010
====================================================

``M qdd + h = S^T tau + J_s^T f`` with the support (contact) rows ``J_s qdd = b_s`` (rigid
contacts: ``b_s = -dJ_s v``, plus the stabilisation of :class:`~hqp.tasks.contact.Contact`).
Eliminating the contact forces::

    Lambda_s^-1 = J_s M^-1 J_s^T,    Jbar_s = M^-1 J_s^T Lambda_s,    N_s = I - Jbar_s J_s,
    f   = Lambda_s (b_s - J_s M^-1 (S^T tau - h)),
    qdd = M^-1 N_s^T S^T tau + qdd_0,       qdd_0 = -M^-1 N_s^T h + Jbar_s b_s,

(support-consistent dynamics: ``N_s M^-1 = M^-1 N_s^T``, ``J_s M^-1 N_s^T = 0``). ``qdd_0`` is
the contact-consistent acceleration without torques. A task sees the torques through

    J_k qdd = J_k* Phi tau + J_k qdd_0,
    Phi = (S N_s) M^-1 (S N_s)^T                 (na, na), rank nv - rank(J_s),
    J_k* = J_k (S N_s)bar = J_k M^-1 N_s^T S^T Phi^+     (support-consistent task Jacobian),

where ``(S N_s)bar = M^-1 (S N_s)^T Phi^+`` is the dynamically consistent inverse of ``S N_s``
and ``J_k* Phi = J_k M^-1 N_s^T S^T`` (the columns of ``S N_s M^-1 J_k^T`` lie in the range of
``Phi``). This is the fixed-base problem with ``M^-1`` replaced by ``Phi`` (positive
*semi*-definite) and ``J_k`` by ``J_k*``, so eq. 14-23 apply unchanged in torque space::

    Lambda*_k|p^-1 = J*_k|p Phi J*_k|p^T,   J*_k|p = J_k* N*_prec(k),
    N*_prec(k+1) = N*_prec(k) - Jbar*_k|p J*_k|p,   Jbar*_k|p = Phi J*_k|p^T Lambda*_k|p,
    tau = sum_k J*_k|p^T F_k + tau_int,    F_k = Lambda*_k|p (a_k - J_k qdd_<k).

On a fixed base ``Phi = M^-1`` and ``J* = J``: the same code runs both cases.

**Internal forces.** ``null(Phi) = null(N_s^T S^T)``: a torque ``tau_int`` there gives
``S^T tau_int = J_s^T f_int`` with ``f_int`` a self-equilibrated contact wrench (zero net
force on the base), it changes the contact forces by ``-f_int`` and no acceleration at all
(Sentis et al.'s internal forces). Every ``J*^T F`` lies in ``range(Phi^+) = range(Phi)``, so
the plain law (``internal_forces="none"``) sends no internal-force torque. With
``internal_forces="min-norm"`` the law adds the ``tau_int`` in ``null(Phi)`` that makes the
contact wrenches ``f`` of least norm (feet share the load; no squeezing), leaving ``qdd``
unchanged.

What links the law to the HQP solution
======================================

*Fixed base.* ``tau^T M^-1 tau = (qdd + M^-1 h)^T M (qdd + M^-1 h)``. The law's torque lies in
``range([J_1^T ... J_N^T])`` (each ``N_prec^T J_k^T`` does), which is the Lagrange condition of
``min tau^T M^-1 tau`` under the task accelerations. Level by level, the task acceleration the
law reaches is ``J_k qdd_<k`` plus the Euclidean projection of ``a_k - J_k qdd_<k`` on
``range(Lambda_k|p^-1) = range(J_k N_prec(k)) = J_k null(J_<k)`` (``Lambda^-1`` is symmetric),
which is exactly the least-squares optimum of level ``k`` over the optimal set of the levels
above, and lower levels never change it (eq. 18). Hence: *on an equality-only stack whose rank
decisions agree (the levels are feasible, or their projected matrices have well separated zero
singular values), the law returns the lexicographic optimum of the task levels that minimises*
``(qdd + M^-1 h)^T M (qdd + M^-1 h)``, i.e. HQP's ``solve`` with ``final_metric = M`` and
``final_target = -M^-1 h`` on ``qdd`` -- the same ``qdd`` and ``tau``. With ``final_target = 0``
HQP minimises the kinetic-energy-like ``qdd^T M qdd`` instead and differs wherever redundancy
is left and ``h`` has a component there.

*Floating base.* On the support-consistent set ``{J_s qdd = b_s}`` every torque producing
``qdd`` gives ``tau^T Phi tau = (qdd - qdd_0)^T M (qdd - qdd_0)``, and ``qdd_0`` is the
``M``-orthogonal projection of ``-M^-1 h`` on that set, so
``(qdd + M^-1 h)^T M (qdd + M^-1 h) = (qdd - qdd_0)^T M (qdd - qdd_0) + const`` there. The law's
torque is the minimiser of ``tau^T Phi tau`` under the task accelerations (same Lagrange
argument in torque space) with no component in ``null(Phi)``. Therefore, with the HQP stack
``[physics: base rows of the dynamics + contact rows | task levels ...]`` over
``x = [qdd | f]``:

1. every level reaches the same task accelerations ``J_k qdd`` under both (for every
   feasible level, and for infeasible ones with agreeing rank decisions);
2. HQP with ``final_metric = M`` and ``final_target = -M^-1 h`` on the ``qdd`` block returns the
   law's ``qdd`` (whatever the law does with internal forces); the contact wrenches and torques
   may differ by an internal-force pair (``tau_int`` in ``null(Phi)``, ``f_int``);
3. with ``tau = T x + t0`` the torque map of the HQP (:func:`hqp.tasks.dynamics.torque_map`)
   and ``W = Phi + P_null(Phi)``, HQP with ``final_metric = T^T W T`` and
   ``final_target = -(T^T W T)^+ T^T W t0`` returns the law's ``qdd``, ``f`` and ``tau`` with
   ``internal_forces="none"`` (the cost is ``||qdd - qdd_0||_M^2 + ||P_null(Phi) tau||^2``: its
   first term is the law's criterion, its second is zeroed by the law and can be zeroed
   independently of ``qdd``). :func:`floating_base_metric` builds this pair.

These statements hold for the equality rows. The law has no inequalities: friction cones,
torque limits and the HQP's viable joint limits are not enforced (only reported), which is
what the activation-zone primitive is for.

Contact and actuation limits as activation zones (opt-in)
=========================================================

The plain law grants whatever the task rows ask, including a support wrench the feet cannot
give. On the hand-reach scenario (seed 003 sec. 5, ``hqp compare hand-reach``) this is what
makes ``paper-humanoid`` fall within 0.1 s in both hierarchies: at the very first step the
accelerations of the CoG, hand and symmetry-posture rows need a centre of pressure about 2 cm
behind the soles (13 cm behind each ankle for a 12.5 cm half sole) and a head torque 17 %
beyond its limit. The feet tip on their heels, the ankle pitch (standing 0.024 rad from its
0.1 rad zone) enters its zone after 4 ms, the zone's PD (kp 400, kv 40) then asks for a
deceleration of the whole body about the ankle that needs a centre of pressure ~1 m away and
torques of 1-2 kN m (clipped to the limits), and the robot collapses. The HQP controller keeps
the same tasks feasible because its contact-limit level (centre of pressure, friction, torque
limits) is above the tasks.

:class:`NullSpaceController` can apply the papers' own constraint mechanism, the activation
zone, to these limits (``support_zone``, ``torque_zone``; off by default, so the controller is
the papers' law): when the plain law's centre of pressure leaves a zone of the support polygon,
or a joint's torque leaves a zone of its limit, equality rows that hold it at the zone's border
(:func:`support_moment_rows`; ``tau_j = Phi^+ S (qdd - qdd_0) + tau_int``) become the top task
level, above the joint-limit zones (constraints first, eq. 10-12, in the HQP stack's order) and
the law is applied again. On hand-reach (both hierarchies) this keeps the run inside its limits
for its first second (no fall, no joint past its limit, no clipping, CoG error below 0.1 mm,
hand 56 cm from its target at 1 s, close to the HQP run); at about 1.1 s the torso pitch
(78 N m, held since 0.55 s) and head pitch (8 N m) torques are both at their zones, the held
rows switch on and off between steps and the solution jumps (|qdd| from 7 to 45 rad/s^2 in
one step, the feet rock sideways) and the robot falls at 1.2-1.5 s. Equalities switched by
zones cannot replace inequalities above the tasks there; the HQP run keeps the torso at its
torque limit from 0.9 s to the end.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
import scipy.linalg as sla

from hqp.errors import InvalidInput, check_array

if TYPE_CHECKING:
    from hqp.controller import Controller, TaskStatus
    from hqp.model import RobotModel
    from hqp.robots import Robot
    from hqp.stack import BuiltStack, Stack
    from hqp.tasks.base import Task

logger = logging.getLogger(__name__)

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
            module docstring; singular values instead of squared ones, so about twice the
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
    M = check_array(M, (None, None), "prioritized_torques: M")
    nv = M.shape[0]
    if M.shape != (nv, nv):
        raise InvalidInput(f"prioritized_torques: M must be square, got {M.shape}")
    h = check_array(h, (nv,), "prioritized_torques: h")
    S = np.eye(nv) if S is None else check_array(S, (None, nv), "prioritized_torques: S")
    na = S.shape[0]
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

    try:
        R = sla.cholesky(M, lower=False)  # M = R^T R
    except np.linalg.LinAlgError:
        raise InvalidInput("prioritized_torques: M is not positive definite") from None
    Rinv = sla.solve_triangular(R, np.eye(nv), lower=False)
    Minv = Rinv @ Rinv.T
    plain = support is None and na == nv and np.array_equal(S, np.eye(nv))

    # Support-consistent dynamics (Sentis et al. 2010).
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

    if method == "literal":
        tau, records, null_spaces = _literal(checked, names, B, Phi, Phi_pinv, qdd0, eig_tol)
        bases: list[np.ndarray] = []
    else:
        y, records, bases = _whitened(checked, names, Wh, qdd0, eig_tol)
        tau = Tm @ y
        null_spaces = []

    # Internal forces: torques in null(Phi) change f, not qdd.
    tau_int = np.zeros(na)
    if internal_forces == "min-norm" and Js.shape[0] and Z_int.shape[1]:
        # f(tau) = Lambda_s (b_s - J_s M^-1 (S^T tau - h)); d f / d tau = -Lambda_s J_s M^-1 S^T
        Df = -Lambda_s @ (Js @ Minv @ S.T @ Z_int)
        f_plain = Lambda_s @ (bs - Js @ Minv @ (S.T @ tau - h))
        y_int = np.linalg.lstsq(Df, -f_plain, rcond=None)[0]
        for _ in range(weight_passes if support_weights is not None else 0):
            sw = np.sqrt(np.asarray(support_weights(f_plain + Df @ y_int), dtype=float))
            y_int = np.linalg.lstsq(sw[:, None] * Df, -sw * f_plain, rcond=None)[0]
        tau_int = Z_int @ y_int
        tau = tau + tau_int

    qdd = qdd0 + B @ tau
    if Js.shape[0]:
        f = Lambda_s @ (bs - Js @ Minv @ (S.T @ tau - h))
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
        phi=Phi,
        phi_pinv=Phi_pinv,
        torque_to_qdd=B,
        qdd0=qdd0,
        whiten=Wh,
        bases=tuple(bases),
        null_spaces=tuple(null_spaces),
        method=method,
        timings={"law": time.perf_counter() - t_start},
    )


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


def floating_base_metric(
    solution: LawSolution, T: np.ndarray, t0: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """HQP final metric and target that reproduce the law's ``qdd``, ``f`` and ``tau``.

    With the HQP torque map ``tau = T x + t0`` (:func:`hqp.tasks.dynamics.torque_map`) and
    ``W = Phi + P_null(Phi)``, returns ``Q = T^T W T`` and ``x_t = -Q^+ T^T W t0``, so that
    ``(x - x_t)^T Q (x - x_t) = tau^T W tau + const`` (module docstring, statement 3). On a
    fixed base ``W = M^-1`` and the pair is equivalent to ``final_metric = M``,
    ``final_target = -M^-1 h`` on ``qdd``.

    Args:
        solution: A law solution at the same state (for ``Phi``).
        T: Torque map ``(na, n)``.
        t0: Torque offset ``(na,)`` [N m].

    Returns:
        ``(final_metric (n, n), final_target (n,))``.

    """
    Phi = solution.phi
    w, U = np.linalg.eigh(Phi)
    Z = U[:, w <= PHI_TOL * max(float(w[-1]), 0.0)]
    W = Phi + Z @ Z.T
    Q = T.T @ W @ T
    Q = 0.5 * (Q + Q.T)
    target = -np.linalg.pinv(Q, rcond=1e-12, hermitian=True) @ (T.T @ W @ t0)
    return Q, target


# ------------------------------------------------------------------------------------------------
# The controller: the law on the tasks of a Stack, behind the Controller interface
# ------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class _LawProblem:
    """The law's view of a built stack.

    Attributes:
        support: ``(J_s, b_s)`` qdd-only equality rows of the physics level (active contacts).
        levels: ``(J_k, a_k)`` qdd-only equality rows of each other built level.
        names: Level names.
        built_levels: Built-level index of each law level.
        task_rows: Per task name ``(law level, J (unweighted), a)`` of its qdd-only rows.
        skipped: Notes on rows the law cannot use (inequalities, rows on contact forces).

    """

    support: tuple[np.ndarray, np.ndarray] | None
    levels: list[tuple[np.ndarray, np.ndarray]]
    names: list[str]
    built_levels: list[int]
    task_rows: dict[str, tuple[int, np.ndarray, np.ndarray]]
    skipped: tuple[str, ...]


def law_problem(built: object, stack: object, nv: int) -> _LawProblem:
    """Turn the levels of a :class:`~hqp.stack.BuiltStack` into the law's matrices.

    Rules (the task rows are the same objects the HQP solves, scaled by ``sqrt(weight)``):

    * equality rows with a nonzero entry on the contact-force columns are physics rows (the
      unactuated rows of the dynamics, released contact slots at zero) or force tasks; the law
      embeds the dynamics itself and cannot command forces: they are not used;
    * equality rows on ``qdd`` only, at the PHYSICS level (category PHYSICS or a level named
      ``"physics"``), are the support rows ``J_s qdd = b_s`` (the active contacts' motion
      constraints);
    * equality rows on ``qdd`` only, at any other level, are that level's task rows;
    * inequality rows are not used (the law has none); the controller reports their violation.

    Args:
        built: A :class:`~hqp.stack.BuiltStack`.
        stack: The :class:`~hqp.stack.Stack` it was built from.
        nv: Number of joint velocities.

    Returns:
        The law's support, levels and per-task rows.

    """
    from hqp.tasks.base import Category

    by_level: dict[int, list] = {}
    for span in built.spans:  # type: ignore[attr-defined]
        by_level.setdefault(span.built_level, []).append(span)
    support_J: list[np.ndarray] = []
    support_b: list[np.ndarray] = []
    levels: list[tuple[np.ndarray, np.ndarray]] = []
    names: list[str] = []
    built_levels: list[int] = []
    task_rows: dict[str, tuple[int, np.ndarray, np.ndarray]] = {}
    skipped: list[str] = []
    for k, level in enumerate(built.levels):  # type: ignore[attr-defined]
        index = built.level_index[k]  # type: ignore[attr-defined]
        physics = (
            stack.level_categories[index] is Category.PHYSICS  # type: ignore[attr-defined]
            or stack.level_names[index] == "physics"  # type: ignore[attr-defined]
        )
        J_rows: list[np.ndarray] = []
        a_rows: list[np.ndarray] = []
        for span in by_level.get(k, []):
            rows = built.rows[span.name]  # type: ignore[attr-defined]
            if rows.C is not None and rows.C.shape[0] and not physics:
                skipped.append(f"{span.name}: {rows.C.shape[0]} inequality rows not enforced")
            if rows.A is None or rows.A.shape[0] == 0:
                continue
            A = np.asarray(level.A)[span.eq]
            b = np.asarray(level.b)[span.eq]
            qdd_only = ~np.any(A[:, nv:] != 0.0, axis=1)
            if not physics and not qdd_only.all():
                skipped.append(f"{span.name}: rows on contact forces not used")
            if not qdd_only.any():
                continue
            if physics:
                support_J.append(A[qdd_only, :nv])
                support_b.append(b[qdd_only])
            else:
                J_rows.append(A[qdd_only, :nv])
                a_rows.append(b[qdd_only])
                task_rows[span.name] = (
                    len(levels),
                    np.asarray(rows.A)[qdd_only, :nv],
                    np.asarray(rows.b)[qdd_only],
                )
        if not physics and J_rows:
            levels.append((np.vstack(J_rows), np.concatenate(a_rows)))
            names.append(str(level.name))
            built_levels.append(k)
    support = (np.vstack(support_J), np.concatenate(support_b)) if support_J else None
    return _LawProblem(support, levels, names, built_levels, task_rows, tuple(skipped))


# ------------------------------------------------------------------------------------------------
# The support constraint as an activation zone (centre of pressure of the feet)
# ------------------------------------------------------------------------------------------------

SUPPORT_ZONE = 0.8
"""Default fraction of each contact's centre-of-pressure box (``half_length`` x ``half_width``)
inside which the law's centre of pressure may move freely (:class:`NullSpaceController`)."""

TORQUE_ZONE = 0.95
"""Default fraction of the torque limits beyond which a joint's torque is held at the zone's
border (:class:`NullSpaceController`)."""


def support_polygon(
    model: RobotModel, contacts: Sequence[object], scale: float
) -> tuple[np.ndarray, float]:
    """Convex hull of the contacts' centre-of-pressure boxes, scaled by ``scale``.

    A surface contact contributes the four corners ``p + R [+-scale hl, +-scale hw, 0]`` of its
    box (``hl``, ``hw`` its ``half_length``, ``half_width``), a point contact its origin.

    Args:
        model: The updated robot model.
        contacts: :class:`~hqp.tasks.contact.Contact` tasks (active ones).
        scale: Fraction of each box (``> 0``).

    Returns:
        ``(hull (k, 2) counter-clockwise [m], height [m])``: the hull's vertices in the
        horizontal plane and the mean height of the contact points (the plane of the centre of
        pressure).

    """
    from hqp.layout import ContactType

    pts = []
    for c in contacts:
        T = model.frame_placement(c.frame)  # type: ignore[attr-defined]
        p, R = T.translation, T.rotation
        if c.kind is ContactType.SURFACE:  # type: ignore[attr-defined]
            hl = scale * float(getattr(c, "half_length", 0.0))
            hw = scale * float(getattr(c, "half_width", 0.0))
            for sx, sy in ((1, 1), (-1, 1), (-1, -1), (1, -1)):
                pts.append(p + R @ np.array([sx * hl, sy * hw, 0.0]))
        else:
            pts.append(np.array(p, dtype=float))
    P = np.array(pts)
    return _convex_hull(P[:, :2]), float(P[:, 2].mean())


def _convex_hull(points: np.ndarray) -> np.ndarray:
    """Counter-clockwise convex hull ``(k, 2)`` of ``(n, 2)`` points (monotone chain)."""
    pts = sorted({(float(x), float(y)) for x, y in points})
    if len(pts) <= 2:
        return np.array(pts)

    def cross(o: tuple, a: tuple, b: tuple) -> float:
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    lower: list[tuple] = []
    for q in pts:
        while len(lower) >= 2 and cross(lower[-2], lower[-1], q) <= 0.0:
            lower.pop()
        lower.append(q)
    upper: list[tuple] = []
    for q in reversed(pts):
        while len(upper) >= 2 and cross(upper[-2], upper[-1], q) <= 0.0:
            upper.pop()
        upper.append(q)
    return np.array(lower[:-1] + upper[:-1])


def project_to_polygon(point: np.ndarray, hull: np.ndarray) -> tuple[np.ndarray, bool]:
    """Closest point of a convex polygon to ``point`` ``(2,)``, and whether it was inside.

    Args:
        point: ``(2,)`` [m].
        hull: Counter-clockwise vertices ``(k, 2)`` (:func:`support_polygon`).

    """
    k = hull.shape[0]
    if k == 0:
        return point.copy(), False
    if k == 1:
        return hull[0].copy(), bool(np.allclose(point, hull[0]))
    inside = True
    best, best_d = hull[0].copy(), np.inf
    for i in range(k):
        a, b = hull[i], hull[(i + 1) % k]
        e = b - a
        if k > 2 and e[0] * (point[1] - a[1]) - e[1] * (point[0] - a[0]) < 0.0:
            inside = False
        s = float(np.clip(np.dot(point - a, e) / max(float(np.dot(e, e)), 1e-300), 0.0, 1.0))
        c = a + s * e
        d = float(np.linalg.norm(point - c))
        if d < best_d:
            best, best_d = c, d
    if inside and k > 2:
        return point.copy(), True
    return best, False


def support_moment_rows(
    model: RobotModel, point: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Rows on ``qdd`` that put the centre of pressure of the support at ``point``.

    The contact wrench resultant follows from the centroidal momentum rate
    ``hdot = A_g qdd + dA_g v`` (about the centre of mass ``c``, world axes):
    ``F = hdot_lin - m g`` (``g`` the gravity vector) and ``M_c = hdot_ang``. Its moment about
    ``p`` is ``M_p = M_c + (c - p) x F``; the centre of pressure is at ``p`` when the two
    horizontal components of ``M_p`` vanish. Both rows are linear in ``qdd``, divided by the
    robot's weight ``m |g|`` (a residual reads as [m] at nominal load).

    Args:
        model: The updated robot model.
        point: ``(3,)`` the point ``p`` [m] (on the plane of the contacts).

    Returns:
        ``(J (2, nv), a (2,))`` with ``J qdd = a`` meaning ``M_p,x = M_p,y = 0``.

    """
    Ag = model.centroidal_matrix
    d = model.centroidal_drift
    m = model.mass
    g = model.gravity_vector
    r = model.com - np.asarray(point, dtype=float)
    rx = np.array([[0.0, -r[2], r[1]], [r[2], 0.0, -r[0]], [-r[1], r[0], 0.0]])
    # M_p = Ag_ang qdd + d_ang + r x (Ag_lin qdd + d_lin - m g)
    J = Ag[3:] + rx @ Ag[:3]
    c = d[3:] + rx @ (d[:3] - m * g)
    scale = 1.0 / (m * max(float(np.linalg.norm(g)), 1e-12))
    return scale * J[:2], -scale * c[:2]


def center_of_pressure(
    model: RobotModel, qdd: np.ndarray, height: float
) -> tuple[np.ndarray, float]:
    """Centre of pressure of the support wrench that produces ``qdd``, and its normal force.

    The resultant is that of :func:`support_moment_rows` (centroidal momentum rate).

    Args:
        model: The updated robot model.
        qdd: Joint accelerations ``(nv,)``.
        height: Height of the plane of the centre of pressure [m].

    Returns:
        ``(cop (2,) [m], F_z [N])``; ``cop`` is ``nan`` when ``F_z <= 0`` (a pulling support).

    """
    hd = model.centroidal_matrix @ qdd + model.centroidal_drift
    F = hd[:3] - model.mass * model.gravity_vector
    Mc = hd[3:]
    c = model.com
    dz = c[2] - height
    if F[2] <= 1e-9:
        return np.array([np.nan, np.nan]), float(F[2])
    px = c[0] - (Mc[1] + dz * F[0]) / F[2]
    py = c[1] - (dz * F[1] - Mc[0]) / F[2]
    return np.array([px, py]), float(F[2])


def _controller_base() -> type:
    from hqp.controller import WholeBodyController

    return WholeBodyController


class NullSpaceController(_controller_base()):  # type: ignore[misc]
    """The papers' null-space torque law behind the HQP controller's interface.

    Same constructor shape, same :meth:`step`, same :class:`~hqp.controller.Command` and
    :class:`~hqp.controller.FeasibilityReport` as :class:`~hqp.controller.WholeBodyController`
    (it reuses its stack handling, torque blending, safe command and torque-limit check); only
    the solve differs: the task rows of the stack become the law's levels (:func:`law_problem`),
    solved by :func:`prioritized_torques`.

    Reports: a task's ``TaskStatus.sigma_min`` holds the smallest eigenvalue of its own
    ``Lambda_task|prec(level)^-1`` (eq. 16, 22: ``m``-th eigenvalue of its ``m`` rows, 0 when
    the levels above leave fewer than ``m`` directions), the law's feasibility measure; the
    task is SINGULAR when that eigenvalue is below ``singular_tolerance`` times the largest
    eigenvalue of its unprojected ``Lambda^-1``. Residuals and conflicts are measured on the
    task's unweighted rows as in the HQP controller; inequality rows (friction, torque and
    viable joint limits) are not enforced by the law, only reported. The full per-level
    eigenvalues of the last step are in ``last_law.levels``.

    Args:
        robot_model: The controller's robot model.
        contacts: Contacts to declare (as for the HQP controller; their limit rows are added
            only when the stack has a CONTACT_LIMITS level, they are reported, not enforced).
        stack: The levels of tasks (joint limits the papers' way: put a
            :class:`~hqp.tasks.joint_limit_zone.JointLimitZone` at the top task level).
        dt: Control period [s].
        backend: Accepted for call compatibility with the HQP controller; unused.
        algorithm: Accepted for call compatibility; unused.
        eig_tol: Relative eigenvalue threshold of eq. 22 (:data:`EIG_TOL`).
        internal_forces: ``"balanced"`` (least load-weighted use of every contact's centre of
            pressure and friction, :meth:`_utilization_weights`), ``"min-norm"`` (default:
            least-norm contact wrenches) or
            ``"none"`` (the plain law); see :func:`prioritized_torques`.
        method: ``"whitened"`` or ``"literal"`` (see :func:`prioritized_torques`).
        tolerance: A task whose unweighted residual norm exceeds this is in conflict.
        singular_tolerance: Relative eigenvalue threshold of the SINGULAR status.
        damping: Joint damping of the safe command [N m s/rad].
        final_metric: Accepted for call compatibility; unused (the law's tie-break is fixed:
            least ``tau^T Phi tau``, module docstring).
        final_target: Accepted for call compatibility; unused.
        diagnostics: ``"full"`` (per-task eigenvalues and ``yields_to``) or ``"residuals"``.
        support_zone: Fraction of each contact's centre-of-pressure box that bounds the
            support's centre of pressure, as an activation zone at the top of the task
            hierarchy (``None``, the default: the plain law; module docstring and
            :meth:`_constraint_zones`).
        torque_zone: Fraction of the torque limits that bounds each joint's torque, as an
            activation zone at the same level (``None``, the default: the plain law).
        zone_passes: Largest number of re-applications of the law per step for the zones.

    Raises:
        InvalidInput: Bad period, tolerances, ``eig_tol``, ``internal_forces``, ``method``,
            ``support_zone``, ``torque_zone`` or ``zone_passes``.

    """

    def __init__(
        self,
        robot_model: RobotModel,
        contacts: Sequence[Task] = (),
        stack: Stack | None = None,
        dt: float = 0.001,
        backend: str | None = None,
        algorithm: str | None = None,
        *,
        eig_tol: float = EIG_TOL,
        internal_forces: str = "min-norm",
        method: str = "whitened",
        tolerance: float = 1e-5,
        singular_tolerance: float = 1e-6,
        damping: float = 2.0,
        final_metric: np.ndarray | None = None,
        final_target: np.ndarray | None = None,
        diagnostics: str = "full",
        support_zone: float | None = None,
        torque_zone: float | None = None,
        zone_passes: int = 4,
    ) -> None:
        from hqp.stack import Stack
        from hqp.tasks.base import Category

        stack = Stack() if stack is None else stack
        # The law enforces no contact limits: declare them only where the stack has their level.
        limits = Category.CONTACT_LIMITS in stack.level_categories
        for contact in contacts:
            if contact.name not in stack.contacts:
                stack.add_contact(contact, limits=limits)
        super().__init__(robot_model, (), stack, dt, tolerance=tolerance,
                         singular_tolerance=singular_tolerance, diagnostics=diagnostics,
                         damping=damping)
        if not (np.isfinite(eig_tol) and 0.0 < eig_tol < 1.0):
            raise InvalidInput(f"NullSpaceController: eig_tol must be in (0, 1), got {eig_tol}")
        if internal_forces not in ("none", "min-norm", "balanced"):
            raise InvalidInput(
                "NullSpaceController: internal_forces must be 'none', 'min-norm' or "
                f"'balanced', got {internal_forces!r}"
            )
        if method not in ("whitened", "literal"):
            raise InvalidInput(
                f"NullSpaceController: method must be 'whitened' or 'literal', got {method!r}"
            )
        if support_zone is not None and not (np.isfinite(support_zone) and support_zone > 0.0):
            raise InvalidInput(
                f"NullSpaceController: support_zone must be > 0 or None, got {support_zone}"
            )
        self.backend = "nullspace"
        self.algorithm = "nullspace"
        if torque_zone is not None and not (np.isfinite(torque_zone) and 0.0 < torque_zone <= 1.0):
            raise InvalidInput(
                f"NullSpaceController: torque_zone must be in (0, 1] or None, got {torque_zone}"
            )
        if int(zone_passes) < 1:
            raise InvalidInput(f"NullSpaceController: zone_passes must be >= 1, got {zone_passes}")
        self.support_zone = None if support_zone is None else float(support_zone)
        self.torque_zone = None if torque_zone is None else float(torque_zone)
        self.zone_passes = int(zone_passes)
        self.torques_held: tuple[int, ...] = ()
        """Actuated joints whose torque was held at its zone's border at the last step."""
        self.support_active = False
        """Whether the support constraint was active at the last step."""
        self.last_cop: np.ndarray | None = None
        """Centre of pressure ``(2,)`` [m] the plain law asked for at the last step (``None``
        without support or with ``support_zone=None``)."""
        self.eig_tol = float(eig_tol)
        self.internal_forces = internal_forces
        self.method = method
        self.last_law: LawSolution | None = None
        self.last_problem: _LawProblem | None = None

    # -- one step ---------------------------------------------------------------------------

    def _solve_built(
        self, built: BuiltStack, t: float, notes: list[str]
    ) -> tuple[np.ndarray, np.ndarray] | None:
        """Apply the law to the built stack: ``(x, tau)``, or ``None`` for the safe command.

        The rest of the step (update, rows, safe command, blending, clipping) is
        :meth:`WholeBodyController.step`, shared with the HQP controller.
        """
        from hqp.errors import HQPError

        m = self.model
        self.last_law = None
        self.support_active = False
        self.torques_held = ()
        self.last_cop = None
        self.last_problem = problem = law_problem(built, self.stack, m.nv)
        try:
            law = self._law(problem)
            law, problem = self._constraint_zones(law, problem, notes)
            self.last_problem = problem
        except (HQPError, np.linalg.LinAlgError) as exc:
            notes.append(f"law failed: {exc}")
            logger.warning("t=%.4f: null-space law failed (%s); safe command sent", t, exc)
            return None
        self.last_law = law
        if not (np.all(np.isfinite(law.tau)) and np.all(np.isfinite(law.qdd))):
            notes.append("law returned non-finite values")
            return None
        return self._decision_vector(law, problem), law.tau.copy()

    def _law(self, problem: _LawProblem) -> LawSolution:
        """Apply the law (:func:`prioritized_torques`) to the law's view of the stack."""
        m = self.model
        return prioritized_torques(
            m.M, m.h, problem.levels,
            S=m.selection() if m.nv_base else None,
            support=problem.support, names=problem.names, eig_tol=self.eig_tol,
            internal_forces="none" if self.internal_forces == "none" else "min-norm",
            method=self.method,
            support_weights=(self._utilization_weights(problem)
                             if self.internal_forces == "balanced" else None),
        )

    def _utilization_weights(
        self, problem: _LawProblem
    ) -> Callable[[np.ndarray], np.ndarray] | None:
        """Weights of the ``"balanced"`` internal forces: least load-weighted utilisation.

        For a surface contact with wrench ``[F; tau]`` (world axes, at its origin), normal
        force ``f_z``, centre-of-pressure box ``hl x hw`` and friction ``mu``, the utilisation
        terms are ``u = tau_x / (hw f_z)``, ``tau_y / (hl f_z)`` (centre of pressure over the
        box), ``tau_z / (min(hl, hw) f_z)`` (yaw) and ``F_x / (mu f_z)``, ``F_y / (mu f_z)``
        (friction). The cost is their load-weighted sum of squares ``sum f_z u^2 / (m g)`` plus
        ``(F_z / m g)^2``; with ``f_z`` of the previous pass fixed it is a weighted
        least-squares cost of the internal forces, whose optimum shares a moment between the
        contacts in proportion to their loads and moves load between them rather than rolling
        every foot onto its edge. (``"min-norm"`` weighs 1 N m of foot torque like 1 N of
        force, so a lateral moment in double support goes into both feet's roll torques while
        the loads stay equal.) Rows of other kinds keep the weight ``1 / (m g)^2``. Returns
        ``None`` when the active contacts do not match the support rows.
        """
        from hqp.layout import ContactType

        if problem.support is None:
            return None
        m = self.model
        surfaces = []  # (start row in the support, hl, hw, mu)
        start = 0
        for name in self.stack.active_contacts:
            task = self.stack.task(name)
            kind = getattr(task, "kind", None)
            size = kind.value if isinstance(kind, ContactType) else 0
            if kind is ContactType.SURFACE:
                surfaces.append((start, float(task.half_length), float(task.half_width),
                                 max(float(task.mu), 1e-3)))
            start += size
        ns = problem.support[0].shape[0]
        if not surfaces or start != ns:
            return None
        weight = m.mass * float(np.linalg.norm(m.gravity_vector))

        def weights(f: np.ndarray) -> np.ndarray:
            w = np.full(ns, 1.0 / weight**2)
            for i, hl, hw, mu in surfaces:
                fz = max(float(f[i + 2]), 0.05 * weight)
                w[i:i + 2] = 1.0 / (mu**2 * fz * weight)
                w[i + 3] = 1.0 / (max(hw, 1e-3) ** 2 * fz * weight)
                w[i + 4] = 1.0 / (max(hl, 1e-3) ** 2 * fz * weight)
                w[i + 5] = 1.0 / (max(min(hl, hw), 1e-3) ** 2 * fz * weight)
            return w

        return weights

    def _constraint_zones(
        self, law: LawSolution, problem: _LawProblem, notes: list[str]
    ) -> tuple[LawSolution, _LawProblem]:
        """Contact and actuation limits as activation zones at the top of the task hierarchy.

        The law has no inequalities; the papers handle a constraint by an activation zone: once
        the motion enters the zone, equality rows hold it at the zone's border at the top of
        the hierarchy (seed 003 eq. 10-12, 25; the joint-limit zones are the seed's example).
        Here the same is done, at one level above the joint-limit zones (the contact and
        actuation limits are above the joint limits, as in the HQP stack), for:

        * the support: the centre of pressure ``z`` of the support wrench that the law's
          accelerations need (:func:`center_of_pressure`) must stay in the hull of the active
          contacts' centre-of-pressure boxes scaled by ``support_zone``
          (:func:`support_polygon`); outside (or when the support would pull), the two rows of
          :func:`support_moment_rows` hold it at the closest point of that zone;
        * the torques: a joint whose torque exceeds ``torque_zone * tau_max`` gets the row
          ``tau_j(qdd) = +-torque_zone * tau_max_j`` (``tau = Phi^+ S (qdd - qdd_0) + tau_int``,
          module docstring; the internal-force part ``tau_int`` is taken from the last pass).

        The law is applied again with these rows, up to ``zone_passes`` times, adding the
        joints that still leave their zone (rows are only added within a step).

        Returns:
            The final law solution and the problem it solved.

        """
        if self.support_zone is None and self.torque_zone is None:
            return law, problem
        m = self.model
        hull = None
        height = 0.0
        if self.support_zone is not None and problem.support is not None:
            contacts = [
                t for t in (self.stack.task(n) for n in self.stack.active_contacts)
                if hasattr(t, "frame")
            ]
            if contacts:
                hull, height = support_polygon(m, contacts, self.support_zone)
        S = m.selection() if m.nv_base else np.eye(m.nv)
        held: set[int] = set()
        rows: list[tuple[np.ndarray, np.ndarray]] = []
        support_held = False
        base = problem
        for _ in range(self.zone_passes):
            new: list[tuple[np.ndarray, np.ndarray]] = []
            if hull is not None and not support_held:
                cop, fz = center_of_pressure(m, law.qdd, height)
                if self.last_cop is None:
                    self.last_cop = cop
                target = None
                if fz > 0.0:  # (a pulling support is beyond what these rows can repair)
                    point, inside = project_to_polygon(cop, hull)
                    if not inside:
                        target = point
                if target is not None:
                    new.append(support_moment_rows(m, np.array([target[0], target[1], height])))
                    support_held = True
                    self.support_active = True
            if self.torque_zone is not None:
                limit = self.torque_zone * m.tau_max
                over = [j for j in np.flatnonzero(np.abs(law.tau) > limit) if j not in held]
                if over:
                    G = law.phi_pinv @ S  # tau_plain = G (qdd - qdd0)
                    for j in over:
                        scale = 1.0 / max(float(m.tau_max[j]), 1e-9)
                        target_j = np.sign(law.tau[j]) * limit[j] - law.tau_internal[j]
                        new.append((scale * G[j:j + 1], scale * np.array(
                            [target_j + float(G[j] @ law.qdd0)])))
                        held.add(int(j))
                    self.torques_held = tuple(sorted(held))
            if not new:
                break
            rows.extend(new)
            J = np.vstack([r[0] for r in rows])
            a = np.concatenate([r[1] for r in rows])
            problem = _LawProblem(
                base.support,
                [(J, a), *base.levels],
                ["constraint_zones", *base.names],
                [0, *base.built_levels],
                {k: (i + 1, Jt, at) for k, (i, Jt, at) in base.task_rows.items()},
                base.skipped,
            )
            law = self._law(problem)
        if support_held:
            notes.append("support zone active: centre of pressure held at its zone's border")
        if held:
            names = ", ".join(m.joint_names[j] for j in sorted(held))
            notes.append(f"torque zone active: {names} held at {self.torque_zone:g} x tau_max")
        return law, problem

    def _feasibility(
        self, built: BuiltStack, x: np.ndarray | None, notes: list[str]
    ) -> tuple[tuple[TaskStatus, ...], tuple[float, ...]]:
        """Statuses from the law's eigenvalues (eq. 22) and level costs at the law's ``x``."""
        law, problem = self.last_law, self.last_problem
        if x is None or law is None or problem is None:
            return (), ()
        statuses = self._law_statuses(built, problem, law, x)
        notes.extend(problem.skipped)
        return statuses, tuple(_level_cost(level, x) for level in built.levels)

    def _decision_vector(self, law: LawSolution, problem: _LawProblem) -> np.ndarray:
        """``x = [qdd | wrenches]`` of the law: support forces mapped to the active slots."""
        from hqp.tasks.dynamics import contact_jacobian

        m = self.model
        x = np.zeros(self.layout.n)
        x[: m.nv] = law.qdd
        if problem.support is None or law.f.size == 0:
            return x
        generalized = problem.support[0].T @ law.f  # J_s^T f, (nv,)
        active = [s for s in self.layout.contacts if s.name in self.stack.active_contacts]
        if not active:
            return x
        JfT = np.hstack([contact_jacobian(m, s).T for s in active])
        w = np.linalg.lstsq(JfT, generalized, rcond=None)[0]
        start = 0
        for s in active:
            x[s.slice] = w[start:start + s.size]
            start += s.size
        return x

    # -- report -----------------------------------------------------------------------------

    def _law_statuses(
        self, built: BuiltStack, problem: _LawProblem, law: LawSolution, x: np.ndarray
    ) -> tuple[TaskStatus, ...]:
        """Per-task feasibility: residuals at ``x``, eigenvalues of ``Lambda^-1`` (eq. 22)."""
        from hqp.controller import Feasibility, TaskStatus

        full = self.diagnostics == "full"
        out = []
        for span in built.spans:
            rows = built.rows[span.name]
            parts = []
            if rows.A is not None:
                parts.append(rows.A @ x - rows.b)
            if rows.C is not None:
                parts.append(_violation(rows.C, rows.lower, rows.upper, x))
            residual = float(np.linalg.norm(np.concatenate(parts))) if parts else 0.0
            eig_min = float("nan")
            singular = False
            entry = problem.task_rows.get(span.name)
            if entry is not None and full:
                k, J, _ = entry
                Jh = J @ law.whiten
                ref = float(np.linalg.norm(Jh, 2)) ** 2
                eig = np.linalg.eigvalsh(law.inverse_inertia(J, k))  # ascending, (m,)
                eig_min = float(max(eig[0], 0.0))
                singular = eig_min < self.singular_tolerance * ref
            elif entry is not None:
                k = entry[0]
                eig_min = law.levels[k].eig_min
            yields_to = None
            if residual > self.tolerance:
                status = Feasibility.CONFLICT
                if entry is not None and full:
                    yields_to = self._law_yields_to(entry, law, problem, built, span.level)
            elif singular:
                status = Feasibility.SINGULAR
            else:
                status = Feasibility.SATISFIED
            out.append(TaskStatus(span.name, span.level, status, residual, yields_to, eig_min))
        return tuple(out)

    def _law_yields_to(
        self,
        entry: tuple[int, np.ndarray, np.ndarray],
        law: LawSolution,
        problem: _LawProblem,
        built: BuiltStack,
        own_level: int,
    ) -> int | None:
        """Highest level whose null space leaves the task's residual above the tolerance.

        The residual reachable from the law's ``qdd`` by torques the levels ``0..j`` leave free
        is ``min_y ||r + J W Z_{j+1} y||`` (whitened bases of eq. 19); the first ``j`` where it
        exceeds the tolerance is the level the task yields to (the physics level when the
        support alone blocks it), its own level when only tasks of its level block it, and
        ``None`` when no torque at all can meet it.
        """
        k, J, a = entry
        if not law.bases:  # method="literal" keeps projectors, not bases
            return None
        r0 = J @ law.qdd - a
        Jh = J @ law.whiten
        scale = max(1.0, float(np.abs(Jh).max(initial=0.0)))

        def reachable(Z: np.ndarray) -> float:
            if Z.shape[1] == 0:
                return float(np.linalg.norm(r0))
            U, sv, _ = np.linalg.svd(Jh @ Z, full_matrices=False)
            U = U[:, sv > 1e-9 * scale]
            return float(np.linalg.norm(r0 - U @ (U.T @ r0)))

        if reachable(law.bases[0]) > self.tolerance:
            if problem.support is not None:
                r_free = np.linalg.lstsq(J, -r0, rcond=None)[0]
                if np.linalg.norm(r0 + J @ r_free) <= self.tolerance:
                    return built.level_index[0]
            return None
        for j in range(k):
            if reachable(law.bases[j + 1]) > self.tolerance:
                return built.level_index[problem.built_levels[j]]
        return own_level


def _violation(
    C: np.ndarray, lower: np.ndarray | None, upper: np.ndarray | None, x: np.ndarray
) -> np.ndarray:
    """Signed distance of ``C x`` outside ``[lower, upper]`` (0 inside)."""
    cx = C @ x
    out = np.zeros_like(cx)
    if upper is not None:
        out = np.where(cx > upper, cx - upper, out)
    if lower is not None:
        out = np.where(cx < lower, cx - lower, out)
    return out


def _level_cost(level: object, x: np.ndarray) -> float:
    """Return ``||A x - b||^2 + ||dist(C x, [lower, upper])||^2`` of a solver level at ``x``."""
    cost = 0.0
    A = getattr(level, "A", None)
    if A is not None:
        cost += float(np.sum((np.asarray(A) @ x - np.asarray(level.b)) ** 2))  # type: ignore[attr-defined]
    C = getattr(level, "C", None)
    if C is not None:
        cost += float(np.sum(_violation(np.asarray(C), level.lower, level.upper, x) ** 2))  # type: ignore[attr-defined]
    return cost


# ------------------------------------------------------------------------------------------------
# Construction by name (the CLI's ``--controller hqp|nullspace``)
# ------------------------------------------------------------------------------------------------

CONTROLLER_NAMES: tuple[str, ...] = ("hqp", "nullspace")
"""Names accepted by :func:`make_standing_controller`."""


def papers_joint_limits(
    stack: Stack, *, zone: float = 0.1, gains: tuple[float, float] = (400.0, 40.0)
) -> None:
    """Replace the stack's viable joint limits by the papers' activation zones (in place).

    Every :class:`~hqp.tasks.joint_limits.JointLimits` task is removed and one
    :class:`~hqp.tasks.joint_limit_zone.JointLimitZone` is placed on the JOINT_LIMITS level
    (the first level with equality rows below the physics, i.e. the top of the task
    hierarchy, seed 003 eq. 12 and 25). The change is made before the first step (no blend).

    Args:
        stack: The stack to change.
        zone: Width of the activation zones [rad].
        gains: ``(kp, kv)`` of the zones' PD law (eq. 27).

    """
    from hqp.tasks.base import Category
    from hqp.tasks.joint_limit_zone import JointLimitZone
    from hqp.tasks.joint_limits import JointLimits

    level = (
        Category.JOINT_LIMITS if Category.JOINT_LIMITS in stack.level_categories else 1
    )
    for task in list(stack.tasks):
        if isinstance(task, JointLimits):
            stack.remove(task.name)
    stack.pop_events()
    stack.add(JointLimitZone(zone=zone, kp=gains[0], kv=gains[1]), level)


def standing_nullspace_controller(
    robot: Robot,
    *,
    dt: float = 0.001,
    backend: str = "proxsuite",
    algorithm: str = "basis",
    diagnostics: str = "full",
    joint_limit_zones: bool = True,
    zone: float = 0.1,
    zone_gains: tuple[float, float] = (400.0, 40.0),
    eig_tol: float = EIG_TOL,
    internal_forces: str = "min-norm",
    support_zone: float | None = None,
    torque_zone: float | None = None,
    **gains: float,
) -> NullSpaceController:
    """Build a :class:`NullSpaceController` holding a humanoid standing on both feet.

    Same arguments as :func:`hqp.controller.standing_controller` (``backend`` and
    ``algorithm`` are accepted and unused) and the same stack
    (:func:`hqp.controller.standing_stack`), except that the viable joint limits, which are
    inequalities, are replaced by the papers' activation zones (:func:`papers_joint_limits`).
    Friction, centre-of-pressure and torque limits stay in the stack: reported, not enforced.

    Args:
        robot: The bundled robot (``hqp.robots.load(name)``).
        dt: Control period [s].
        backend: Unused (call compatibility).
        algorithm: Unused (call compatibility).
        diagnostics: ``"full"`` or ``"residuals"``.
        joint_limit_zones: Use activation zones (``False``: no joint-limit handling at all,
            the case the HQP design is about).
        zone: Width of the activation zones [rad].
        zone_gains: ``(kp, kv)`` of the zones' PD law.
        eig_tol: Relative eigenvalue threshold of eq. 22.
        internal_forces: ``"min-norm"`` or ``"none"``.
        support_zone: Support activation zone (:class:`NullSpaceController`; ``None``: off).
        torque_zone: Torque activation zone (:class:`NullSpaceController`; ``None``: off).
        **gains: Keyword arguments of :func:`hqp.controller.standing_stack`.

    """
    from hqp.controller import standing_stack
    from hqp.tasks.joint_limits import JointLimits

    model = robot.model()
    stack, contacts = standing_stack(robot, model, **gains)
    if joint_limit_zones:
        papers_joint_limits(stack, zone=zone, gains=zone_gains)
    else:
        for task in list(stack.tasks):
            if isinstance(task, JointLimits):
                stack.remove(task.name)
        stack.pop_events()
    return NullSpaceController(model, contacts, stack, dt=dt, diagnostics=diagnostics,
                               eig_tol=eig_tol, internal_forces=internal_forces,
                               support_zone=support_zone, torque_zone=torque_zone)


def make_standing_controller(kind: str, robot: Robot, **kwargs: object) -> Controller:
    """Build the standing controller ``kind`` (``"hqp"`` or ``"nullspace"``) by name.

    Args:
        kind: One of :data:`CONTROLLER_NAMES`.
        robot: The bundled robot.
        **kwargs: Arguments of :func:`hqp.controller.standing_controller` (both) and of
            :func:`standing_nullspace_controller` (``"nullspace"`` only).

    Raises:
        UnknownName: Another name (lists the valid ones).

    """
    from hqp.errors import UnknownName

    if kind == "hqp":
        from hqp.controller import standing_controller

        return standing_controller(robot, **kwargs)  # type: ignore[arg-type]
    if kind == "nullspace":
        return standing_nullspace_controller(robot, **kwargs)  # type: ignore[arg-type]
    raise UnknownName("controller", kind, CONTROLLER_NAMES)
