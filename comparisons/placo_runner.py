"""PlaCo's ``DynamicsSolver`` (placo 0.10.2) on a scenario's hierarchy, as a controller.

:class:`PlacoController` loads the robot's URDF (``Robot.urdf_path``) in
``placo.RobotWrapper`` and sets PlaCo up the way its own humanoid example
(placo-examples ``dynamics/sigmaban.py``) and its documentation ("Joint,
velocity and torque limits", "Regularization") do (:class:`PlacoConfig`):

- both soles as planar contacts on hard frame tasks (unilateral, friction,
  centre of pressure within the sole), contact moments regularised with
  ``weight_moments = 1e-3`` as in the example;
- PlaCo's own joint-position, velocity and torque limits, all enabled, with
  its own joint-limit handling: its default safe acceleration ``qdd_safe``
  (1 rad/s^2) and the model's (URDF) velocity limits;
- the posture as a regularisation task of weight ``1e-6`` (the example's
  weight) and PlaCo's default torque regularisation (``torque_cost = 1e-3``).

Until issue 18 it got hqp's own joint-limit assumptions instead (the HQP
stack's braking acceleration as ``qdd_safe``, half the velocity limits) and a
posture of weight 1e-3: its QP became infeasible as soon as a joint outran
that envelope (1139 failed solves of 2000 in ``hand-reach cog-first``, 955
in ``shared``, and it fell in both). :data:`HQP_LIMITS` keeps that mapping
for comparison.

The scenario's tasks map onto PlaCo tasks:

- centre of gravity (horizontal) -> ``DynamicsCoMTask`` with an ``xy`` mask;
- frame position -> ``DynamicsPositionTask``;
- frame orientation -> ``DynamicsOrientationTask`` (PD without saturation);
- symmetry posture -> ``DynamicsJointsTask`` towards ``q_mid``.

PlaCo has two priorities, ``hard`` (equality constraints) and ``soft``
(weighted costs). A scenario level becomes hard when it is the first level
and holds a single task (``cog-first``: the centre of gravity), soft
otherwise with the task's weight (the example's centre of mass is soft with
weight 1 beside its trunk; with a soft centre of gravity ``cog-first``
becomes ``shared``). So a three-level hierarchy ``cog > hand > posture``
becomes ``cog`` hard, ``hand`` and ``posture`` traded by weights: the strict
priority of the hand over the posture cannot be expressed, and neither can
the posture's normalising matrix ``W`` (a ``JointsTask`` has one weight for
all its joints), nor an inequality below the top (PlaCo's inequalities are
all hard).

The PD law of eq. 27-28 is reproduced exactly, both saturations included:
PlaCo's task acceleration is ``kp (x_target - x) + kd (v_target - v) +
a_target``; hqp sets ``kp = kd = 0`` and ``a_target`` to the hqp task's own
reference acceleration (:class:`hqp.tasks.reference.PDReference`) at every
step, so every controller tracks the same references.

PlaCo (``placo==0.10.2`` pins ``pin==3.8.0``, hqp is on pinocchio 4) runs in a
worker process of its own environment (:mod:`hqp.bench.placo_worker`, driven
through :mod:`hqp.bench.worker`; ``python -m hqp.bench.peer_env placo`` makes
it, and ``hqp compare`` does so on first use). The references are computed
here, on hqp's model at the measured state, and sent with the state; a run's
``step_time_median_ms`` is that work plus PlaCo's step as the worker times it
(the pipe not counted: ``round_trip_median_ms`` and ``placo_step_median_ms``
give it apart).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from comparisons.common import DT, JOINT_VELOCITY_SCALE, Hierarchy, braking_acceleration
from hqp.bench.placo_step import WORKER
from hqp.bench.worker import start_setup
from hqp.controller import Command, FeasibilityReport
from hqp.errors import InvalidInput
from hqp.model import RobotModel
from hqp.robots import Robot
from hqp.tasks.com import CoMTask
from hqp.tasks.orientation import OrientationTask
from hqp.tasks.position import PositionTask
from hqp.tasks.posture import PostureTask


@dataclass(frozen=True)
class PlacoConfig:
    """How :class:`PlacoController` sets PlaCo's ``DynamicsSolver`` up (module docstring).

    The defaults are PlaCo's own configuration (its humanoid example and documentation).

    Attributes:
        qdd_safe: Safe joint acceleration of PlaCo's joint-limit rows [rad/s^2]: a number
            for every joint, ``"hqp"`` for the HQP stack's braking acceleration
            (:func:`comparisons.common.braking_acceleration`), ``None`` for PlaCo's default
            (1 rad/s^2, not set).
        velocity_scale: Fraction of the model's velocity limits given to PlaCo.
        hard_first: Whether a first level of a single task becomes a ``hard`` task
            (PlaCo's only strict priority); else it is ``soft`` with :attr:`first_weight`.
        first_weight: Weight of that first task when it is soft.
        posture_weight: Weight of the posture task.
        weight_moments: PlaCo's regularisation of the contact moments (``weight_moments`` of
            its planar contacts; 0: none).
        joint_limits: Whether PlaCo's joint-limit rows are on.

    """

    qdd_safe: float | str | None = None
    velocity_scale: float = 1.0
    hard_first: bool = True
    first_weight: float = 1.0
    posture_weight: float = 1e-6
    weight_moments: float = 1e-3
    joint_limits: bool = True


HQP_LIMITS = PlacoConfig(qdd_safe="hqp", velocity_scale=JOINT_VELOCITY_SCALE,
                         posture_weight=1e-3, weight_moments=0.0)
"""The mapping before issue 18: hqp's joint-limit assumptions handed to PlaCo (module
docstring); its QP becomes infeasible in the paper scenarios."""


class _EmptyStack:
    """What :func:`hqp.sim.run.simulate` reads of a controller's stack: no hqp tasks."""

    tasks: tuple = ()


