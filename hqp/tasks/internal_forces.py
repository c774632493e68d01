"""Internal forces between two contacts (the feet): the wrenches that cancel out."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from hqp.errors import InvalidInput, check_array
from hqp.model.geometry import cross3
from hqp.tasks.base import Category, Rows, Task

if TYPE_CHECKING:
    from hqp.model import RobotModel
    from hqp.model.layout import ContactSlot, Layout

COMPONENTS = (
    "tension",
    "shear_horizontal",
    "shear_vertical",
    "moment_line",
    "moment_horizontal",
    "moment_vertical",
)
"""Names of the internal-force coordinates of two surface contacts (point contacts: tension)."""


def line_frame(p1: np.ndarray, p2: np.ndarray, where: str) -> tuple[np.ndarray, ...]:
    """Return the unit line ``d`` from 1 to 2, horizontal normal ``s_h``, ``d x s_h``, length.

    Raises:
        InvalidInput: The two contact origins coincide.

    """
    diff = p2 - p1
    L = float(np.linalg.norm(diff))
    if L < 1e-9:
        raise InvalidInput(f"{where}: the two contact frames coincide")
    d = diff / L
    sh = cross3([0.0, 0.0, 1.0], d)
    if np.linalg.norm(sh) < 1e-6:  # vertical line
        sh = cross3([1.0, 0.0, 0.0], d)
    sh /= np.linalg.norm(sh)
    return d, sh, cross3(d, sh), np.array(L)


def internal_basis(p1: np.ndarray, p2: np.ndarray, surface: bool, where: str) -> np.ndarray:
    """Basis ``B`` of the internal wrenches of two contacts, columns in :data:`COMPONENTS` order.

    A pair of contact wrenches ``w = [w_1; w_2]`` (each ``[force; torque]`` at
    its contact origin, world axes) is internal when it has zero net force and
    zero net moment (it lies in the null space of the grasp map ``G``, which
    sums the wrenches at a common point). For two surface contacts this null
    space has dimension 6 (12 - 6), spanned by

    * ``tension``: ``F_1 = -d``, ``F_2 = d`` (``d``: unit line from 1 to 2;
      positive: the contact forces push the feet apart);
    * ``shear_horizontal`` / ``shear_vertical``: ``F_1 = -s``, ``F_2 = s`` for
      ``s`` horizontal and normal to the line / ``s = d x s_h``, balanced by
      equal torques ``tau_1 = tau_2 = -(L/2) d x s``;
    * ``moment_line`` / ``moment_horizontal`` / ``moment_vertical``:
      ``tau_1 = -e``, ``tau_2 = e`` for ``e = d, s_h, s_v``.

    For two point contacts (6 - 5 = 1) only ``tension`` exists.

    Returns:
        ``B`` ``(12, 6)`` (surface) or ``(6, 1)`` (point).

    """
    d, sh, sv, L = line_frame(p1, p2, where)
    if not surface:
        return np.concatenate([-d, d])[:, None]
    B = np.zeros((12, 6))
    B[0:3, 0], B[6:9, 0] = -d, d
    for k, s in ((1, sh), (2, sv)):
        tau = -0.5 * float(L) * cross3(d, s)
        B[0:3, k], B[3:6, k] = -s, tau
        B[6:9, k], B[9:12, k] = s, tau
    for k, e in ((3, d), (4, sh), (5, sv)):
        B[3:6, k], B[9:12, k] = -e, e
    return B


class InternalForcesTask(Task):
    """Internal forces between two contacts (the feet), driven to zero or a set value.

    Coordinates ``c = B^+ [w_1; w_2]`` on the basis ``B`` of
    :func:`internal_basis`: since ``B`` spans the null space of the grasp map,
    ``B c`` is the orthogonal projection of the wrench pair onto the internal
    wrenches (Euclidean metric on ``[N, N m]``, i.e. the non-internal part is
    the minimum-norm distribution of the net wrench). Rows over the two wrench
    slots ``S B^+ [w_1; w_2] = c_goal`` (``S``: the selected components).
    The columns of ``B`` are mutually orthogonal, so the coordinates do not
    mix. Seed 001 controls internal forces "to vanish"; but a pure shift of
    weight from one foot to the other (different normal forces, no torques)
    projects onto ``shear_vertical`` only, so zeroing it would dictate how the
    weight is shared (almost all through equal ankle torques, the minimum-norm
    share). By default every component except ``shear_vertical`` is
    controlled: the forces and moments that squeeze, scissor or twist the
    support without carrying the body.

    Args:
        robot: Robot model (for a uniform constructor; frames are checked at run time).
        contacts: Names of the two contacts in the layout (same kind).
        components: Selected coordinates (names of :data:`COMPONENTS`;
            default all but ``shear_vertical`` for surface contacts, ``("tension",)`` for
            point contacts).
        name: Task name.
        weight: Weight within its level.

    Goal: :meth:`set_goal` with ``(k,)`` [N or N m] (default zero).

    Raises:
        InvalidInput: Not two distinct contacts, or unknown components.

    """

    category = Category.OPERATIONAL
    DEFAULT_SURFACE = (
        "tension",
        "shear_horizontal",
        "moment_line",
        "moment_horizontal",
        "moment_vertical",
    )

    def __init__(
        self,
        robot: RobotModel,
        contacts: Sequence[str],
        components: Sequence[str] | None = None,
        *,
        name: str = "internal_forces",
        weight: float = 1.0,
    ) -> None:
        super().__init__(name, weight)
        w = self.where()
        if isinstance(contacts, str) or len(contacts) != 2 or contacts[0] == contacts[1]:
            raise InvalidInput(f"{w}: contacts must be two distinct contact names")
        self.contacts = (str(contacts[0]), str(contacts[1]))
        if components is not None:
            comps = tuple(str(c) for c in components)
            bad = [c for c in comps if c not in COMPONENTS]
            if bad or not comps or len(set(comps)) != len(comps):
                raise InvalidInput(
                    f"{w}: components {list(comps)} must be distinct names among "
                    f"{', '.join(COMPONENTS)}"
                )
        else:
            comps = None
        self._components = comps
        self._goal: np.ndarray | None = None
        self._last: np.ndarray | None = None

    def components(self, layout: Layout) -> tuple[str, ...]:
        """Return the selected components for the layout's contact kinds.

        Raises:
            InvalidInput: Unknown contacts, mixed kinds, or components a point pair lacks.

        """
        s1, s2 = self._slots(layout)
        surface = s1.size == 6
        if self._components is None:
            return self.DEFAULT_SURFACE if surface else ("tension",)
        if not surface and self._components != ("tension",):
            raise InvalidInput(f"{self.where()}: two point contacts only have 'tension'")
        return self._components

    def _slots(self, layout: Layout) -> tuple[ContactSlot, ContactSlot]:
        try:
            s1, s2 = layout.contact(self.contacts[0]), layout.contact(self.contacts[1])
        except InvalidInput as exc:
            raise InvalidInput(f"{self.where()}: {exc}") from None
        if s1.kind is not s2.kind:
            raise InvalidInput(f"{self.where()}: the two contacts must be of the same kind")
        return s1, s2

    def set_goal(self, values: object) -> None:
        """Set the goal of the selected components ``(k,)`` (copied; default zero).

        The size is checked against the selection at the next :meth:`rows`.

        Raises:
            InvalidInput: Not a 1-D finite array.

        """
        self._goal = check_array(values, (None,), f"{self.where()}: goal")

    def goal_of(self, k: int) -> np.ndarray:
        """Return the goal ``(k,)`` of ``k`` selected components (zero when none was set).

        Raises:
            InvalidInput: A goal of another size.

        """
        goal = np.zeros(k) if self._goal is None else self._goal
        if goal.shape != (k,):
            raise InvalidInput(f"{self.where()}: goal has {goal.shape[0]} entries, {k} components")
        return goal

    def coordinates(self, model: RobotModel, layout: Layout) -> np.ndarray:
        """Map ``K`` ``(k, n)``: selected internal coordinates ``c = K x``.

        Raises:
            InvalidInput: Bad contacts or components.
            InvalidFrame: A contact frame not in the model.

        """
        s1, s2 = self._slots(layout)
        comps = self.components(layout)
        p1 = model.data.oMf[model.frame_id(s1.frame, self.where())].translation
        p2 = model.data.oMf[model.frame_id(s2.frame, self.where())].translation
        B = internal_basis(p1, p2, s1.size == 6, self.where())
        Bp = np.linalg.pinv(B)
        names = COMPONENTS if s1.size == 6 else ("tension",)
        rows = Bp[[names.index(c) for c in comps]]
        K = np.zeros((len(comps), layout.n))
        K[:, s1.slice] = rows[:, : s1.size]
        K[:, s2.slice] = rows[:, s1.size :]
        return K

    def rows(self, model: RobotModel, layout: Layout, dt: float, t: float) -> Rows:
        """Equality rows ``K x = c_goal`` ``(k, n)``.

        Raises:
            InvalidInput: Bad contacts, components, or a goal of the wrong size.

        """
        K = self.coordinates(model, layout)
        goal = self.goal_of(K.shape[0])
        self._last_goal = goal
        return Rows(A=K, b=goal.copy())

    def measure(self, model: RobotModel, layout: Layout, x: object) -> np.ndarray:
        """Return the internal coordinates ``(k,)`` of a solution ``x`` (kept for :meth:`error`)."""
        xv = check_array(x, (layout.n,), f"{self.where()}: x")
        self._last = self.coordinates(model, layout) @ xv
        return self._last

    def error(self) -> np.ndarray:
        """``c_goal - c`` for the last :meth:`measure` (empty before)."""
        if self._last is None:
            return np.zeros(0)
        goal = np.zeros_like(self._last) if self._goal is None else self._goal
        return goal - self._last
