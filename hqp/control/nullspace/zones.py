"""Contact and actuation limits as the papers' activation zones (seed 003 eq. 10-12, 25).

The law has no inequalities. Once the motion enters a zone, equality rows that hold it at the
zone's border become the top task level and the law is applied again: the centre of pressure
of the support inside a shrunk support polygon (:func:`support_moment_rows`), each joint's
torque inside a fraction of its limit. Off by default (the plain law); measured effects on
hand-reach in docs/design/nullspace.md.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from hqp.control.nullspace.law import LawSolution
from hqp.control.nullspace.multicontact import LawProblem
from hqp.model.geometry import monotone_chain
from hqp.model.layout import ContactType

if TYPE_CHECKING:
    from hqp.model import RobotModel
    from hqp.tasks.contact import Contact


SUPPORT_ZONE = 0.8
"""Default fraction of each contact's centre-of-pressure box (``half_length`` x ``half_width``)
inside which the law's centre of pressure may move freely (:class:`NullSpaceController`)."""

TORQUE_ZONE = 0.95
"""Default fraction of the torque limits beyond which a joint's torque is held at the zone's
border (:class:`NullSpaceController`)."""


def support_polygon(
    model: RobotModel, contacts: Sequence[Contact], scale: float
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
    pts = []
    for c in contacts:
        T = model.frame_placement(c.frame)
        p, R = T.translation, T.rotation
        if c.kind is ContactType.SURFACE:
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
    return monotone_chain(sorted({(float(x), float(y)) for x, y in points}))


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


@dataclass(frozen=True)
class ZoneSettings:
    """Which activation zones the law applies.

    Attributes:
        support: Fraction of each contact's centre-of-pressure box that bounds the support's
            centre of pressure (``None``: off).
        torque: Fraction of the torque limits that bounds each joint's torque (``None``: off).
        passes: Largest number of re-applications of the law per step.

    """

    support: float | None = None
    torque: float | None = None
    passes: int = 4


@dataclass
class ZoneState:
    """What the zones did at the last step.

    Attributes:
        cop: Centre of pressure ``(2,)`` [m] the plain law asked for (``None`` without support
            or without a support zone).
        support_active: The support zone held the centre of pressure.
        torques_held: Actuated joints whose torque was held at its zone's border.

    """

    cop: np.ndarray | None = None
    support_active: bool = False
    torques_held: tuple[int, ...] = ()


def constraint_zones(
    law: LawSolution,
    problem: LawProblem,
    model: RobotModel,
    contacts: Sequence[Contact],
    zones: ZoneSettings,
    state: ZoneState,
    apply_law: Callable[[LawProblem], LawSolution],
    notes: list[str],
) -> tuple[LawSolution, LawProblem]:
    """Contact and actuation limits as activation zones at the top of the task hierarchy.

    The law has no inequalities; the papers handle a constraint by an activation zone: once
    the motion enters the zone, equality rows hold it at the zone's border at the top of
    the hierarchy (seed 003 eq. 10-12, 25; the joint-limit zones are the seed's example).
    Here the same is done, at one level above the joint-limit zones (the contact and
    actuation limits are above the joint limits, as in the HQP stack), for:

    * the support: the centre of pressure ``z`` of the support wrench that the law's
      accelerations need (:func:`center_of_pressure`) must stay in the hull of the active
      contacts' centre-of-pressure boxes scaled by ``zones.support``
      (:func:`support_polygon`); outside (or when the support would pull), the two rows of
      :func:`support_moment_rows` hold it at the closest point of that zone;
    * the torques: a joint whose torque exceeds ``zones.torque * tau_max`` gets the row
      ``tau_j(qdd) = +-zones.torque * tau_max_j`` (``tau = Phi^+ S (qdd - qdd_0) + tau_int``,
      docs/design/nullspace.md; the internal-force part ``tau_int`` is taken from the last pass).

    The law is applied again with these rows, up to ``zones.passes`` times, adding the
    joints that still leave their zone (rows are only added within a step).

    Returns:
        The final law solution and the problem it solved.

    """
    if zones.support is None and zones.torque is None:
        return law, problem
    m = model
    hull = None
    height = 0.0
    if zones.support is not None and problem.support is not None and contacts:
        hull, height = support_polygon(m, contacts, zones.support)
    S = m.selection() if m.nv_base else np.eye(m.nv)
    held: set[int] = set()
    rows: list[tuple[np.ndarray, np.ndarray]] = []
    support_held = False
    base = problem
    for _ in range(zones.passes):
        new: list[tuple[np.ndarray, np.ndarray]] = []
        if hull is not None and not support_held:
            support = _support_rows(m, law, hull, height, state)
            if support is not None:
                new.append(support)
                support_held = True
                state.support_active = True
        if zones.torque is not None:
            torque = _torque_rows(m, law, zones.torque * m.tau_max, held, S)
            if torque:
                new.extend(torque)
                state.torques_held = tuple(sorted(held))
        if not new:
            break
        rows.extend(new)
        J = np.vstack([r[0] for r in rows])
        a = np.concatenate([r[1] for r in rows])
        problem = LawProblem(
            base.support,
            [(J, a), *base.levels],
            ["constraint_zones", *base.names],
            [0, *base.built_levels],
            {k: (i + 1, Jt, at) for k, (i, Jt, at) in base.task_rows.items()},
            base.skipped,
        )
        law = apply_law(problem)
    if support_held:
        notes.append("support zone active: centre of pressure held at its zone's border")
    if held:
        names = ", ".join(m.joint_names[j] for j in sorted(held))
        notes.append(f"torque zone active: {names} held at {zones.torque:g} x tau_max")
    return law, problem


def _support_rows(model: RobotModel, law: LawSolution, hull: np.ndarray, height: float,
                  state: ZoneState) -> tuple[np.ndarray, np.ndarray] | None:
    """Rows holding the law's centre of pressure at the zone's border, ``None`` when inside."""
    cop, fz = center_of_pressure(model, law.qdd, height)
    if state.cop is None:
        state.cop = cop
    if not fz > 0.0:  # a pulling support is beyond what these rows can repair
        return None
    point, inside = project_to_polygon(cop, hull)
    if inside:
        return None
    return support_moment_rows(model, np.array([point[0], point[1], height]))


def _torque_rows(model: RobotModel, law: LawSolution, limit: np.ndarray, held: set[int],
                 S: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
    """Rows ``tau_j(qdd) = +-limit_j`` of the joints newly past their zone (added to ``held``)."""
    over = [j for j in np.flatnonzero(np.abs(law.tau) > limit) if j not in held]
    rows: list[tuple[np.ndarray, np.ndarray]] = []
    if not over:
        return rows
    G = law.phi_pinv @ S  # tau_plain = G (qdd - qdd0)
    for j in over:
        scale = 1.0 / max(float(model.tau_max[j]), 1e-9)
        target_j = np.sign(law.tau[j]) * limit[j] - law.tau_internal[j]
        rows.append((scale * G[j:j + 1], scale * np.array([target_j + float(G[j] @ law.qdd0)])))
        held.add(int(j))
    return rows
