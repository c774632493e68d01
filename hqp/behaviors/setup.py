"""A behavior ready to run: loaded for a robot, on a controller of its own (no simulator).

:func:`prepare` loads a behavior (library name, file or spec), checks its frames, joints and
contacts against the robot, and builds its controller (:func:`build_controller`), task
factory, runtime inputs and planner. Running it is the caller's part (``hqp run``:
:func:`hqp.app.run.run_behavior`).
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from hqp import robots
from hqp.behaviors.behavior import Behavior
from hqp.behaviors.expressions import ExpressionError, Namespace
from hqp.behaviors.factory import TaskFactory
from hqp.behaviors.inputs import InputStream
from hqp.behaviors.loader import file_error, load_behavior
from hqp.behaviors.planners import WalkPlanner
from hqp.behaviors.spec import BehaviorSpec, InputSpec
from hqp.control.presets import constraint_controller
from hqp.control.servo import MAX_TORQUE_RATE
from hqp.errors import BehaviorFileError, HQPError, InvalidInput, UnknownName


def build_controller(
    robot: Any,
    controller: str,
    *,
    diagnostics: str = "residuals",
    backend: str | None = None,
    max_joint_acceleration: float | None = None,
    max_torque_rate: float | None = MAX_TORQUE_RATE,
) -> Any:
    """Build a whole-body controller holding only the constraint levels of docs/concepts/levels.md.

    :func:`hqp.control.presets.constraint_controller`: the constraint levels of the standing
    controllers (physics with both soles as contacts, friction / centre-of-pressure / torque
    limits, viable joint limits for HQP or the papers' activation zones for the null-space
    law), without their standing tasks: the behavior writes its own task sets.

    Args:
        robot: The bundled robot.
        controller: ``"hqp"`` or ``"nullspace"``.
        diagnostics: ``"residuals"`` (per-task residuals, cheap) or ``"full"``.
        backend: QP backend of the HQP controller (``None``: its default).
        max_joint_acceleration: Clip of the HQP controller's joint-acceleration bounds
            [rad/s^2] (``None``: its default; the null-space law has activation zones instead).
        max_torque_rate: The HQP servo's torque-rate level [N m/s] (``None``: none; the
            null-space law has none).

    Raises:
        UnknownName: Unknown controller.

    """
    return constraint_controller(controller, robot, diagnostics=diagnostics, backend=backend,
                                 max_joint_acceleration=max_joint_acceleration,
                                 max_torque_rate=max_torque_rate)


def _torque_rate(spec: BehaviorSpec) -> float | None:
    """Return the behavior's torque-rate level [N m/s]: its file's, else the default."""
    if spec.max_torque_rate is None:
        return MAX_TORQUE_RATE
    return spec.max_torque_rate or None


def _contacts_of(spec: BehaviorSpec, robot: Any) -> dict[str, str]:
    if spec.contact_frames:
        return dict(spec.contact_frames)
    return {c.name: c.frame for c in robot.contacts}


def _with_overrides(spec: BehaviorSpec, overrides: dict[str, Any]) -> BehaviorSpec:
    """Return the spec with some input defaults replaced (by input name).

    Raises:
        UnknownName: An input the behavior does not declare.
        InvalidInput: A value that is not finite numbers of the input's shape.

    """
    new_inputs = dict(spec.inputs)
    for k, v in overrides.items():
        if k not in new_inputs:
            raise UnknownName("input", k, new_inputs)
        old = new_inputs[k]
        want = f"{list(old.shape)} (a number)" if old.shape == () else f"{list(old.shape)}"
        try:
            arr = np.asarray(v, dtype=float)
        except (TypeError, ValueError):
            arr = None
        if (arr is None or isinstance(v, (bool, str)) or v is None
                or arr.size != int(np.prod(old.shape)) or not np.isfinite(arr).all()):
            raise InvalidInput(f"input {k!r}: expected finite numbers of shape {want}, "
                               f"got {v!r}")
        new_inputs[k] = InputSpec(k, old.shape, arr.reshape(old.shape),
                                  old.interpolate, old.description)
    return replace(spec, inputs=new_inputs)


def _robot_defaults(spec: BehaviorSpec, dimensions: dict[str, Any]) -> BehaviorSpec:
    """Return the spec with its expression defaults evaluated on the robot's dimensions.

    Raises:
        BehaviorFileError: A default that does not give finite numbers of the input's shape
            (names the file and key).

    """
    new_inputs = dict(spec.inputs)
    env = {"robot": Namespace(dimensions, "robot")}
    for k, old in spec.inputs.items():
        if old.default_expression is None:
            continue
        key = ("inputs", k, "default")
        try:
            value = np.asarray(old.default_expression.evaluate(env), dtype=float)
        except (ExpressionError, TypeError, ValueError) as exc:
            raise file_error(spec.path, key, str(exc)) from None
        if value.size != int(np.prod(old.shape)) or not np.isfinite(value).all():
            raise file_error(spec.path, key, f"gives {value.tolist()} on this robot; expected "
                             f"finite numbers of shape {list(old.shape)}")
        new_inputs[k] = InputSpec(k, old.shape, value.reshape(old.shape), old.interpolate,
                                  old.description)
    return replace(spec, inputs=new_inputs)


def _check_for_controller(spec: BehaviorSpec, behavior: Behavior, ctrl: Any,
                          factory: TaskFactory) -> None:
    """Check at load what only the controller can tell: levels and the goals known then.

    A goal written as numbers, or reading only inputs (their values at t = 0), ``standing``
    and captured poses, is set once on a fresh task of its type.

    Raises:
        BehaviorFileError: A level the controller does not have, or such a goal the task
            refuses (wrong length, not a rotation, ...); the message names file, line, key.

    """
    for pname, phase in spec.phases.items():
        for ts in phase.action.tasks:
            own = spec.tasks[ts.name]
            if ts.level == own.level:
                key: tuple[str | int, ...] = ("tasks", ts.name, "level")
            elif phase.action.name == pname:
                key = ("phases", pname, "levels", ts.name)
            else:
                key = ("actions", phase.action.name, "levels", ts.name)
            try:
                ctrl.stack.level_of(ts.level, behavior.tasks[ts.name])
            except HQPError as exc:
                raise file_error(spec.path, key, f"task {ts.name!r}: {exc}") from None
            goals = {g: (("tasks", ts.name, g), e) for g, e in own.goals.items()}
            goals.update({g: (("phases", pname, "goals", ts.name) if len(phase.goals[ts.name])
                              == 1 else ("phases", pname, "goals", ts.name, g), e)
                          for g, e in phase.goals.get(ts.name, {}).items()})
            for gname, (gkey, expr) in goals.items():
                if not expr.names <= _KNOWN_AT_LOAD or (
                        "standing" in expr.names and behavior.standing is None):
                    continue  # read from the sensed state: checked when it is evaluated
                try:
                    value = expr.evaluate(_load_env(spec, behavior))
                    factory.set_goals(factory.build(own), own, {gname: value})
                except (HQPError, ExpressionError) as exc:
                    raise file_error(spec.path, gkey, str(exc)) from None


_KNOWN_AT_LOAD = frozenset({"input", "standing", "pose", "robot"})
"""Names a goal may read that have a value before the run: the inputs at t = 0, the
standing configuration, the captured poses, the robot's dimensions."""


