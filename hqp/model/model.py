"""Robot model: a thin layer over pinocchio (the seed's "Robot Model").

One :meth:`RobotModel.update` per control step computes everything the control
primitives need (frame placements, Jacobians and drift terms, mass matrix,
bias forces, centre of gravity and its Jacobian, centroidal momentum matrix);
primitives then read those quantities without running pinocchio again.

Conventions (pinocchio's): a floating base is a free-flyer joint whose
configuration is ``[x, y, z, qx, qy, qz, qw]`` and whose velocity is
``[v_base (base frame), omega_base (base frame)]``; world-frame quantities of
frames use ``LOCAL_WORLD_ALIGNED`` (origin of the frame, axes of the world).
Spatial 6-vectors are ordered ``[linear, angular]``.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Hashable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TypeVar

import numpy as np
import pinocchio as pin

from hqp.errors import InvalidFrame, InvalidInput, check_array

LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
"""Shorthand for pinocchio's ``LOCAL_WORLD_ALIGNED`` reference frame."""

T = TypeVar("T")


@dataclass(frozen=True)
class RobotState:
    """What a robot (real or simulated) reports to the controller each step.

    Attributes:
        q: Configuration ``(nq,)`` in pinocchio's convention.
        v: Velocity ``(nv,)`` in pinocchio's convention.
        t: Time of the measurement [s].
        contacts: Sensed contact state by contact name (``None``: not sensed).
        wrenches: Measured contact wrenches ``(6,)`` or forces ``(3,)`` by
            contact name (``None``: not measured).

    """

    q: np.ndarray
    v: np.ndarray
    t: float = 0.0
    contacts: Mapping[str, bool] | None = None
    wrenches: Mapping[str, np.ndarray] | None = field(default=None)



def _computed(name: str, doc: str) -> property:
    """Return a property reading a quantity of the update's pass (run first if deferred)."""
    attr = "_" + name

    def get(self: RobotModel) -> np.ndarray:
        if self._pending:
            value = self._provided(name)
            if value is not None:
                return value
            self._compute()
        return getattr(self, attr)  # type: ignore[no-any-return]

    return property(get, doc=doc)

