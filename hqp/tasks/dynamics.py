"""Floating-base dynamics: the unactuated rows of the equation of motion.

The equation of motion over the decision vector ``x = [qdd | f_1 | ... | f_k]``
(:mod:`hqp.model.layout`) is

    M qdd + h = S^T tau + sum_c J_c^T f_c,

with ``J_c`` the ``LOCAL_WORLD_ALIGNED`` frame Jacobian of contact ``c`` (its
6 rows for a surface contact, its first 3 rows for a point contact) and ``S``
the actuation selection (:meth:`RobotModel.selection`). Its first 6 rows (the
free flyer's, where ``S^T tau`` is zero) do not involve the torques; they are
the physics rows of the hierarchy paper's floating base (eq. 1-3 of seed 003
with the contact forces as decision variables):

    M_u qdd - sum_c J_{c,u}^T f_c = -h_u        (6 rows)

The remaining rows give the torques, an affine function of ``x``:

    tau = S (M qdd + h - sum_c J_c^T f_c) = T x + t0.

A fixed-base robot has no unactuated rows (:class:`FloatingBaseDynamics`
returns no rows) but :func:`torque_map` still applies.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from hqp.errors import InvalidInput
from hqp.model.layout import ContactType
from hqp.tasks.base import Category, Rows, Task

if TYPE_CHECKING:
    from hqp.model import RobotModel
    from hqp.model.layout import ContactSlot, Layout


def contact_jacobian(model: RobotModel, slot: ContactSlot, where: str = "") -> np.ndarray:
    """Jacobian whose transpose maps a contact slot's wrench to generalized forces.

    Args:
        model: Updated robot model.
        slot: The contact slot (surface: wrench ``[force, torque]`` at the frame
            origin, world axes; point: force, world axes).
        where: Prefix of error messages (e.g. the primitive's name).

    Returns:
        ``J_c`` ``(6, nv)`` (surface) or ``(3, nv)`` (point): rows of the
        ``LOCAL_WORLD_ALIGNED`` frame Jacobian.

    Raises:
        InvalidFrame: The slot's frame is not in the model.

    """
    if where:
        model.frame_id(slot.frame, where)
    J = model.frame_jacobian(slot.frame)
    return J if slot.kind is ContactType.SURFACE else J[:3]


def _check_layout(model: RobotModel, layout: Layout, where: str) -> None:
    if layout.nv != model.nv:
        raise InvalidInput(f"{where}: layout has nv={layout.nv}, robot has nv={model.nv}")


def _contact_columns(
    model: RobotModel, layout: Layout, out: np.ndarray, rows: slice, where: str
) -> None:
    """Write ``-J_c[:, rows]^T`` of every contact slot into its columns of ``out`` ``(r, n)``.

    ``J_c`` is the slot's frame Jacobian (:func:`contact_jacobian`), read once per update from
    the model's cache; the other columns of ``out`` are left as they are.
    """
    for slot in layout.contacts:
        if where:
            model.frame_id(slot.frame, where)
        k = slot.kind.value
        out[:, slot.start : slot.start + k] = -model.frame_jacobian(slot.frame)[:k, rows].T


def generalized_contact_matrix(model: RobotModel, layout: Layout, where: str = "") -> np.ndarray:
    """``[J_1^T | ... | J_k^T]`` ``(nv, n - nv)``: generalized force of the contact slots.

    Raises:
        InvalidFrame: A slot's frame is not in the model.
        InvalidInput: The layout does not match the robot.

    """
    _check_layout(model, layout, where or "generalized_contact_matrix")
    JT = np.zeros((model.nv, layout.n - layout.nv))
    for slot in layout.contacts:
        cols = slice(slot.start - layout.nv, slot.start - layout.nv + slot.size)
        JT[:, cols] = contact_jacobian(model, slot, where).T
    return JT


def contact_dynamics_matrix(model: RobotModel, layout: Layout, where: str = "") -> np.ndarray:
    """``[M | -J_1^T ... -J_k^T]`` ``(nv, n)``: the equation of motion's map of ``x``.

    ``M qdd - sum_c J_c^T f_c = S^T tau - h``; its first ``nv_base`` rows are the
    :class:`FloatingBaseDynamics` rows, the others the :func:`torque_map`. Computed once per
    update and layout (:meth:`RobotModel.per_update`), shared by the tasks of the step: read
    only.

    Raises:
        InvalidFrame: A contact frame is not in the model.
        InvalidInput: The layout does not match the robot.

    """
    _check_layout(model, layout, where or "contact_dynamics_matrix")
    key = ("contact_dynamics_matrix", id(layout))
    hit = model.per_update(key, lambda: _contact_dynamics(model, layout, where))
    if hit[0] is not layout:  # an id reused by another layout: recompute
        hit = _contact_dynamics(model, layout, where)
    return hit[1]


def _contact_dynamics(
    model: RobotModel, layout: Layout, where: str
) -> tuple[Layout, np.ndarray]:
    nv = layout.nv
    blocks = [model.M]
    start = nv
    for slot in layout.contacts:
        if slot.start != start:  # slots not back to back (a hand-made layout): fill in place
            blocks = []
            break
        if where:
            model.frame_id(slot.frame, where)
        k = slot.size
        blocks.append(-model.frame_jacobian(slot.frame)[:k].T)
        start += k
    if blocks and start == layout.n:
        G = np.concatenate(blocks, axis=1)
    else:
        G = np.zeros((nv, layout.n))
        G[:, :nv] = model.M
        _contact_columns(model, layout, G, slice(None), where)
    G.flags.writeable = False
    return layout, G


def torque_map(model: RobotModel, layout: Layout, where: str = "") -> tuple[np.ndarray, np.ndarray]:
    """Actuated torques as an affine map of ``x``: ``tau = T x + t0``.

    ``tau = S (M qdd + h - sum_c J_c^T f_c)``, so ``T = S [M | -J_1^T ... -J_k^T]``
    ``(na, n)`` and ``t0 = S h`` ``(na,)`` [N m].

    Args:
        model: Updated robot model.
        layout: Decision-variable layout.
        where: Prefix of error messages.

    Returns:
        ``(T, t0)`` (new arrays).

    Raises:
        InvalidFrame: A contact frame is not in the model.
        InvalidInput: The layout does not match the robot.

    """
    act = model.actuated
    return contact_dynamics_matrix(model, layout, where)[act].copy(), model.h[act].copy()


def joint_torques(model: RobotModel, layout: Layout, x: np.ndarray) -> np.ndarray:
    """Actuated joint torques of a solution: ``tau = S (M qdd + h - sum_c J_c^T f_c)``.

    Args:
        model: Robot model updated at the state the solution was computed for.
        layout: Decision-variable layout.
        x: Solution ``(n,)`` ``[qdd | f_1 | ... | f_k]``.

    Returns:
        ``tau`` ``(na,)`` [N m] (actuated joints, velocity order).

    Raises:
        InvalidInput: ``x`` of the wrong shape or not finite.

    """
    from hqp.errors import check_array

    x = check_array(x, (layout.n,), "joint_torques: x")
    act = model.actuated
    # [M | -J_c^T] of the step, usually already built by the dynamics and torque-limit rows.
    return contact_dynamics_matrix(model, layout)[act].dot(x) + model.h[act]


class FloatingBaseDynamics(Task):
    """Physics rows: the 6 unactuated rows of the equation of motion (equalities).

    ``[M_u | -J_{1,u}^T ... -J_{k,u}^T] x = -h_u`` where ``u`` are the free-flyer
    rows; every contact slot of the layout enters (an inactive contact's slot
    is held at zero by its :class:`~hqp.tasks.contact.Contact` rows). Returns
    no rows on a fixed-base robot.

    Args:
        name: Task name.
        weight: Weight within its level (the rows are exact physics; keep 1).

    """

    category = Category.PHYSICS

    def __init__(self, name: str = "dynamics", weight: float = 1.0) -> None:
        super().__init__(name, weight)

    def rows(self, model: RobotModel, layout: Layout, dt: float, t: float) -> Rows:
        """Return the unactuated rows ``(6, n)`` (none on a fixed base).

        Raises:
            InvalidFrame: A contact frame of the layout is not in the model.
            InvalidInput: The layout does not match the robot.

        """
        nb = model.nv_base
        if nb == 0:
            _check_layout(model, layout, self.where())
            return Rows()
        G = contact_dynamics_matrix(model, layout, self.where())
        return Rows(A=G[:nb].copy(), b=-model.h[:nb])

    def torques(self, model: RobotModel, layout: Layout, x: np.ndarray) -> np.ndarray:
        """Actuated torques of a solution (see :func:`joint_torques`)."""
        return joint_torques(model, layout, x)