def _kind(task: Any) -> str:
    """Return PlaCo's task kind of an hqp task (the worker's ``kind``).

    Raises:
        InvalidInput: A task type PlaCo's mapping does not support.

    """
    for cls, kind in ((CoMTask, "com"), (PositionTask, "position"),
                      (OrientationTask, "orientation"), (PostureTask, "joints")):
        if isinstance(task, cls):
            return kind
    raise InvalidInput(f"PlacoController: no PlaCo mapping for {type(task).__name__}")


def hierarchy_setup(robot: Robot, model: RobotModel, hierarchy: Hierarchy,
                    config: PlacoConfig) -> tuple[dict[str, Any], list[str]]:
    """Return the worker's ``setup`` request of a scenario's hierarchy, and its hard levels.

    The mapping of the module docstring: soles as planar contacts, the first level hard when
    it holds one task (not a posture) and ``config.hard_first``, every other task soft with its
    weight (the posture with ``config.posture_weight``); centre of gravity and position tasks
    with ``kp = kd = 0`` (their acceleration is sent at every step), orientation and posture
    tasks with the hqp task's own gains.

    Raises:
        InvalidInput: A task type PlaCo's mapping does not support.

    """
    names = list(model.joint_names)
    qdd_safe = None
    if config.qdd_safe is not None:
        qdd_safe = (braking_acceleration(robot, model) if config.qdd_safe == "hqp"
                    else np.full(len(names), float(config.qdd_safe))).tolist()
    contacts = [{"frame": robot.contact(name).frame, "name": f"{name}_frame",
                 "length": 2.0 * robot.contact(name).half_length,
                 "width": 2.0 * robot.contact(name).half_width,
                 "mu": robot.contact(name).friction, "weight_moments": config.weight_moments}
                for name in robot.feet]
    tasks: list[dict[str, Any]] = []
    hard_levels: list[str] = []
    for k, (level, level_tasks) in enumerate(hierarchy.levels):
        first = k == 0 and len(level_tasks) == 1 and _kind(level_tasks[0]) != "joints"
        hard = first and config.hard_first
        if hard:
            hard_levels.append(level)
        for task in level_tasks:
            kind = _kind(task)
            ref = task.reference  # type: ignore[attr-defined]
            spec: dict[str, Any] = {
                "name": task.name, "kind": kind, "frame": getattr(task, "frame", None),
                "priority": "hard" if hard else "soft",
                "weight": config.first_weight if first and not hard else task.weight,
                "kp": 0.0, "kd": 0.0, "target": None, "mask": None}
            goal = np.asarray(task.goal_at(0.0).position, dtype=float).tolist()
            if kind == "com":
                target: list[float | None] = [None, None, None]  # z: PlaCo's own height
                target[: len(goal)] = goal
                spec.update(target=target, mask="xy" if getattr(task, "horizontal") else None)
            elif kind == "position":
                spec["target"] = goal
            elif kind == "orientation":
                spec.update(target=goal, kp=ref.kp, kd=ref.kv)
            else:
                spec.update(target=dict(zip(getattr(task, "joints"), goal)), kp=ref.kp,
                            kd=ref.kv, priority="soft", weight=config.posture_weight)
            tasks.append(spec)
    setup = {
        "op": "setup", "urdf": str(robot.urdf_path), "ignore_collisions": False, "dt": DT,
        "q": np.asarray(robot.q_standing, dtype=float).tolist(), "joints": names,
        "q_lower": None, "q_upper": None, "tau_max": None, "qdd_safe": qdd_safe,
        "v_max": (config.velocity_scale * model.v_max).tolist(),
        "joint_limits": config.joint_limits, "velocity_limits": True, "torque_limits": True,
        "contacts": contacts, "tasks": tasks,
    }
    return setup, hard_levels


