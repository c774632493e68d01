"""What every control primitive shares: its rows, its category, its interface.

A primitive (task) is a pure map from the updated robot state to rows over
the decision variables ``x = [qdd | contact wrenches]`` (see
:mod:`hqp.model.layout`): equality rows ``A x = b`` and/or inequality rows
``lower <= C x <= upper``. It holds its goal and gains, nothing else: no
solver handle and no cache keyed on the configuration.
"""

from __future__ import annotations

import abc
import enum
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from hqp.errors import InvalidInput

if TYPE_CHECKING:
    from hqp.model import RobotModel
    from hqp.model.layout import Layout


class Category(enum.IntEnum):
    """Default priority categories, highest first (docs/concepts/levels.md, seed Figure 9).

    The first four are the constraint sub-levels; a category is a default
    level, not a cage: any task may be placed at any level of a stack.
    """

    PHYSICS = 0
    """Floating-base dynamics, active contacts, inactive contact slots at zero."""
    CONTACT_LIMITS = 1
    """Friction pyramids, unilateral forces, centre of pressure, torque limits."""
    JOINT_LIMITS = 2
    """Viable joint position and velocity limits."""
    COLLISION = 3
    """Obstacle and self-collision distances."""
    BALANCE = 4
    """Centre of gravity, ZMP / centre of pressure, centroidal momentum."""
    OPERATIONAL = 5
    """Frame position, orientation, pose, gaze, hybrid force/position, internal forces."""
    POSTURE = 6
    """Imitate a captured pose, minimise effort."""


@dataclass(frozen=True)
class Rows:
    """Rows of one task over the decision vector ``x`` of size ``n``.

    Attributes:
        A: Equality matrix ``(m_eq, n)`` or ``None``.
        b: Equality target ``(m_eq,)`` or ``None``.
        C: Inequality matrix ``(m_in, n)`` or ``None``.
        lower: Inequality lower bounds ``(m_in,)`` (may hold ``-inf``) or ``None``.
        upper: Inequality upper bounds ``(m_in,)`` (may hold ``+inf``) or ``None``.

    """

    A: np.ndarray | None = None
    b: np.ndarray | None = None
    C: np.ndarray | None = None
    lower: np.ndarray | None = None
    upper: np.ndarray | None = None

    @property
    def n_eq(self) -> int:
        """Number of equality rows."""
        return 0 if self.A is None else self.A.shape[0]

    @property
    def n_in(self) -> int:
        """Number of inequality rows."""
        return 0 if self.C is None else self.C.shape[0]

    def scaled(self, factor: float) -> Rows:
        """Rows multiplied by ``factor`` (a task's weight enters as its square root)."""
        if factor == 1.0:
            return self
        return Rows(
            None if self.A is None else factor * self.A,
            None if self.b is None else factor * self.b,
            None if self.C is None else factor * self.C,
            None if self.lower is None else factor * self.lower,
            None if self.upper is None else factor * self.upper,
        )

    @staticmethod
    def stack(parts: list[Rows], n: int) -> Rows:
        """Stack the rows of several tasks (same ``n``) into one ``Rows``."""
        eq = [p for p in parts if p.A is not None and p.A.shape[0]]
        ineq = [p for p in parts if p.C is not None and p.C.shape[0]]
        for p in eq:
            if p.A.shape[-1] != n:  # type: ignore[union-attr]
                raise InvalidInput(f"Rows.stack: rows do not have {n} columns")
        for p in ineq:
            if p.C.shape[-1] != n:  # type: ignore[union-attr]
                raise InvalidInput(f"Rows.stack: rows do not have {n} columns")
        A = _vstack([p.A for p in eq]) if eq else None  # type: ignore[misc]
        b = np.concatenate([p.b for p in eq]) if eq else None  # type: ignore[misc]
        if ineq:
            C = _vstack([p.C for p in ineq])  # type: ignore[misc]
            lower = np.concatenate(
                [p.lower if p.lower is not None else np.full(p.C.shape[0], -np.inf)  # type: ignore[union-attr]
                 for p in ineq]
            )
            upper = np.concatenate(
                [p.upper if p.upper is not None else np.full(p.C.shape[0], np.inf)  # type: ignore[union-attr]
                 for p in ineq]
            )
        else:
            C = lower = upper = None
        return Rows(A, b, C, lower, upper)


