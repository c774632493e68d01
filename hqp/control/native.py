"""The native control step of a controller's stack (``hqp._core._ext.NativeStep``).

:func:`native_step` mirrors a :class:`~hqp.control.servo.WholeBodyController`'s stack into
the C++ core: one kernel per task, at the task's level and weight, in the stack's row order,
so that one call (:meth:`NativeStepMirror.step`) runs the model pass, every task's rows,
the strict hierarchy and the torques without Python in between. The Python tasks stay the
interface and the test oracle (``tests/test_core_step.py`` holds the two equal).

Supported today: the standing set (floating-base dynamics, contacts and their limits,
torque limits, viable joint limits with a fixed or support-dependent braking, CoG,
centroidal momentum, orientation, position and posture tasks) with fixed goals, in a
steady stack (no task ramping in, no contact unloading). Anything else raises
:class:`NotSupported`; the Python step is the path for it.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from hqp._core import _ext as _core_ext
from hqp.errors import HQPError
from hqp.robots.robot import ROOT_JOINT, Robot
from hqp.tasks.centroidal import CentroidalMomentumTask
from hqp.tasks.com import CoMTask
from hqp.tasks.contact import Contact, ContactLimits
from hqp.tasks.dynamics import FloatingBaseDynamics
from hqp.tasks.joint_limits import JointLimits
from hqp.tasks.orientation import OrientationTask
from hqp.tasks.position import PositionTask
from hqp.tasks.posture import PostureTask
from hqp.tasks.torque_limits import TorqueLimits


class NotSupported(HQPError):
    """A task or stack state the native step does not run (yet): use the Python step."""


def _gains(task: Any) -> tuple[float, float, float, float]:
    r = task.reference
    return r.kp, r.kv, r.max_velocity, r.max_acceleration


_NO_INT = np.zeros(0, dtype=np.int32)
_NO_SCALE = np.zeros(0)


class NativeStepMirror:
    """A controller's stack in the native core, and the goals pushed down each step.

    Args:
        robot: The bundled robot (its URDF and extra frames build the native model).
        controller: A controller with ``stack``, ``model``, ``layout`` and ``dt``.
        rank_tol: The solver's rank tolerance.
        warm_start: The solver's active-set warm start from the previous step.

    Raises:
        NotSupported: A task without a kernel, or a stack that is not steady.

    """

    def __init__(self, robot: Robot, controller: Any, rank_tol: float = 1e-9,
                 warm_start: bool = True) -> None:
        core = _core_ext
        stack, model, layout = controller.stack, controller.model, controller.layout
        self.dt = float(controller.dt)
        self.model = model
        self.stack = stack
        self._layout = layout
        frames = [(n, p, T.homogeneous) for n, (p, T) in robot.extra_frames.items()]
        slots = []
        robot_core = core.RobotCore(str(robot.urdf_path), ROOT_JOINT, frames)
        for slot in layout.contacts:
            slots.append((robot_core.frame_id(slot.frame), slot.kind.value, slot.start))
        self.step_core = core.NativeStep(str(robot.urdf_path), ROOT_JOINT, frames,
                                         model.nv_base, slots, stack.n_levels, rank_tol,
                                         warm_start, True)
        self._frame = robot_core.frame_id
        self._goals: list[tuple[int, Any, bool]] = []  # (handle, task, orientation)
        self._braking: list[tuple[int, JointLimits]] = []
        contacts: dict[str, int] = {}
        for task in stack.tasks:
            level = stack.level_of_task(task.name)
            self._add(core, task, level, contacts)

    def _add(self, core: Any, task: Any, level: int, contacts: dict[str, int]) -> None:
        s, w, model = self.step_core, task.weight, self.model
        if isinstance(task, FloatingBaseDynamics):
            s.add_dynamics(level, w)
        elif isinstance(task, Contact):
            kernel = core.ContactKernel(self._frame(task.frame), task.kind.value,
                                        self._slot_start(task), task.mu, task.half_length,
                                        task.half_width, task.f_min, task.max_normal_force,
                                        task.kp, task.kd)
            if not task.active:
                kernel.deactivate()
            elif task.reference is not None:
                kernel.activate(task.reference.homogeneous)
            contacts[task.name] = s.add_contact(level, w, kernel)
        elif isinstance(task, ContactLimits):
            s.add_contact_limits(level, w, contacts[task.contact.name])
        elif isinstance(task, TorqueLimits):
            s.add_torque_limits(level, w, np.asarray(task.bounds(model), dtype=float))
        elif isinstance(task, JointLimits):
            if task.qdd_max is None:  # A recomputed at every state: not pushed down (yet)
                raise NotSupported(f"{task.where()}: qdd_max=None (a state-dependent bound)")
            handle = s.add_joint_limits(
                level, w, model.q_lower + task.position_margin,
                model.q_upper - task.position_margin, task.velocity_scale * model.v_max,
                task.reserve, task.velocity_time, task.inactive_beyond, task.acceleration_bounds,
                np.asarray(task.max_acceleration(model), dtype=float),
                np.asarray(task.braking_deceleration(model), dtype=float))
            self._braking.append((handle, task))
        elif isinstance(task, OrientationTask):
            handle = s.add_orientation(level, w, core.OrientationTracking(
                self._frame(task.frame), *_gains(task)))
            self._goals.append((handle, task, True))
        elif isinstance(task, (PositionTask, CoMTask, PostureTask, CentroidalMomentumTask)):
            handle = s.add_tracking(level, w, self._tracking_kernel(core, task))
            self._goals.append((handle, task, False))
        else:
            raise NotSupported(f"{task.where()}: no native kernel for {type(task).__name__}")

    def _slot_start(self, task: Contact) -> int:
        return int(self._layout.contact(task.name).start)

    def _tracking_kernel(self, core: Any, task: Any) -> Any:
        scale = getattr(task, "scale", None)
        scale = _NO_SCALE if scale is None else np.asarray(scale, dtype=float)
        if isinstance(task, PositionTask):
            return core.VectorTracking("frame_position", self._frame(task.frame),
                                       np.asarray(task.axes, dtype=np.int32), _NO_INT, scale,
                                       *_gains(task))
        if isinstance(task, CoMTask):
            return core.VectorTracking("com", -1, np.arange(task.goal_size, dtype=np.int32),
                                       _NO_INT, scale, *_gains(task))
        if isinstance(task, CentroidalMomentumTask):
            return core.VectorTracking("centroidal", -1, task.components.astype(np.int32),
                                       _NO_INT, _NO_SCALE, *_gains(task))
        return core.VectorTracking("joints", -1, task._q_index.astype(np.int32),
                                   task._v_index.astype(np.int32), scale, *_gains(task))

    def push_goals(self, t: float) -> None:
        """Send every tracking task's goal at time ``t`` (and the joint-limit braking)."""
        s = self.step_core
        for handle, task, orientation in self._goals:
            if isinstance(task, CentroidalMomentumTask):
                g = task._goal if task.trajectory is None else task.trajectory.sample(t)
                s.set_goal(handle, g.position, g.velocity, np.zeros_like(g.velocity))
                continue
            g = task.goal_at(t)
            if orientation:
                s.set_orientation_goal(handle, g.position, g.velocity, g.acceleration)
            else:
                s.set_goal(handle, g.position, g.velocity, g.acceleration)
        for handle, task in self._braking:
            s.set_braking(handle, np.asarray(task.braking_deceleration(self.model), dtype=float))

    def step(self, q: np.ndarray, v: np.ndarray, t: float) -> tuple[np.ndarray, np.ndarray]:
        """One native step at ``(q, v)`` and time ``t``: ``(x, tau)``."""
        self.push_goals(t)
        self.step_core.step(q, v, self.dt)
        return self.step_core.x, self.step_core.tau
