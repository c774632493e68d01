"""Posture: imitate a captured pose (all or selected joints); the symmetry posture of eq. 26."""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from hqp.errors import InvalidInput, check_array
from hqp.tasks.base import Category
from hqp.tasks.reference import TrajectorySample
from hqp.tasks.tracking import Gains, VectorTrackingTask

if TYPE_CHECKING:
    from hqp.model import RobotModel


def load_poses(path: str | Path) -> dict[str, dict[str, float] | np.ndarray]:
    """Read named poses from an ``.npz`` or ``.json`` file.

    Formats:
        * ``.npz``: one array per pose name, over all actuated joints in the
          model's order ``(na,)``.
        * ``.json``: ``{"pose_name": {"joint_name": value, ...}, ...}`` or
          ``{"pose_name": [v_0, ..., v_{na-1}], ...}``.

    Values are joint positions [rad or m].

    Returns:
        Pose name -> ``{joint: value}`` mapping or array.

    Raises:
        InvalidInput: Missing file, unknown extension, or malformed content.

    """
    p = Path(path)
    where = f"load_poses {str(p)!r}"
    if not p.is_file():
        raise InvalidInput(f"{where}: no such file")
    poses: dict[str, dict[str, float] | np.ndarray] = {}
    if p.suffix == ".npz":
        with np.load(p, allow_pickle=False) as data:
            for key in data.files:
                poses[key] = check_array(data[key], (None,), f"{where}: pose {key!r}")
        return poses
    if p.suffix == ".json":
        try:
            raw = json.loads(p.read_text())
        except json.JSONDecodeError as exc:
            raise InvalidInput(f"{where}: invalid JSON ({exc})") from None
        if not isinstance(raw, dict):
            raise InvalidInput(f"{where}: top level must map pose names to poses")
        for key, pose in raw.items():
            if isinstance(pose, dict):
                values = {}
                for joint, value in pose.items():
                    if not isinstance(value, (int, float)) or not math.isfinite(value):
                        raise InvalidInput(
                            f"{where}: pose {key!r} joint {joint!r}: bad value {value!r}"
                        )
                    values[str(joint)] = float(value)
                poses[str(key)] = values
            else:
                poses[str(key)] = check_array(pose, (None,), f"{where}: pose {key!r}")
        return poses
    raise InvalidInput(f"{where}: unknown extension {p.suffix!r} (expected .npz or .json)")