def _vstack(mats: list[np.ndarray]) -> np.ndarray:
    """``np.vstack`` (a new array), by one ``np.concatenate`` when every part is 2-D."""
    for m in mats:
        if m.ndim != 2:
            return np.vstack(mats)
    return np.concatenate(mats)


class Edits:
    """A count of the edits to what a controller's native step copies when it is built.

    Every attribute assignment on a :class:`Tracked` object (a task, its PD reference, a
    stack's entries) and every change of a stack's structure or of a world's obstacles adds
    one. A controller compares the count with the one of its last step: equal, nothing it
    copied into the core can have changed (goals excepted: they are pushed when they are new
    samples) and the step skips every check; different, it checks again what the core
    holds (``hqp.control.native``). A task's parameters change by assignment
    (``task.weight = 2.0``, ``task.tau_max = limits``, ``task.set_gains(...)``): the arrays
    they hold are read-only (:class:`Tracked`).
    """

    count = 0


def edited() -> None:
    """Count one edit (:class:`Edits`), for changes that are not attribute assignments."""
    Edits.count += 1


class Tracked:
    """An object whose attribute assignments are edits (:class:`Edits`).

    Names in ``_untracked`` are not: what a step itself records on the object (errors, the
    rows of its last step), so that a running loop leaves the count still. An array assigned
    to a public attribute (a parameter: ``tau_max``, ``qdd_max``, gains) is kept as a
    read-only copy, so that an edit in place, which no count would see, is an error
    (NumPy's ``ValueError``: the destination is read-only) rather than lost; ``task.tau_max
    = task.tau_max * 0.7`` is an edit.
    """

    _untracked: frozenset[str] = frozenset()

    def __setattr__(self, name: str, value: Any) -> None:
        if name not in self._untracked:
            if type(value) is np.ndarray and name[0] != "_":
                value = value.copy()
                value.flags.writeable = False
            Edits.count += 1
        object.__setattr__(self, name, value)


class Task(Tracked, abc.ABC):
    """A control primitive: robot state -> rows over ``x = [qdd | wrenches]``.

    Args:
        name: Name of the task, unique in a stack (used in reports and errors).
        weight: Weight within its level (its rows are scaled by ``sqrt(weight)``).

    Raises:
        InvalidGain: Negative or non-finite weight.

    """

    category: Category = Category.OPERATIONAL
    """Default category (level) of the primitive."""

    _untracked = frozenset({
        # goals: pushed to the core when they are new samples, not by the edit count
        "_goal", "_trajectory", "_trusted",
        # what a step records: the errors and rows of the last step
        "_error_source", "_error_serial", "_recorded", "_last", "_last_reference", "_error",
        "_violation", "_margins", "pair_names",
    })

    contact_aware: bool = False
    """Whether the stack calls ``set_active_contacts(frames)`` before every :meth:`rows`."""

    def __init__(self, name: str, weight: float = 1.0) -> None:
        from hqp.errors import InvalidGain

        if not np.isfinite(weight) or weight <= 0.0:
            raise InvalidGain(
                f"{type(self).__name__} {name!r}: weight must be positive, got {weight}"
            )
        self.name = name
        self.weight = float(weight)

    @abc.abstractmethod
    def rows(self, model: RobotModel, layout: Layout, dt: float, t: float) -> Rows:
        """Rows of the task at the updated state.

        Args:
            model: Robot model after :meth:`RobotModel.update` for this step.
            layout: Decision-variable layout.
            dt: Control period [s].
            t: Time [s].

        """

    _error_source: Any = None
    """Where the error of a step computed elsewhere (the native step) is fetched when
    :meth:`error` is first called after it (``None``: the error held is current): an object
    with the ``serial`` of its last step and ``fetch(task)``."""

    _error_serial: int = -1
    """The ``serial`` of ``_error_source`` whose error this task holds."""

    def error(self) -> np.ndarray:
        """Task-space error ``goal - current`` at the last call of :meth:`rows` (empty if none)."""
        return np.zeros(0)

    def _fetch_error(self) -> None:
        """Fetch the error of a step computed elsewhere, if one waits (see ``_error_source``).

        The source records the error (``record_error``) only if its step is still the
        controller's last one; a Python step since then computed the error in :meth:`rows`.
        """
        source = self._error_source
        if source is not None and source.serial != self._error_serial:
            self._error_serial = source.serial
            source.fetch(self)

    def where(self) -> str:
        """Prefix for error messages: the primitive's type and name."""
        return f"{type(self).__name__} {self.name!r}"
