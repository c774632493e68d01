r"""The law on a standing robot: a built stack as the law's matrices, and back (Sentis 2010).

Support-consistent dynamics: with ``N_s = I - Jbar_s J_s`` the support's null space,
``Phi = (S N_s) M^-1 (S N_s)^T`` ``(na, na)`` plays the role of ``M^-1`` and the task Jacobians
become ``J* = J M^-1 N_s^T S^T Phi^+`` (docs/design/nullspace.md). Here: which rows of a
:class:`~hqp.stack.BuiltStack` the law uses (:func:`law_problem`), the HQP tie-break that
reproduces the law (:func:`floating_base_metric`), the load-weighted internal forces
(:func:`utilization_weights`) and the law's decision vector ``x = [qdd | f]``
(:func:`decision_vector`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from hqp.control.nullspace.law import PHI_TOL, LawSolution
from hqp.model.layout import ContactType
from hqp.tasks.base import Category
from hqp.tasks.dynamics import contact_jacobian

if TYPE_CHECKING:
    from hqp.model import RobotModel
    from hqp.model.layout import Layout
    from hqp.stack import BuiltStack, Stack


def floating_base_metric(
    solution: LawSolution, T: np.ndarray, t0: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """HQP final metric and target that reproduce the law's ``qdd``, ``f`` and ``tau``.

    With the HQP torque map ``tau = T x + t0`` (:func:`hqp.tasks.dynamics.torque_map`) and
    ``W = Phi + P_null(Phi)``, returns ``Q = T^T W T`` and ``x_t = -Q^+ T^T W t0``, so that
    ``(x - x_t)^T Q (x - x_t) = tau^T W tau + const`` (docs/design/nullspace.md, statement 3). On a
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


@dataclass(frozen=True)
class LawProblem:
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


def law_problem(built: BuiltStack, stack: Stack, nv: int) -> LawProblem:
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
    by_level: dict[int, list] = {}
    for span in built.spans:
        by_level.setdefault(span.built_level, []).append(span)
    support_J: list[np.ndarray] = []
    support_b: list[np.ndarray] = []
    levels: list[tuple[np.ndarray, np.ndarray]] = []
    names: list[str] = []
    built_levels: list[int] = []
    task_rows: dict[str, tuple[int, np.ndarray, np.ndarray]] = {}
    skipped: list[str] = []
    for k, level in enumerate(built.levels):
        index = built.level_index[k]
        physics = (
            stack.level_categories[index] is Category.PHYSICS
            or stack.level_names[index] == "physics"
        )
        J_rows: list[np.ndarray] = []
        a_rows: list[np.ndarray] = []
        for span in by_level.get(k, []):
            rows = built.rows[span.name]
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
    return LawProblem(support, levels, names, built_levels, task_rows, tuple(skipped))


def utilization_weights(
    model: RobotModel, stack: Stack, problem: LawProblem
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
    if problem.support is None:
        return None
    m = model
    surfaces = []  # (start row in the support, hl, hw, mu)
    start = 0
    for name in stack.active_contacts:
        task = stack.task(name)
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


def decision_vector(model: RobotModel, layout: Layout, stack: Stack, law: LawSolution,
                    problem: LawProblem) -> np.ndarray:
    """``x = [qdd | wrenches]`` ``(n,)`` of the law: support forces mapped to the active slots."""
    m = model
    x = np.zeros(layout.n)
    x[: m.nv] = law.qdd
    if problem.support is None or law.f.size == 0:
        return x
    generalized = problem.support[0].T @ law.f  # J_s^T f, (nv,)
    active = [s for s in layout.contacts if s.name in stack.active_contacts]
    if not active:
        return x
    JfT = np.hstack([contact_jacobian(m, s).T for s in active])
    w = np.linalg.lstsq(JfT, generalized, rcond=None)[0]
    start = 0
    for s in active:
        x[s.slice] = w[start:start + s.size]
        start += s.size
    return x
