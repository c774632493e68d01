"""Pose of a frame: world position (3 rows) and orientation ``log3(R_goal^T R)`` (3 rows)."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from hqp.tasks.base import Category
from hqp.tasks.orientation import orientation_kinematics
from hqp.tasks.position import frame_position_kinematics
from hqp.tasks.reference import MinimumJerkPose, PDReference, TrajectorySample, check_placement
from hqp.tasks.tracking import Gains, TaskKinematics, TrackingTask

if TYPE_CHECKING:
    from hqp.model import RobotModel


class PoseTask(TrackingTask):
    """Pose of a frame on SE(3): ``e = [p - p_goal; log3(R_goal^T R)]`` (6 rows).

    The translation error is in world axes [m], the rotation error in the
    goal's axes [rad] (decoupled: the origin moves straight to its goal). The
    Jacobian stacks ``J_lin`` and ``Jlog3(E) R^T J_ang``, the drift the
    origin's classical acceleration and the rotation drift of
    :func:`~hqp.tasks.orientation.orientation_kinematics`. The two blocks
    have their own saturations (``max_velocity``/``max_acceleration`` for the
    translation, ``max_angular_velocity``/``max_angular_acceleration`` for
    the rotation, by default the same numbers); they share ``kp`` and ``kv``.

    Args:
        robot: Robot model (the frame is checked here).
        frame: Frame name.
        name: Task name (default: the frame's name).
        weight: Weight within its level.
        kp: Stiffness of the PD reference [1/s^2] (translation and rotation).
        kv: Damping [1/s] (``None``: ``2 sqrt(kp)``, critical damping).
        max_velocity: Saturation of the translation's corrective velocity [m/s].
        max_acceleration: Saturation of the translation's feedback acceleration [m/s^2].
        max_angular_velocity: Saturation of the rotation's corrective velocity [rad/s]
            (``None``: the translation's number).
        max_angular_acceleration: Saturation of the rotation's feedback acceleration
            [rad/s^2] (``None``: the translation's number).

    Goal: :meth:`set_goal` with a ``pin.SE3`` or ``(4, 4)`` placement and
    optional velocity and acceleration ``(6,)`` ``[linear; angular]`` (world);
    :meth:`set_trajectory` (samples: ``(4, 4)``, ``(6,)``, ``(6,)``) or
    :meth:`move_to` (a :class:`MinimumJerkPose`).

    Raises:
        InvalidFrame: Unknown frame.
        InvalidGain: Bad gains.

    """

    category = Category.OPERATIONAL

    def __init__(
        self,
        robot: RobotModel,
        frame: str,
        *,
        name: str | None = None,
        weight: float = 1.0,
        kp: float = 100.0,
        kv: float | None = None,
        max_velocity: float = math.inf,
        max_acceleration: float = math.inf,
        max_angular_velocity: float | None = None,
        max_angular_acceleration: float | None = None,
    ) -> None:
        super().__init__(name or frame, weight, Gains(kp, kv, max_velocity, max_acceleration))
        robot.frame_id(frame, self.where())
        self.frame = frame
        self.angular_reference = self._angular(max_angular_velocity, max_angular_acceleration)

    def _angular(self, vmax: float | None, amax: float | None) -> PDReference:
        ref = self.reference
        return PDReference(
            ref.kp,
            ref.kv,
            ref.max_velocity if vmax is None else vmax,
            ref.max_acceleration if amax is None else amax,
            where=self.where() + " (rotation)",
        )

    def set_gains(
        self,
        kp: float | None = None,
        kv: float | None = None,
        max_velocity: float | None = None,
        max_acceleration: float | None = None,
        max_angular_velocity: float | None = None,
        max_angular_acceleration: float | None = None,
    ) -> None:
        """Change gains or saturations (``None`` keeps a value; see :meth:`TrackingTask.set_gains`).

        Raises:
            InvalidGain: Bad values.

        """
        old = self.angular_reference
        super().set_gains(kp, kv, max_velocity, max_acceleration)
        self.angular_reference = self._angular(
            old.max_velocity if max_angular_velocity is None else max_angular_velocity,
            old.max_acceleration if max_angular_acceleration is None else max_angular_acceleration,
        )

    def _check_goal(
        self, goal: object, velocity: object | None, acceleration: object | None
    ) -> TrajectorySample:
        H = check_placement(goal, f"{self.where()}: goal")
        return self._goal_sample(H, velocity, acceleration, 6)

    def set_goal(
        self, goal: object, velocity: object | None = None, acceleration: object | None = None
    ) -> None:
        """Set the goal placement (copied) with optional ``(6,)`` world velocity/acceleration.

        Raises:
            InvalidInput: Wrong shape, not a placement, NaN (names the primitive).

        """
        self._store_goal(self._check_goal(goal, velocity, acceleration))

    def value(self, model: RobotModel) -> np.ndarray:
        """Return the current placement ``T_world_frame`` as a ``(4, 4)`` array."""
        return model.frame_placement(self.frame).homogeneous.copy()

    def move_to(self, model: RobotModel, goal: object, duration: float, t0: float) -> None:
        """Reach ``goal`` along a :class:`MinimumJerkPose` from the current placement."""
        H = self._check_goal(goal, None, None).position
        self.set_trajectory(MinimumJerkPose(self.value(model), H, duration, t0))

    def kinematics(self, model: RobotModel, t: float = 0.0) -> TaskKinematics:
        """Stacked translation and rotation kinematics ``(6,)`` / ``(6, nv)``."""
        g = self.goal_at(t)
        rot = orientation_kinematics(
            model,
            self.frame,
            TrajectorySample(g.position[:3, :3], g.velocity[3:], g.acceleration[3:]),
        )
        p, v, J, a = frame_position_kinematics(model, self.frame)
        return TaskKinematics(
            np.concatenate([p - g.position[:3, 3], rot.error]),
            np.concatenate([v - g.velocity[:3], rot.rate]),
            np.concatenate([J, rot.jacobian]),
            np.concatenate([a - g.acceleration[:3], rot.drift]),
        )

    def _translation_rows(self) -> int:
        """Return the number of leading translation rows of :meth:`kinematics` (then rotation)."""
        return 3

    def feedback(self, kin: TaskKinematics) -> np.ndarray:
        """Return the translation and rotation feedback, each with its own saturations."""
        k = self._translation_rows()
        return np.concatenate(
            [
                self.reference.feedback(kin.error[:k], kin.rate[:k]),
                self.angular_reference.feedback(kin.error[k:], kin.rate[k:]),
            ]
        )
