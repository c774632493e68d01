"""Build the control primitives of a behavior for one robot, and set their goals.

The bridge between a behavior file's task specs (:class:`~hqp.behaviors.spec.TaskSpec`,
validated against :data:`~hqp.behaviors.schema.SCHEMAS`) and the task classes
of :mod:`hqp.tasks`: one builder and one goal setter per task type.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import Any

import numpy as np
import pinocchio as pin

from hqp.behaviors.spec import TaskSpec
from hqp.errors import BehaviorFileError, HQPError
from hqp.model import RobotModel
from hqp.tasks.base import Task
from hqp.tasks.centroidal import CentroidalMomentumTask
from hqp.tasks.com import CoMTask
from hqp.tasks.effort import EffortTask, ForceRegularization
from hqp.tasks.gaze import GazeTask
from hqp.tasks.orientation import OrientationTask
from hqp.tasks.pose import PoseTask
from hqp.tasks.position import PositionTask
from hqp.tasks.posture import PostureTask

_GAIN_KEYS = ("kp", "kv", "max_velocity", "max_acceleration")


def _rotation(value: Any, where: str) -> np.ndarray:
    """Return a rotation matrix from roll-pitch-yaw ``(3,)`` [rad] or a matrix ``(3, 3)``."""
    arr = np.asarray(value, dtype=float)
    if arr.shape == (3,):
        return pin.rpy.rpyToMatrix(arr)
    if arr.shape == (3, 3):
        return arr
    raise BehaviorFileError(f"{where}: expected roll-pitch-yaw (3,) or a rotation (3, 3), "
                            f"got shape {arr.shape}")


class TaskFactory:
    """Builds tasks for one robot model and evaluates the quantities behaviors read.

    Args:
        model: The controller's robot model.
        contacts: Declared contacts, name -> frame (e.g. ``{"left_foot": "left_foot"}``).
        standing: Standing configuration ``(nq,)`` (posture goal ``"standing"``).
        feet: Contact names whose frames define ``feet_center``.

    """

    def __init__(
        self,
        model: RobotModel,
        contacts: Mapping[str, str],
        standing: np.ndarray | None = None,
        feet: Iterable[str] = ("left_foot", "right_foot"),
    ) -> None:
        self.model = model
        self.contacts = dict(contacts)
        self.standing = None if standing is None else np.asarray(standing, dtype=float)
        self.feet = [c for c in feet if c in self.contacts]

    @property
    def contact_names(self) -> list[str]:
        """Declared contact names."""
        return list(self.contacts)

    @property
    def joint_names(self) -> tuple[str, ...]:
        """Actuated joints."""
        return self.model.joint_names

    # -- sensed quantities ------------------------------------------------------------------

    def feet_center(self, model: RobotModel) -> np.ndarray:
        """Mean position of the feet's contact frames ``(3,)`` [m]."""
        frames = [self.contacts[c] for c in self.feet] or list(self.contacts.values())
        return np.mean([model.frame_placement(f).translation for f in frames], axis=0)

    def frame_position(self, model: RobotModel, name: str) -> np.ndarray:
        """World position of a frame ``(3,)`` [m]."""
        return model.frame_placement(name).translation.copy()

    def joint(self, model: RobotModel, name: str) -> float:
        """Position of an actuated joint [rad]."""
        i = model.joint_index(name)
        return float(model.q[model.actuated_q][i])

    def joint_margin(self, model: RobotModel, name: str) -> float:
        """Distance of a joint to its nearer position limit [rad] (negative past a limit)."""
        i = model.joint_index(name)
        q = float(model.q[model.actuated_q][i])
        return float(min(q - model.q_lower[i], model.q_upper[i] - q))

    # -- tasks ------------------------------------------------------------------------------

    def build(self, spec: TaskSpec) -> Task:
        """Instantiate the task of a spec.

        Raises:
            BehaviorFileError: The task cannot be built (the message names the task).

        """
        builder = getattr(self, f"_build_{spec.type}", None)
        if builder is None:
            raise BehaviorFileError(f"task {spec.name!r}: type {spec.type!r} is not available "
                                    "in this version of hqp")
        gains = {k: float(spec.params[k]) for k in _GAIN_KEYS if k in spec.params}
        try:
            return builder(spec, gains)
        except HQPError as exc:
            if isinstance(exc, BehaviorFileError):
                raise
            raise BehaviorFileError(f"task {spec.name!r}: {exc}") from None

    def current(self, task: Task, spec: TaskSpec, model: RobotModel) -> Any:
        """Return the task's current value (``initial`` in goals), ``None`` if it has none."""
        if spec.type == "posture":
            return model.q.copy()
        value = getattr(task, "value", None)
        if callable(value):
            try:
                return np.asarray(value(model), dtype=float).copy()
            except HQPError:
                return None
        return None

    def set_goals(self, task: Task, spec: TaskSpec, values: Mapping[str, Any]) -> None:
        """Set a task's goals from evaluated goal expressions.

        Raises:
            BehaviorFileError: A value of the wrong shape (names the task and the goal).

        """
        setter = getattr(self, f"_goal_{spec.type}", self._goal_vector)
        try:
            setter(task, spec, values)
        except HQPError as exc:
            if isinstance(exc, BehaviorFileError):
                raise
            raise BehaviorFileError(f"task {spec.name!r}: goal: {exc}") from None

    # builders -------------------------------------------------------------------------------

    def _build_com(self, spec: TaskSpec, gains: dict[str, float]) -> Task:
        axes = spec.params.get("axes", "xyz")
        if axes not in ("xy", "xyz"):
            raise BehaviorFileError(f"task {spec.name!r}: com axes must be 'xy' or 'xyz' "
                                    f"(for a height, use a position task on the trunk), "
                                    f"got {axes!r}")
        return CoMTask(self.model, horizontal=axes == "xy", name=spec.name, weight=spec.weight,
                       **gains)

    def _build_position(self, spec: TaskSpec, gains: dict[str, float]) -> Task:
        return PositionTask(self.model, spec.frames["frame"], axes=spec.params.get("axes"),
                            name=spec.name, weight=spec.weight, **gains)

    def _build_orientation(self, spec: TaskSpec, gains: dict[str, float]) -> Task:
        return OrientationTask(self.model, spec.frames["frame"], name=spec.name,
                               weight=spec.weight, **gains)

    def _build_pose(self, spec: TaskSpec, gains: dict[str, float]) -> Task:
        return PoseTask(self.model, spec.frames["frame"], name=spec.name, weight=spec.weight,
                        **gains)

    def _build_gaze(self, spec: TaskSpec, gains: dict[str, float]) -> Task:
        kwargs: dict[str, Any] = {}
        if "axis" in spec.params:
            kwargs["axis"] = np.asarray(spec.params["axis"], dtype=float)
        return GazeTask(self.model, spec.frames["frame"], name=spec.name, weight=spec.weight,
                        **kwargs, **gains)

    def _build_posture(self, spec: TaskSpec, gains: dict[str, float]) -> Task:
        kwargs: dict[str, Any] = {}
        if "joints" in spec.params:
            kwargs["joints"] = list(spec.params["joints"])
        return PostureTask(self.model, name=spec.name, weight=spec.weight, **kwargs, **gains)

    def _build_effort(self, spec: TaskSpec, gains: dict[str, float]) -> Task:
        return EffortTask(self.model, name=spec.name, weight=spec.weight)

    def _build_momentum(self, spec: TaskSpec, gains: dict[str, float]) -> Task:
        part = spec.params.get("part", "angular")
        if part not in ("angular", "linear", "all"):
            raise BehaviorFileError(f"task {spec.name!r}: momentum part must be 'angular', "
                                    f"'linear' or 'all', got {part!r}")
        kwargs: dict[str, float] = {}
        if "kv" in gains:
            kwargs["gain"] = gains["kv"]
        if "max_acceleration" in gains:
            kwargs["max_rate"] = gains["max_acceleration"]
        return CentroidalMomentumTask(self.model, part, name=spec.name, weight=spec.weight,
                                      **kwargs)

    def _build_forces(self, spec: TaskSpec, gains: dict[str, float]) -> Task:
        return ForceRegularization(self.model, name=spec.name, weight=spec.weight)

    # goal setters -----------------------------------------------------------------------------

    def _goal_vector(self, task: Task, spec: TaskSpec, values: Mapping[str, Any]) -> None:
        if "goal" in values:
            task.set_goal(values["goal"], values.get("goal_velocity"),  # type: ignore[attr-defined]
                          values.get("goal_acceleration"))

    def _goal_momentum(self, task: Task, spec: TaskSpec, values: Mapping[str, Any]) -> None:
        if "goal" in values:
            task.set_goal(values["goal"])  # type: ignore[attr-defined]

    def _goal_orientation(self, task: Task, spec: TaskSpec, values: Mapping[str, Any]) -> None:
        if "goal" in values:
            task.set_goal(_rotation(values["goal"], f"task {spec.name!r}: goal"))  # type: ignore[attr-defined]

    def _goal_pose(self, task: Task, spec: TaskSpec, values: Mapping[str, Any]) -> None:
        if "goal" in values or "goal_rotation" in values:
            cur = task.value(self.model) if hasattr(task, "value") else None  # type: ignore[attr-defined]
            pos = values.get("goal")
            rot = values.get("goal_rotation")
            T = np.eye(4) if cur is None else np.asarray(cur, dtype=float).reshape(4, 4).copy()
            if pos is not None:
                T[:3, 3] = np.asarray(pos, dtype=float)
            if rot is not None:
                T[:3, :3] = _rotation(rot, f"task {spec.name!r}: goal_rotation")
            task.set_goal(T)  # type: ignore[attr-defined]

    def _goal_gaze(self, task: Task, spec: TaskSpec, values: Mapping[str, Any]) -> None:
        if "target" in values:
            task.set_goal(values["target"])  # type: ignore[attr-defined]

    def _goal_posture(self, task: Task, spec: TaskSpec, values: Mapping[str, Any]) -> None:
        if "goal" in values:
            goal = np.asarray(values["goal"], dtype=float)
            m = self.model
            if goal.shape == (m.nq,):
                task.set_configuration(goal, m)  # type: ignore[attr-defined]
            elif goal.shape == (m.na,) and len(task.joints) != m.na:  # type: ignore[attr-defined]
                task.set_pose(goal, m)  # type: ignore[attr-defined]
            else:
                task.set_goal(goal, values.get("goal_velocity"),  # type: ignore[attr-defined]
                              values.get("goal_acceleration"))