def _load_env(spec: BehaviorSpec, behavior: Behavior) -> dict[str, Any]:
    """Return the values of :data:`_KNOWN_AT_LOAD` before the run."""
    stream = behavior.inputs
    return {
        "input": Namespace({k: stream.value(k, 0.0) for k in spec.inputs}, "input"),
        "standing": behavior.standing,
        "pose": Namespace({k: behavior.pose(k) for k in spec.poses}, "pose"),
        "robot": Namespace(behavior.robot_values, "robot"),
    }


def prepare(
    source: str | Path | BehaviorSpec,
    *,
    robot: str | None = None,
    controller: str = "hqp",
    inputs: str | Path | None = None,
    overrides: dict[str, Any] | None = None,
    backend: str | None = None,
) -> tuple[Behavior, Any, Any]:
    """Load a behavior for a robot and build its controller (no simulation).

    Args:
        source: Library name, file path, or an already parsed spec.
        robot: Robot name or robot TOML file (default: the behavior's).
        controller: ``"hqp"`` or ``"nullspace"``.
        inputs: Inputs file (default: the behavior's ``inputs_file``, else defaults).
        overrides: Input defaults to replace, by input name (e.g. a jump target).
        backend: QP backend of the HQP controller (default: the behavior's ``backend``,
            else the controller's default).

    Returns:
        ``(behavior, controller, robot)``.

    """
    spec = source if isinstance(source, BehaviorSpec) else load_behavior(source)
    robot_obj = robots.load(robot or spec.robot)
    ctrl = build_controller(robot_obj, controller,
                            backend=backend if backend is not None else spec.backend,
                            max_joint_acceleration=spec.max_joint_acceleration,
                            max_torque_rate=_torque_rate(spec))
    model = ctrl.model
    contacts = _contacts_of(spec, robot_obj)
    declared = set(ctrl.stack.contacts)
    if set(contacts) != declared:
        raise BehaviorFileError(f"{spec.path}: contacts {sorted(contacts)} differ from the "
                                f"robot's {sorted(declared)}")
    # validate frames, joints and contacts of the file against this robot
    path = spec.path if spec.path is not None else source
    if spec.path is not None:
        spec = load_behavior(spec.path, frames=model.frame_names, joints=model.joint_names,
                             contacts=list(contacts))
    dimensions = robot_obj.dimensions()
    spec = _robot_defaults(spec, dimensions)
    if overrides:
        spec = _with_overrides(spec, overrides)
    factory = TaskFactory(model, contacts, robot_obj.q_standing, feet=robot_obj.feet)
    inputs_path = inputs if inputs is not None else spec.inputs_file
    stream = InputStream(spec.inputs, inputs_path)
    planner = None
    if spec.planner is not None:
        surface = robot_obj.contact(robot_obj.feet[0])
        planner = WalkPlanner(spec.planner.params, feet=robot_obj.feet,
                              foot_length=2 * surface.half_length,
                              foot_width=2 * surface.half_width, where=str(path))
    behavior = Behavior(spec, ctrl, factory, inputs=stream, planner=planner,
                        standing=robot_obj.q_standing, robot_values=dimensions)
    _check_for_controller(spec, behavior, ctrl, factory)
    return behavior, ctrl, robot_obj