class PostureTask(VectorTrackingTask):
    """Joint posture: ``e = W (q_sel - q_goal)`` over all or selected actuated joints.

    Jacobian ``W S_sel`` (a selection of the ``qdd`` columns of the actuated
    joints), no drift. With ``W`` the identity this imitates a captured pose;
    :meth:`symmetry` builds the seed's body-symmetry posture
    ``V_SYM = ||W (q - q_mid)||^2`` (seed 003 eq. 26) with
    ``q_mid = (q_upper + q_lower) / 2`` and the normalising matrix
    ``W = diag(1 / (q_upper - q_lower))`` (the seed prints
    ``diag(q_upper - q_lower)`` and calls it normalising; hqp divides by the
    range, Liegeois' joint-range criterion, so that every joint's error is a
    fraction of its range).

    Args:
        robot: Robot model.
        joints: Names of the controlled actuated joints (``None``: all).
        weights: Diagonal of ``W`` ``(k,)`` (positive; default ones).
        name: Task name.
        weight: Weight within its level.
        kp: Stiffness of the PD reference [1/s^2].
        kv: Damping [1/s] (``None``: ``2 sqrt(kp)``, critical damping).
        max_velocity: Saturation of the corrective velocity [rad/s, on ``e``].
        max_acceleration: Saturation of the feedback acceleration [rad/s^2].

    Goal: :meth:`set_goal` with ``(k,)`` positions of the selected joints or a
    ``{joint: value}`` mapping that covers them; :meth:`set_configuration`
    with a full configuration ``(nq,)``; :meth:`set_pose` with a pose from
    :func:`load_poses`.

    Raises:
        InvalidInput: Unknown or repeated joints, bad weights.
        InvalidGain: Bad gains.

    """

    category = Category.POSTURE

    def __init__(
        self,
        robot: RobotModel,
        joints: Sequence[str] | None = None,
        *,
        weights: object | None = None,
        name: str = "posture",
        weight: float = 1.0,
        kp: float = 100.0,
        kv: float | None = None,
        max_velocity: float = math.inf,
        max_acceleration: float = math.inf,
    ) -> None:
        super().__init__(name, weight, Gains(kp, kv, max_velocity, max_acceleration))
        w = self.where()
        if joints is None:
            names = list(robot.joint_names)
        else:
            names = [str(j) for j in joints]
            if not names or len(set(names)) != len(names):
                raise InvalidInput(f"{w}: joints must be non-empty and distinct")
            for j in names:
                if j not in robot.joint_names:
                    raise InvalidInput(
                        f"{w}: unknown joint {j!r}; joints: {', '.join(robot.joint_names)}"
                    )
        self.joints: tuple[str, ...] = tuple(names)
        idx = np.array([robot.joint_index(j) for j in names], dtype=int)
        self._q_index = robot.nq_base + idx
        self._v_index = robot.nv_base + idx
        self.goal_size = len(names)
        if weights is not None:
            W = check_array(weights, (self.goal_size,), f"{w}: weights")
            if np.any(W <= 0.0):
                raise InvalidInput(f"{w}: weights must be positive")
            self.scale = W
        self._nv = robot.nv
        # Jacobian (a selection of qdd columns) and drift (zero), shared by every step.
        self._J = np.zeros((self.goal_size, robot.nv))
        self._J[np.arange(self.goal_size), self._v_index] = 1.0
        self._J.flags.writeable = False
        self._drift = np.zeros(self.goal_size)
        self._drift.flags.writeable = False

    @classmethod
    def symmetry(
        cls,
        robot: RobotModel,
        joints: Sequence[str] | None = None,
        *,
        name: str = "symmetry",
        **kwargs: object,
    ) -> PostureTask:
        """Build the body-symmetry posture of seed 003 eq. 26 (``q_mid``, ``W = diag(1/range)``).

        Raises:
            InvalidInput: A selected joint with an infinite or empty range.

        """
        task = cls(robot, joints, name=name, **kwargs)  # type: ignore[arg-type]
        idx = task._v_index - robot.nv_base
        lo, hi = robot.q_lower[idx], robot.q_upper[idx]
        if not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi)) and np.all(hi > lo)):
            raise InvalidInput(f"{task.where()}: symmetry posture needs finite, non-empty ranges")
        task.scale = 1.0 / (hi - lo)
        task.set_goal(0.5 * (lo + hi))
        return task

    @classmethod
    def from_file(
        cls,
        robot: RobotModel,
        path: str | Path,
        pose: str,
        joints: Sequence[str] | None = None,
        **kwargs: object,
    ) -> PostureTask:
        """Build a posture task whose goal is a named pose of a file (:func:`load_poses`).

        Raises:
            InvalidInput: Bad file or unknown pose (lists the poses).

        """
        task = cls(robot, joints, **kwargs)  # type: ignore[arg-type]
        poses = load_poses(path)
        if pose not in poses:
            raise InvalidInput(
                f"{task.where()}: no pose {pose!r} in {str(path)!r}; poses: {', '.join(poses)}"
            )
        task.set_pose(poses[pose], robot)
        return task

    def _check_goal(
        self, goal: object, velocity: object | None, acceleration: object | None
    ) -> TrajectorySample:
        if isinstance(goal, Mapping):
            missing = [j for j in self.joints if j not in goal]
            if missing:
                raise InvalidInput(f"{self.where()}: goal misses joints {', '.join(missing)}")
            goal = [goal[j] for j in self.joints]
        return super()._check_goal(goal, velocity, acceleration)

    def set_configuration(self, q: object, robot: RobotModel) -> None:
        """Goal from a full configuration ``(nq,)`` (its selected joints).

        Raises:
            InvalidInput: Wrong shape or NaN.

        """
        qa = check_array(q, (robot.nq,), f"{self.where()}: configuration")
        self.set_goal(qa[self._q_index])

    def set_pose(self, pose: Mapping[str, float] | np.ndarray, robot: RobotModel) -> None:
        """Goal from a pose of :func:`load_poses`: a ``{joint: value}`` mapping or ``(na,)`` array.

        Raises:
            InvalidInput: Missing joints or wrong shape.

        """
        if isinstance(pose, Mapping):
            self.set_goal(pose)
            return
        qa = check_array(pose, (robot.na,), f"{self.where()}: pose over all actuated joints")
        self.set_goal(qa[self._q_index - robot.nq_base])

    def measure(self, model: RobotModel) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``(q_sel, v_sel, S_sel, 0)`` (``S_sel`` and ``0`` are read-only arrays)."""
        if model.nv == self._nv:
            return model.q[self._q_index], model.v[self._v_index], self._J, self._drift
        k = self.goal_size
        J = np.zeros((k, model.nv))
        J[np.arange(k), self._v_index] = 1.0
        return model.q[self._q_index], model.v[self._v_index], J, np.zeros(k)
