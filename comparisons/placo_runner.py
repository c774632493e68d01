"""PlaCo's ``DynamicsSolver`` (placo 0.10.2) on a scenario's hierarchy, as a controller.

:class:`PlacoController` loads the robot's URDF (``Robot.urdf_path``) in
``placo.RobotWrapper``, declares both soles as planar contacts (hard frame
tasks, friction and centre-of-pressure limits), enables joint-position,
velocity and torque limits (PlaCo's own inequalities, with the braking
acceleration and velocity fraction of the HQP stack), and maps the
scenario's tasks onto PlaCo tasks:

- centre of gravity (horizontal) -> ``DynamicsCoMTask`` with an ``xy`` mask;
- frame position -> ``DynamicsPositionTask``;
- frame orientation -> ``DynamicsOrientationTask`` (PD without saturation);
- symmetry posture -> ``DynamicsJointsTask`` towards ``q_mid``.

PlaCo has two priorities, ``hard`` (equality constraints) and ``soft``
(weighted costs). A scenario level becomes hard when it is the first level
and holds a single task (``cog-first``: the centre of gravity), soft
otherwise with the task's weight; the posture is soft with weight
:data:`POSTURE_WEIGHT`. So a three-level hierarchy ``cog > hand > posture``
becomes ``cog`` hard, ``hand`` and ``posture`` traded by weights: the strict
priority of the hand over the posture cannot be expressed, and neither can
the posture's normalising matrix ``W`` (a ``JointsTask`` has one weight for
all its joints).

The PD law of eq. 27-28 is reproduced exactly, both saturations included:
PlaCo's task acceleration is ``kp (x_target - x) + kd (v_target - v) +
a_target``; hqp sets ``kp = kd = 0`` and ``a_target`` to the hqp task's own
reference acceleration (:class:`hqp.tasks.reference.PDReference`) at every
step.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from comparisons.common import DT, JOINT_VELOCITY_SCALE, Hierarchy, braking_acceleration
from hqp.controller import Command, FeasibilityReport
from hqp.robots import Robot

POSTURE_WEIGHT = 1e-3
"""Weight of the posture task relative to the operational tasks (weight 1)."""


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

    def __init__(self, robot: Robot, hierarchy: Hierarchy) -> None:
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
        self.solver.mask_fbase(False)
        self.solver.enable_joint_limits(True)
        self.solver.enable_velocity_limits(True)
        self.solver.enable_torque_limits(True)
        # The joint-limit assumptions of the HQP stack (comparisons.common.build_stack): the
        # same braking acceleration (PlaCo's qdd_safe, 1 rad/s^2 by default: the first
        # MuJoCo step's contact transient of ~1 rad/s at an ankle already made every QP
        # infeasible) and the same fraction of the velocity limits.
        for name, qdd, vmax in zip(self.names, braking_acceleration(robot, self.model),
                                   JOINT_VELOCITY_SCALE * self.model.v_max, strict=True):
            self.solver.set_qdd_safe(name, float(qdd))
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
        self._tracked: list[tuple[Any, Any, str]] = []  # (hqp task, placo task, kind)
        for k, (level, tasks) in enumerate(hierarchy.levels):
            hard = k == 0 and len(tasks) == 1 and not isinstance(tasks[0], PostureTask)
            for task in tasks:
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
                    pt.configure(task.name, "hard" if hard else "soft", task.weight)
                    self._tracked.append((task, pt, "orientation"))
                    continue
                elif isinstance(task, PostureTask):
                    pt = self.solver.add_joints_task()
                    goal = task.goal_at(0.0).position
                    pt.set_joints(dict(zip(task.joints, goal)))  # type: ignore[attr-defined]
                    pt.kp, pt.kd = ref.kp, ref.kv
                    pt.configure(task.name, "soft", POSTURE_WEIGHT)
                    continue
                else:
                    raise InvalidInput(
                        f"PlacoController: no PlaCo mapping for {type(task).__name__}"
                    )
                pt.kp, pt.kd = 0.0, 0.0
                pt.configure(task.name, "hard" if hard else "soft", task.weight)
                self._tracked.append((task, pt, kind))
        self.hard_levels = [lv for k, (lv, ts) in enumerate(hierarchy.levels)
                            if k == 0 and len(ts) == 1 and not isinstance(ts[0], PostureTask)]

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
        f"PlaCo has hard/soft priorities only: of the levels {levels}, "
        f"{controller.hard_levels or 'none'} became hard, the rest soft (traded by weights); "
        "strict priority between soft levels and the posture's W are not expressible"
    )
