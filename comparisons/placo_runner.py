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
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from comparisons.common import DT, JOINT_VELOCITY_SCALE, Hierarchy, braking_acceleration
from hqp.controller import Command, FeasibilityReport
from hqp.robots import Robot


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


class PlacoController:
    """A PlaCo ``DynamicsSolver`` with the :class:`hqp.controller.Controller` step interface.

    Args:
        robot: The robot (its URDF is loaded by PlaCo).
        hierarchy: The scenario's levels of hqp tasks (centre of gravity,
            position and posture tasks are supported).

    Raises:
        HQPError: A task type PlaCo's mapping does not support.

    """

    def __init__(self, robot: Robot, hierarchy: Hierarchy,
                 config: PlacoConfig | None = None) -> None:
        import placo

        from hqp.errors import InvalidInput
        from hqp.tasks.com import CoMTask
        from hqp.tasks.orientation import OrientationTask
        from hqp.tasks.position import PositionTask
        from hqp.tasks.posture import PostureTask

        self.dt = DT
        self.stack = _EmptyStack()
        self.robot = placo.RobotWrapper(str(robot.urdf_path))
        self.model = robot.model()
        self.names = list(self.model.joint_names)
        self.solver = placo.DynamicsSolver(self.robot)
        self.solver.dt = DT
        cfg = config or PlacoConfig()
        self.config = cfg
        self.solver.mask_fbase(False)
        self.solver.enable_joint_limits(cfg.joint_limits)
        self.solver.enable_velocity_limits(True)
        self.solver.enable_torque_limits(True)
        if cfg.qdd_safe is not None:
            braking = (braking_acceleration(robot, self.model) if cfg.qdd_safe == "hqp"
                       else np.full(len(self.names), float(cfg.qdd_safe)))
            for name, qdd in zip(self.names, braking, strict=True):
                self.solver.set_qdd_safe(name, float(qdd))
        for name, vmax in zip(self.names, cfg.velocity_scale * self.model.v_max, strict=True):
            self.robot.set_velocity_limit(name, float(vmax))
        q = robot.q_standing
        self._set_state(q, np.zeros(self.model.nv))
        for name in robot.feet:
            surface = robot.contact(name)
            task = self.solver.add_frame_task(surface.frame, self.robot.get_T_world_frame(
                surface.frame))
            task.configure(f"{name}_frame", "hard", 1.0)
            contact = self.solver.add_planar_contact(task)
            contact.length = 2.0 * surface.half_length
            contact.width = 2.0 * surface.half_width
            contact.mu = surface.friction
            contact.weight_moments = cfg.weight_moments
        self._tracked: list[tuple[Any, Any, str]] = []  # (hqp task, placo task, kind)
        for k, (level, tasks) in enumerate(hierarchy.levels):
            first = k == 0 and len(tasks) == 1 and not isinstance(tasks[0], PostureTask)
            hard = first and cfg.hard_first
            for task in tasks:
                weight = cfg.first_weight if first and not hard else task.weight
                ref = task.reference  # type: ignore[attr-defined]
                if isinstance(task, CoMTask):
                    goal = np.zeros(3)
                    goal[: task.goal_size] = task.goal_at(0.0).position
                    goal[2] = self.robot.com_world()[2]
                    pt = self.solver.add_com_task(goal)
                    if task.horizontal:
                        pt.mask.set_axises("xy")
                    kind = "com"
                elif isinstance(task, PositionTask):
                    pt = self.solver.add_position_task(task.frame, task.goal_at(0.0).position)
                    kind = "position"
                elif isinstance(task, OrientationTask):
                    pt = self.solver.add_orientation_task(task.frame, task.goal_at(0.0).position)
                    pt.kp, pt.kd = ref.kp, ref.kv
                    pt.configure(task.name, "hard" if hard else "soft", weight)
                    self._tracked.append((task, pt, "orientation"))
                    continue
                elif isinstance(task, PostureTask):
                    pt = self.solver.add_joints_task()
                    goal = task.goal_at(0.0).position
                    pt.set_joints(dict(zip(task.joints, goal)))  # type: ignore[attr-defined]
                    pt.kp, pt.kd = ref.kp, ref.kv
                    pt.configure(task.name, "soft", cfg.posture_weight)
                    continue
                else:
                    raise InvalidInput(
                        f"PlacoController: no PlaCo mapping for {type(task).__name__}"
                    )
                pt.kp, pt.kd = 0.0, 0.0
                pt.configure(task.name, "hard" if hard else "soft", weight)
                self._tracked.append((task, pt, kind))
        self.hard_levels = [lv for k, (lv, ts) in enumerate(hierarchy.levels)
                            if cfg.hard_first and k == 0 and len(ts) == 1
                            and not isinstance(ts[0], PostureTask)]

    def _set_state(self, q: np.ndarray, v: np.ndarray) -> None:
        """Copy an hqp state (pinocchio convention, same URDF) into PlaCo's robot."""
        self.robot.state.q = np.array(q)
        self.robot.state.qd = np.array(v)
        self.robot.update_kinematics()

    def step(self, state: Any, t: float) -> Command:
        """One control step: set PlaCo's state and references, solve, return torques."""
        w0 = time.perf_counter()
        self._set_state(state.q, state.v)
        self.model.update(state.q, state.v)
        for task, pt, kind in self._tracked:
            sample = task.goal_at(t)
            if kind == "orientation":  # plain PD towards the (moving) goal, no saturation
                pt.R_world_frame = sample.position
                pt.omega_world = sample.velocity
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
            pt.ddtarget_world = acc  # kp = kd = 0: PlaCo's task acceleration is exactly this
        result = self.solver.solve(False)
        if result.success:  # (tau_dict of a failed solve crashes placo 0.10.2)
            tau_dict = result.tau_dict(self.robot)
            tau = np.array([tau_dict[n] for n in self.names])
            qdd = np.array(result.qdd)
        else:
            tau = np.zeros(len(self.names))
            qdd = np.zeros(self.model.nv)
        w1 = time.perf_counter()
        return Command(
            tau=tau,
            qdd=qdd,
            wrenches={},
            report=FeasibilityReport(notes=() if result.success else ("placo: solve failed",)),
            safe_mode=not result.success,
            timings={"total": w1 - w0},
            t=t,
        )


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