class PlacoController:
    """A PlaCo ``DynamicsSolver`` with the :class:`hqp.controller.Controller` step interface.

    PlaCo runs in a worker process of its own environment (:mod:`hqp.bench.placo_worker`;
    ``python -m hqp.bench.peer_env placo`` makes it); :meth:`close` stops it. Each step computes
    the tasks' references on hqp's side (the hqp tasks' own PD laws at the measured state) and
    sends them with the state; the worker solves and times its own step.

    Args:
        robot: The robot (its URDF is loaded by PlaCo).
        hierarchy: The scenario's levels of hqp tasks (centre of gravity,
            position, orientation and posture tasks are supported).
        config: How PlaCo is set up (default: its own configuration, :class:`PlacoConfig`).
        python: PlaCo's interpreter (default: :func:`hqp.bench.peer_env.env_python`).

    Raises:
        InvalidInput: A task type PlaCo's mapping does not support.
        PeerUnavailable: PlaCo's environment is missing or cannot run the worker.
        WorkerError: The worker could not set the robot up.

    """

    def __init__(self, robot: Robot, hierarchy: Hierarchy,
                 config: PlacoConfig | None = None, python: Path | None = None) -> None:
        self.dt = DT
        self.stack = _EmptyStack()
        self.model = robot.model()
        self.names = list(self.model.joint_names)
        self.config = config or PlacoConfig()
        setup, self.hard_levels = hierarchy_setup(robot, self.model, hierarchy, self.config)
        self._tracked: list[tuple[Any, str]] = []  # (hqp task, kind) sent at every step
        self._posture: dict[str, tuple[Any, np.ndarray]] = {}  # name: (hqp task, goal sent)
        for _, tasks in hierarchy.levels:
            for task in tasks:
                kind = _kind(task)
                if kind == "joints":
                    self._posture[task.name] = (task, np.array(task.goal_at(0.0).position))
                else:
                    self._tracked.append((task, kind))
        self.worker, info = start_setup("placo", WORKER, setup, python)
        self.placo_version: str = info["placo_version"]
        self.pinocchio_version: str = info["pinocchio_version"]
        self.step_time: list[float] = []
        """Each step's own time [s]: references on hqp's side plus PlaCo's step in the worker
        (the pipe not counted)."""
        self.placo_time: list[float] = []
        """Wall-clock time of PlaCo's step in the worker [s]."""

    def references(self, state: Any, t: float) -> dict[str, Any]:
        """Return the tasks' references at the measured state (the worker's ``refs``).

        Centre of gravity and position tasks: the hqp task's own reference acceleration
        (eq. 27-28, both saturations), PlaCo's ``ddtarget_world`` with ``kp = kd = 0``;
        orientation tasks: the goal's rotation and angular velocity (PlaCo's PD, without
        saturation); posture tasks: their goal, when it changed (``screwgun`` switches it to
        the work pose). The model is updated at ``state`` first.
        """
        self.model.update(state.q, state.v)
        refs: dict[str, Any] = {}
        for task, kind in self._tracked:
            sample = task.goal_at(t)
            if kind == "orientation":  # plain PD towards the (moving) goal, no saturation
                refs[task.name] = {"R": np.asarray(sample.position).tolist(),
                                   "omega": np.asarray(sample.velocity).tolist()}
                continue
            if kind == "com":
                m = task.goal_size
                x, xd = self.model.com[:m], self.model.com_velocity[:m]
            else:
                x = self.model.frame_placement(task.frame).translation
                xd = self.model.frame_velocity(task.frame)[:3]
            acc = np.zeros(3)
            acc[: x.size] = task.reference(x, xd, sample.position, sample.velocity,
                                           sample.acceleration)
            refs[task.name] = {"acceleration": acc.tolist()}
        for name, (task, sent) in self._posture.items():
            goal = np.asarray(task.goal_at(t).position)
            if not np.array_equal(goal, sent):
                refs[name] = {"joints": dict(zip(getattr(task, "joints"), goal.tolist()))}
                self._posture[name] = (task, goal.copy())
        return refs

    def step(self, state: Any, t: float) -> Command:
        """One control step: references, then PlaCo's state, references and solve (worker)."""
        w0 = time.perf_counter()
        refs = self.references(state, t)
        w1 = time.perf_counter()
        reply = self.worker.request({"op": "step", "q": np.asarray(state.q).tolist(),
                                     "v": np.asarray(state.v).tolist(), "refs": refs})
        success = bool(reply["success"])
        self.placo_time.append(float(reply["wall_s"]))
        self.step_time.append(w1 - w0 + float(reply["wall_s"]))
        return Command(
            tau=np.asarray(reply["tau"]),
            qdd=np.asarray(reply["qdd"]),
            wrenches={},
            report=FeasibilityReport(notes=() if success else ("placo: solve failed",)),
            safe_mode=not success,
            timings={"total": self.step_time[-1], "placo": float(reply["wall_s"])},
            t=t,
        )

    def metrics(self) -> dict[str, float | str | None]:
        """Return the worker's figures of the run: PlaCo's own step, the pipe's round trip [ms]."""
        def median_ms(xs: list[float]) -> float | None:
            return round(1e3 * float(np.median(xs)), 4) if xs else None

        return {"placo_step_median_ms": median_ms(self.placo_time),
                "round_trip_median_ms": median_ms(self.worker.round_trip[2:]),
                "placo_version": self.placo_version}

    def close(self) -> None:
        """Stop the worker."""
        self.worker.close()


def placo_note(controller: PlacoController, hierarchy: Hierarchy) -> str:
    """Say what PlaCo's hard/soft priorities cannot express of a hierarchy."""
    levels = [name for name, _ in hierarchy.levels]
    return (
        "PlaCo as its humanoid example sets it up (its own limits and regularisation); "
        f"it has hard/soft priorities only: of the levels {levels}, "
        f"{controller.hard_levels or 'none'} became hard, the rest soft (traded by weights); "
        "strict priority between soft levels, the posture's W and inequalities below the top "
        "are not expressible"
    )