class RobotModel:
    """Kinematics and dynamics of one robot, updated once per control step.

    Args:
        model: A pinocchio model. Its first joint is a free flyer when
            ``floating_base`` is true; every other joint has one degree of
            freedom and is actuated.
        name: Robot name used in messages.
        floating_base: Whether the first joint is a free flyer.
        position_limits: ``(lower, upper)`` over the actuated joints [rad or m]
            (defaults: the model's limits).
        velocity_limits: Over the actuated joints [rad/s] (default: model's).
        torque_limits: Over the actuated joints [N m] (default: model's).

    Raises:
        InvalidInput: A joint with more than one degree of freedom besides the
            free flyer, or limits of the wrong shape.

    """

    def __init__(
        self,
        model: pin.Model,
        *,
        name: str = "robot",
        floating_base: bool = True,
        position_limits: tuple[np.ndarray, np.ndarray] | None = None,
        velocity_limits: np.ndarray | None = None,
        torque_limits: np.ndarray | None = None,
    ) -> None:
        self.model = model
        self._data = model.createData()
        self._pending = False  # an update whose pinocchio pass waits for its first reader
        self._provider: Callable[[str], np.ndarray | None] | None = None
        self._provided_cache: dict[str, np.ndarray] = {}
        self.name = name
        self.source: Any = None
        """The bundled robot this model was built from (``Robot.model()`` sets it; ``None``
        for a model built otherwise): the native step builds its own model from it."""
        self.floating_base = floating_base
        self.nq = model.nq
        self.nv = model.nv
        first = 2 if floating_base else 1
        if floating_base and model.joints[1].nv != 6:
            raise InvalidInput(
                f"RobotModel {name!r}: floating_base but joint 1 is not a free flyer"
            )
        for j in range(first, model.njoints):
            if model.joints[j].nv != 1 or model.joints[j].nq != 1:
                raise InvalidInput(
                    f"RobotModel {name!r}: joint {model.names[j]!r} has "
                    f"nq={model.joints[j].nq}, nv={model.joints[j].nv}; only 1-DoF joints "
                    "besides the free flyer are supported"
                )
        self.nq_base = 7 if floating_base else 0
        self.nv_base = 6 if floating_base else 0
        self.na = self.nv - self.nv_base
        self.joint_names: tuple[str, ...] = tuple(model.names[first:])
        """Actuated joint names, in velocity order."""
        self.actuated = slice(self.nv_base, self.nv)
        """Slice of ``v`` (and of ``qdd``) holding the actuated joints."""
        self.actuated_q = slice(self.nq_base, self.nq)
        """Slice of ``q`` holding the actuated joints."""
        self.frame_names: tuple[str, ...] = tuple(f.name for f in model.frames)
        self._frame_ids = {f.name: i for i, f in enumerate(model.frames)}
        self.mass = float(sum(inertia.mass for inertia in model.inertias))
        self.gravity_vector = np.array(model.gravity.linear)

        if position_limits is None:
            lower = np.array(model.lowerPositionLimit[self.actuated_q])
            upper = np.array(model.upperPositionLimit[self.actuated_q])
        else:
            lower = check_array(
                position_limits[0], (self.na,), f"RobotModel {name!r}: lower limits"
            )
            upper = check_array(
                position_limits[1], (self.na,), f"RobotModel {name!r}: upper limits"
            )
        if np.any(lower > upper):
            raise InvalidInput(f"RobotModel {name!r}: a lower position limit exceeds its upper one")
        self.q_lower = lower
        self.q_upper = upper
        self.v_max = (
            np.array(model.velocityLimit[self.actuated])
            if velocity_limits is None
            else check_array(velocity_limits, (self.na,), f"RobotModel {name!r}: velocity limits")
        )
        self.tau_max = (
            np.array(model.effortLimit[self.actuated])
            if torque_limits is None
            else check_array(torque_limits, (self.na,), f"RobotModel {name!r}: torque limits")
        )
        if np.any(self.v_max < 0) or np.any(self.tau_max < 0):
            raise InvalidInput(f"RobotModel {name!r}: negative velocity or torque limit")

        self._frame_cache: dict[tuple[str, pin.ReferenceFrame, int], np.ndarray] = {}
        self._step_cache: dict[Hashable, Any] = {}
        self.q = pin.neutral(model)
        self.v = np.zeros(self.nv)

        self._upper = np.triu(np.ones((self.nv, self.nv), dtype=bool))
        self.update(self.q, self.v)

    # -- construction -------------------------------------------------------------------------

    @classmethod
    def from_urdf(
        cls,
        path: str | Path,
        *,
        floating_base: bool = True,
        package_dirs: list[str] | None = None,
        **kwargs: object,
    ) -> RobotModel:
        """Build from a URDF file (free flyer added when ``floating_base``)."""
        root = pin.JointModelFreeFlyer() if floating_base else None
        if root is None:
            model = pin.buildModelFromUrdf(str(path))
        else:
            model = pin.buildModelFromUrdf(str(path), root)
        return cls(model, floating_base=floating_base, **kwargs)  # type: ignore[arg-type]

    @classmethod
    def from_mjcf(
        cls, path: str | Path, *, floating_base: bool = True, **kwargs: object
    ) -> RobotModel:
        """Build from an MJCF file (its free joint becomes pinocchio's free flyer)."""
        model = pin.buildModelFromMJCF(str(path))
        return cls(model, floating_base=floating_base, **kwargs)  # type: ignore[arg-type]

    # -- names --------------------------------------------------------------------------------

    def frame_id(self, name: str, where: str = "") -> int:
        """Index of a frame by name.

        Raises:
            InvalidFrame: Unknown name; the message lists the frames that exist.

        """
        try:
            return self._frame_ids[name]
        except KeyError:
            raise InvalidFrame(name, self.frame_names, where or f"robot {self.name!r}") from None

    def has_frame(self, name: str) -> bool:
        """Whether a frame of that name exists."""
        return name in self._frame_ids

    def joint_index(self, name: str) -> int:
        """Index of an actuated joint in the actuated vector (0 .. na-1).

        Raises:
            InvalidInput: Unknown joint; the message lists the joints.

        """
        try:
            return self.joint_names.index(name)
        except ValueError:
            raise InvalidInput(
                f"robot {self.name!r}: unknown joint {name!r}; "
                f"joints: {', '.join(self.joint_names)}"
            ) from None

    # -- update -------------------------------------------------------------------------------

    def update(self, q: np.ndarray, v: np.ndarray, *, defer: bool = False) -> None:
        """Compute every quantity of a control step at ``(q, v)``.

        Args:
            q: Configuration ``(nq,)``.
            v: Velocity ``(nv,)``.
            defer: Run the pinocchio pass when a derived quantity is first read (never if
                none is): for a step whose rows the native core computes from its own model,
                so that the state is checked and ``q``, ``v`` set, but no second pass runs
                unless logs or behaviors read the model.

        Raises:
            InvalidInput: Wrong shape or non-finite entries.

        """
        q = np.asarray(q, dtype=float)
        v = np.asarray(v, dtype=float)
        if q.shape != (self.nq,) or v.shape != (self.nv,):
            raise InvalidInput(
                f"robot {self.name!r}: state shapes q {q.shape}, v {v.shape}; "
                f"expected ({self.nq},), ({self.nv},)"
            )
        # One reduction first (NaN and inf propagate; an overflow falls to the exact check).
        if not math.isfinite(q.dot(q) + v.dot(v)) and not (
            np.isfinite(q).all() and np.isfinite(v).all()
        ):
            raise InvalidInput(f"robot {self.name!r}: state holds NaN or inf")
        self.q = q.copy()
        self.v = v.copy()
        self._frame_cache.clear()
        self._step_cache.clear()
        self._provider = None
        self._provided_cache.clear()
        self._pending = True
        if not defer:
            self._compute()

    def provide(self, provider: Callable[[str], np.ndarray | None]) -> None:
        """Take some quantities of a deferred update from a pass made elsewhere.

        The native step makes the pinocchio pass of this update's state in C++: where a
        reader asks for a quantity it has (the centre of mass and its velocity), the model
        takes it from there instead of running its own pass. ``provider(name)`` returns the
        quantity at this update's ``(q, v)``, or ``None``; it is forgotten at the next update.
        """
        if self._pending:
            self._provider = provider

    def _provided(self, name: str) -> np.ndarray | None:
        """Return a quantity of the pending update from the provider (``None``: not there)."""
        if self._provider is None:
            return None
        value = self._provided_cache.get(name)
        if value is None:
            value = self._provider(name)
            if value is not None:
                value.setflags(write=False)
                self._provided_cache[name] = value
        return value

    def _compute(self) -> None:
        """Run the update's one pinocchio pass at ``(self.q, self.v)``."""
        model, data = self.model, self._data
        self._pending = False
        # One pass over the tree (pinocchio's computeAllTerms): joint placements, velocities and
        # accelerations at qdd = 0 (the drift terms of the frames), joint Jacobians, M (upper
        # triangle), h, g, centre of mass, its velocity and Jacobian, A_g and dA_g.
        pin.computeAllTerms(model, data, self.q, self.v)
        pin.updateFramePlacements(model, data)
        M = data.M
        self._M = np.where(self._upper, M, M.T)
        self._h = data.nle.copy()
        self._g = data.g.copy()
        self._centroidal_matrix = data.Ag.copy()
        self._centroidal_drift = data.dAg @ self.v
        self._com_jacobian = data.Jcom.copy()
        self._com = data.com[0].copy()
        self._com_velocity = data.vcom[0].copy()
        # Linear rows of dA_g v are the momentum rate m c_ddot at qdd = 0.
        self._com_drift = self._centroidal_drift[:3] / data.mass[0]

    @property
    def data(self) -> pin.Data:
        """Pinocchio's data at the last update's state (its pass run if deferred)."""
        if self._pending:
            self._compute()
        return self._data

    M = _computed("M", "Joint-space mass matrix ``M(q)`` ``(nv, nv)``.")
    h = _computed("h", "Bias forces ``h(q, v)`` (Coriolis, centrifugal, gravity) ``(nv,)``.")
    com = _computed("com", "Centre of mass ``(3,)`` [m].")
    com_velocity = _computed("com_velocity", "Centre-of-mass velocity ``(3,)`` [m/s].")
    com_jacobian = _computed("com_jacobian", "Centre-of-mass Jacobian ``(3, nv)``.")
    com_drift = _computed("com_drift", "Centre-of-mass acceleration at ``qdd = 0`` ``(3,)``.")
    centroidal_matrix = _computed("centroidal_matrix", "Centroidal momentum matrix ``A_g``.")
    centroidal_drift = _computed("centroidal_drift", "``dA_g v`` ``(6,)``.")

    def per_update(self, key: Hashable, compute: Callable[[], T]) -> T:
        """Return ``compute()``, computed once per :meth:`update` for a given ``key``.

        For quantities derived from the state that several tasks of a step read (e.g. the
        contact terms of the equation of motion for a layout): the first call computes and
        keeps the value, later calls until the next update return the same object (treat it as
        read only). Keys must be hashable and name the quantity and its inputs.
        """
        try:
            return self._step_cache[key]  # type: ignore[no-any-return]
        except KeyError:
            value = self._step_cache[key] = compute()
            return value

    # -- whole-body quantities ----------------------------------------------------------------

    @property
    def gravity(self) -> np.ndarray:
        """Generalized gravity ``g(q)`` ``(nv,)`` [N m] (from the update's single pass)."""
        if self._pending:
            self._compute()
        return self._g

    def selection(self) -> np.ndarray:
        """Actuation selection ``S`` ``(na, nv)``: ``tau_full = S^T tau``."""
        S = np.zeros((self.na, self.nv))
        S[:, self.actuated] = np.eye(self.na)
        return S

    # -- frames -------------------------------------------------------------------------------

    def frame_placement(self, name: str) -> pin.SE3:
        """World placement ``T_world_frame`` of a frame."""
        return self.data.oMf[self.frame_id(name)]

    def frame_jacobian(self, name: str, reference: pin.ReferenceFrame = LWA) -> np.ndarray:
        """Frame Jacobian ``(6, nv)``, rows ``[linear; angular]`` (computed once per update).

        The array is shared by every caller of the step: read it, do not modify it.
        """
        key = (name, reference, 0)
        J = self._frame_cache.get(key)
        if J is None:
            J = pin.getFrameJacobian(self.model, self.data, self.frame_id(name), reference)
            self._frame_cache[key] = J
        return J

    def frame_velocity(self, name: str, reference: pin.ReferenceFrame = LWA) -> np.ndarray:
        """Frame spatial velocity ``(6,)`` ``[linear; angular]`` (computed once per update).

        The array is shared by every caller of the step: read it, do not modify it.
        """
        key = (name, reference, 1)
        w = self._frame_cache.get(key)
        if w is None:
            w = pin.getFrameVelocity(self.model, self.data, self.frame_id(name), reference).vector
            self._frame_cache[key] = w
        return w

    def frame_drift(self, name: str, reference: pin.ReferenceFrame = LWA) -> np.ndarray:
        """Classical acceleration of a frame at ``qdd = 0`` ``(6,)`` ``[linear; angular]``.

        With ``J`` the frame Jacobian, the frame's classical acceleration is
        ``J qdd + frame_drift`` (computed once per update; the array is shared by every caller
        of the step: read it, do not modify it).
        """
        key = (name, reference, 2)
        a = self._frame_cache.get(key)
        if a is None:
            a = pin.getFrameClassicalAcceleration(
                self.model, self.data, self.frame_id(name), reference
            ).vector
            self._frame_cache[key] = a
        return a

    # -- configuration helpers ----------------------------------------------------------------

    def neutral(self) -> np.ndarray:
        """Neutral configuration ``(nq,)``."""
        return pin.neutral(self.model)

    def integrate(self, q: np.ndarray, dv: np.ndarray) -> np.ndarray:
        """``q (+) dv`` on the configuration manifold."""
        return pin.integrate(self.model, q, dv)

    def difference(self, q0: np.ndarray, q1: np.ndarray) -> np.ndarray:
        """Tangent vector ``dv`` with ``q0 (+) dv = q1``."""
        return pin.difference(self.model, q0, q1)

    def random_configuration(self, rng: np.random.Generator, margin: float = 0.0) -> np.ndarray:
        """Draw a configuration, actuated joints uniform within their limits shrunk by ``margin``.

        The base (if any) is placed at a random position within 1 m of the
        origin with a random orientation.
        """
        q = self.neutral()
        lo = self.q_lower + margin
        hi = self.q_upper - margin
        lo = np.where(np.isfinite(lo), lo, -np.pi)
        hi = np.where(np.isfinite(hi), hi, np.pi)
        q[self.actuated_q] = rng.uniform(lo, hi)
        if self.floating_base:
            q[:3] = rng.uniform(-1.0, 1.0, 3)
            quat = rng.normal(size=4)
            q[3:7] = quat / np.linalg.norm(quat)
        return q
