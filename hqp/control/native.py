"""The native control step of a controller's stack (``hqp._core._ext.NativeStep``).

:func:`native_step` mirrors a :class:`~hqp.control.servo.WholeBodyController`'s stack into
the C++ core: one kernel per task, at the task's level and weight, in the stack's row order,
so that one call (:meth:`NativeStepMirror.step`) runs the model pass, every task's rows,
the strict hierarchy and the torques without Python in between. The Python tasks stay the
interface and the test oracle (``tests/test_core_step.py`` holds the two equal).

Supported today: the standing set (floating-base dynamics, contacts and their limits,
torque limits, viable joint limits with a fixed or support-dependent braking, CoG,
centroidal momentum, orientation, position and posture tasks, the contact-force
regularisation), gaze, pose and hybrid force/position tasks, internal forces, obstacle
avoidance and self-collision (capsule distances), minimum effort, the centre of pressure, with
goals and trajectories, contacts made and released, in a steady stack (no task ramping in,
no contact unloading, no torque blend; :meth:`hqp.stack.Stack.steady`). Anything else
raises :class:`NotSupported` (a task without a kernel) or is left to the Python step for that
step (a stack that is not steady).

:class:`NativeEngine` is what a :class:`~hqp.control.servo.WholeBodyController` runs: the
mirror of its stack, rebuilt when the stack's structure or a task's parameters change, and
the command of a steady step with its feasibility report (the report's statuses computed by
:class:`~hqp.control.diagnostics.Diagnostics` from the native levels, the one place they are
computed).
"""

from __future__ import annotations

import math
import operator
import os
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from hqp._core import _ext as _core_ext
from hqp.control.command import Feasibility, TaskStatus
from hqp.control.diagnostics import Diagnostics
from hqp.errors import HQPError
from hqp.model.layout import ContactType
from hqp.robots.robot import ROOT_JOINT, Robot
from hqp.solver.level import Level
from hqp.solver.solution import LevelReport, Solution
from hqp.stack import BuiltStack, TaskSpan
from hqp.tasks.base import Edits, Rows
from hqp.tasks.centroidal import CentroidalMomentumTask
from hqp.tasks.collision import ObstacleAvoidance, SelfCollision
from hqp.tasks.com import CoMTask
from hqp.tasks.contact import Contact, ContactLimits
from hqp.tasks.cop import CoPTask
from hqp.tasks.dynamics import FloatingBaseDynamics
from hqp.tasks.effort import EffortTask, ForceRegularization
from hqp.tasks.gaze import GazeTask
from hqp.tasks.hybrid import HybridTask
from hqp.tasks.internal_forces import COMPONENTS, InternalForcesTask
from hqp.tasks.joint_limits import JointLimits
from hqp.tasks.orientation import OrientationTask
from hqp.tasks.pose import PoseTask
from hqp.tasks.position import PositionTask
from hqp.tasks.posture import PostureTask
from hqp.tasks.torque_limits import TorqueLimits
from hqp.tasks.tracking import TrackingTask

RATE_TASK = "torque_rate"
"""Name of the servo's torque-rate level's rows in the report (``WholeBodyController``)."""


class NotSupported(HQPError):
    """A task or stack state the native step does not run (yet): use the Python step."""


def _gains(task: Any) -> tuple[float, float, float, float]:
    r = task.reference
    return r.kp, r.kv, r.max_velocity, r.max_acceleration


_NO_INT = np.zeros(0, dtype=np.int32)
_NO_SCALE = np.zeros(0)


_FRAME_MODELS: dict[tuple[Any, ...], Any] = {}


def _frame_model(core: Any, urdf: str, frames: list[tuple[str, str, np.ndarray]]) -> Any:
    """Return the core's model of a robot, for its frame indices: one per description and module."""
    key = (core, urdf, os.stat(urdf).st_mtime_ns) + tuple((n, p, T.tobytes())
                                                          for n, p, T in frames)
    model = _FRAME_MODELS.get(key)
    if model is None:
        model = _FRAME_MODELS[key] = core.RobotCore(urdf, ROOT_JOINT, frames)
    return model


class NativeStepMirror:
    """A controller's stack in the native core, and the goals pushed down each step.

    Args:
        robot: The bundled robot (its URDF and extra frames build the native model).
        controller: A controller with ``stack``, ``model``, ``layout`` and ``dt``.
        rank_tol: The solver's rank tolerance.
        warm_start: The solver's active-set warm start from the previous step.
        core: The extension module to build the step from (default ``hqp._core._ext``; the
            no-allocation test passes ``hqp._core._ext_checked``).

    Raises:
        NotSupported: A task without a kernel, or a stack that is not steady.

    """

    def __init__(self, robot: Robot, controller: Any, rank_tol: float = 1e-9,
                 warm_start: bool = True, core: Any = None) -> None:
        core = _core_ext if core is None else core
        stack, model, layout = controller.stack, controller.model, controller.layout
        self.dt = float(controller.dt)
        self.model = model
        self.stack = stack
        self._layout = layout
        frames = [(n, p, T.homogeneous) for n, (p, T) in robot.extra_frames.items()]
        slots = []
        robot_core = _frame_model(core, str(robot.urdf_path), frames)
        for slot in layout.contacts:
            slots.append((robot_core.frame_id(slot.frame), slot.kind.value, slot.start))
        # the servo's torque-rate level (max_torque_rate): a level of its own after the stack
        # level _rate_after, as WholeBodyController._with_rate_level inserts it
        rate = getattr(controller, "max_torque_rate", None)
        self._rate_at: int | None = None  # its native level
        self._rate_index = 0  # the stack level index it reports (as the Python step)
        if rate is not None:
            after = int(controller._rate_after)
            self._rate_at, self._rate_index = after + 1, max(after, 0)
        self.step_core = core.NativeStep(str(robot.urdf_path), ROOT_JOINT, frames,
                                         model.nv_base, slots,
                                         stack.n_levels + (rate is not None), rank_tol,
                                         warm_start, True)
        self._frame = robot_core.frame_id
        self._goals: list[tuple[int, Any, str]] = []  # (handle, task, goal kind)
        self._braking: list[tuple[int, JointLimits]] = []
        self._internal: list[tuple[int, InternalForcesTask, int]] = []  # (handle, task, rows)
        self._cops: list[tuple[int, CoPTask]] = []
        # (handle, task, obstacles or None, pair names)
        self._distances: list[tuple[int, Any, list[Any] | None, tuple[str, ...]]] = []
        self._contacts: dict[str, int] = {}
        self._names: list[str] = []  # task name by handle
        self._entries: list[tuple[Any, ...]] | None = None  # row placement, after a step
        self._report_order: list[tuple[int, tuple[Any, ...]]] | None = None
        self._reported: np.ndarray | None = None
        self._reported_names: list[str] = []
        feasibility = getattr(controller, "feasibility", None)
        self._report_settings: tuple[float, float, bool] | None = None
        if feasibility is not None:
            self._report_settings = (feasibility.tolerance, feasibility.singular_tolerance,
                                     feasibility.full)
            self.step_core.set_report(*self._report_settings)
        self.step_core.set_work_budget(int(getattr(controller, "work_budget", None) or 0))
        for task in stack.tasks:
            level = self._native_level(stack.level_of_task(task.name))
            self._add(core, task, level, self._contacts)
            self._names.append(task.name)
        for k, threshold in enumerate(stack.weak_thresholds):
            if threshold:
                self.step_core.set_weak_threshold(self._native_level(k), threshold)
        self._rate_handle: int | None = None
        self._rate_bounds = np.empty((2, model.na))  # (lower, upper) torques pushed down
        if self._rate_at is not None:
            self._rate_handle = self.step_core.add_torque_rate(self._rate_at, 1.0)
            self._names.append(RATE_TASK)
        model_errors = [t for t in stack.tasks if isinstance(t, (Contact, JointLimits))]
        # the tasks whose errors the step leaves in its kernels (a handle) or in the model
        self._error_tasks = [task for _h, task, _k in self._goals] + model_errors
        self._error_handles: dict[int, int | None] = {
            id(task): handle for handle, task, _k in self._goals}
        self._error_handles.update((id(task), None) for task in model_errors)
        self._source: ErrorSource | None = None  # (record_errors)
        self._contact_tasks = [t for t in stack.tasks if isinstance(t, Contact)]
        self._handles = {task.name: h for h, task in enumerate(stack.tasks)}
        self._f_max = {t.name: float(t.max_normal_force) for t in self._contact_tasks}
        self._ramped: dict[int, Any] = {}  # handle -> the offsets pushed (a ramp running)
        self._recording: list[tuple[int, Any]] = []  # (handle, stack entry) recorded this step
        self._pushed_goals: list[Any] = [None] * len(self._goals)  # the samples pushed last
        self._braking_keys: list[Any] = [None] * len(self._braking)
        self._pushed: dict[str, tuple[bool, Any]] = {
            t.name: (t.active, None if t.reference is None else t.reference.homogeneous.copy())
            for t in stack.tasks if isinstance(t, Contact)}

    def resume(self) -> None:
        """Take the mirror up again after another one ran (:attr:`NativeEngine.KEPT`).

        Its tasks' errors are fetched from it again (the other mirror's source had them).
        """
        self._source = None

    def _native_level(self, level: int) -> int:
        """Return the native level of stack level ``level`` (after the torque-rate level)."""
        return level + (self._rate_at is not None and level >= self._rate_at)

    def stack_level(self, level: int) -> int:
        """Return the stack level index a native level reports (the inverse of the above)."""
        if self._rate_at is None or level < self._rate_at:
            return level
        return self._rate_index if level == self._rate_at else level - 1

    @property
    def has_torque_rate(self) -> bool:
        """Whether the mirror holds the servo's torque-rate level."""
        return self._rate_handle is not None

    def set_torque_rate(self, tau_ref: np.ndarray | None, delta: np.ndarray) -> None:
        """Bound the next step's torques to ``tau_ref +- delta`` (the torque-rate level).

        ``tau_ref=None`` (the first step): unbounded.

        Raises:
            NotSupported: The mirror was built without the level.

        """
        if self._rate_handle is None:
            raise NotSupported("the mirror was built without the torque-rate level")
        lo, up = self._rate_bounds
        if tau_ref is None:
            lo.fill(-np.inf)
            up.fill(np.inf)
        else:
            np.subtract(tau_ref, delta, out=lo)
            np.add(tau_ref, delta, out=up)
        self.step_core.set_torque_rate(self._rate_handle, lo, up)

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
                np.asarray(task.braking_deceleration(model), dtype=float), task.approach_time,
                np.asarray(task.recovery_deceleration(model), dtype=float))
            self._braking.append((handle, task))
        elif isinstance(task, OrientationTask):
            handle = s.add_orientation(level, w, core.OrientationTracking(
                self._frame(task.frame), *_gains(task)))
            self._goals.append((handle, task, "orientation"))
        elif isinstance(task, (PositionTask, CoMTask, PostureTask, CentroidalMomentumTask)):
            handle = s.add_tracking(level, w, self._tracking_kernel(core, task))
            self._goals.append((handle, task, "momentum" if isinstance(
                task, CentroidalMomentumTask) else "vector"))
        elif isinstance(task, GazeTask):
            handle = s.add_gaze(level, w, core.GazeKernel(
                self._frame(task.frame), task.axis, task._P, *_gains(task)))
            self._goals.append((handle, task, "vector"))
        elif isinstance(task, PoseTask):  # and HybridTask
            handle = s.add_pose(level, w, self._pose_kernel(core, task))
            self._goals.append((handle, task, "hybrid" if isinstance(task, HybridTask)
                                else "pose"))
        elif isinstance(task, InternalForcesTask):
            handle = s.add_internal_forces(level, w, self._internal_kernel(core, task))
            self._internal.append((handle, task, len(task.components(self._layout))))
        elif isinstance(task, (ObstacleAvoidance, SelfCollision)):
            self._add_distance(core, task, level)
        elif isinstance(task, CoPTask):
            try:
                slots = task._slots(self._layout)
            except HQPError:
                raise NotSupported(f"{task.where()}: contacts the Python step refuses") from None
            kernel = core.CoPKernel(
                [(self._frame_of(task, c.frame), c.size, c.start) for c in slots],
                math.nan if task.height is None else task.height, task._scale)
            self._cops.append((s.add_cop(level, w, kernel), task))
        elif isinstance(task, EffortTask):
            if task._w.shape != (model.na,):
                raise NotSupported(f"{task.where()}: built for another robot")
            s.add_effort(level, w, np.asarray(task._w, dtype=float))
        elif isinstance(task, ForceRegularization):  # rows of the layout alone
            rows = task.rows(model, self._layout, self.dt, 0.0)
            s.add_constant(level, w, np.asarray(rows.A, dtype=float),
                           np.asarray(rows.b, dtype=float))
        else:
            raise NotSupported(f"{task.where()}: no native kernel for {type(task).__name__}")

    def _frame_of(self, task: Any, frame: str) -> int:
        """Return the native frame index (a frame the model lacks: the Python step raises)."""
        fid = self._frame(frame)
        if fid < 0:
            raise NotSupported(f"{task.where()}: frame {frame!r} is not in the model")
        return int(fid)

    def _pose_kernel(self, core: Any, task: PoseTask) -> Any:
        linear, angular = np.arange(3), np.arange(3)
        force_start, force_index = 0, _NO_INT
        if isinstance(task, HybridTask):
            try:
                slot = self._layout.contact(task.contact)
            except HQPError:
                raise NotSupported(f"{task.where()}: contact not in the layout") from None
            point = slot.kind is not ContactType.SURFACE
            if slot.frame != task.frame or (point and np.any(task._force_index >= 3)):
                raise NotSupported(f"{task.where()}: rows the Python step refuses")
            linear = task._linear
            angular = task._angular if not point else np.zeros(0, dtype=int)
            force_start, force_index = int(slot.start), task._force_index
        ang = task.angular_reference
        return core.PoseKernel(self._frame_of(task, task.frame), linear.astype(np.int32),
                               angular.astype(np.int32), isinstance(task, HybridTask),
                               *_gains(task), ang.max_velocity, ang.max_acceleration,
                               force_start, np.asarray(force_index, dtype=np.int32))

    def _internal_kernel(self, core: Any, task: InternalForcesTask) -> Any:
        try:
            s1, s2 = task._slots(self._layout)
            components = task.components(self._layout)
        except HQPError:
            raise NotSupported(f"{task.where()}: contacts the Python step refuses") from None
        names = COMPONENTS if s1.size == 6 else ("tension",)
        index = np.array([names.index(c) for c in components], dtype=np.int32)
        return core.InternalForcesKernel(self._frame_of(task, s1.frame), s1.size, s1.start,
                                         self._frame_of(task, s2.frame), s2.start, index)

    def _add_distance(self, core: Any, task: Any, level: int) -> None:
        kernel = core.DistanceKernel(task.d_safe, task.d_influence, task.xi,
                                     0.0 if task.kv is None else task.kv)
        names: list[str] = []
        obstacles: list[Any] | None = None
        if isinstance(task, SelfCollision):
            for a, b in task.pairs:
                kernel.add_pair(self._frame_of(task, a.frame), a.point_a, a.point_b, a.radius,
                                self._frame_of(task, b.frame), b.point_a, b.point_b, b.radius)
                names.append(task.pair_name(a.name, b.name))
        else:
            try:
                obstacles = task.selected_obstacles()
            except HQPError:
                raise NotSupported(f"{task.where()}: obstacles the Python step refuses") from None
            for p in task.proxies:
                frame = self._frame_of(task, p.frame)
                for k, o in enumerate(obstacles):
                    kernel.add_obstacle_pair(frame, p.point_a, p.point_b, p.radius, k)
                    names.append(task.pair_name(p.name, o.name))
        handle = self.step_core.add_distance(level, task.weight, kernel)
        self._distances.append((handle, task, obstacles, tuple(names)))

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
        """Send every goal that is a new sample at time ``t`` (and the per-step inputs).

        A goal held (``set_goal``) is pushed once: the kernel keeps it until the task holds
        another sample; a trajectory is sampled at every step. The internal forces', centres
        of pressure's and obstacles' inputs are pushed at every step.

        Raises:
            InvalidInput: A goal the Python step refuses too (same message).

        """
        s = self.step_core
        pushed = self._pushed_goals
        for i, (handle, task, kind) in enumerate(self._goals):
            trajectory = task._trajectory
            if trajectory is None:
                if task._goal is pushed[i] and kind != "hybrid":
                    continue  # the same (read-only) goal as the last push: in the kernel
            elif trajectory is pushed[i]:
                continue  # a bundled trajectory's end, held: pushed when it was reached
            if kind == "momentum":
                g = task._goal if trajectory is None else trajectory.sample(t)
                pushed[i] = g
                s.set_goal(handle, g.position, g.velocity, np.zeros_like(g.velocity))
                continue
            # a bundled trajectory's samples are checked once (TrackingTask.goal_at)
            g = trajectory.sample(t) if trajectory is not None and task._trusted \
                else task.goal_at(t)
            # after a bundled trajectory's end its sample is the goal held at rest, for ever
            pushed[i] = trajectory if (trajectory is not None and task._trusted and kind !=
                                       "hybrid" and t - trajectory.t0 >= trajectory.duration
                                       ) else g
            if kind == "orientation":
                s.set_orientation_goal(handle, g.position, g.velocity, g.acceleration)
            elif kind == "vector":
                s.set_goal(handle, g.position, g.velocity, g.acceleration)
            else:  # a pose, a hybrid task's pose and force
                s.set_pose_goal(handle, g.position, g.velocity, g.acceleration)
                if kind == "hybrid":
                    s.set_force(handle, task._force)
        for handle, task, rows in self._internal:
            s.set_internal_goal(handle, task.goal_of(rows))
        for handle, task in self._cops:
            s.set_cop_goal(handle, task.goal_at(t))
        for handle, _task, obstacles, _names in self._distances:
            for k, o in enumerate(obstacles or ()):
                a, b = o.segment
                s.set_obstacle(handle, k, a, b, o.velocity, o.radius)

    def push_parameters(self) -> None:
        """Send what changes with the stack's state: joint-limit braking, contact force bounds.

        The braking of each joint-limit kernel, recomputed where what it depends on changed
        (the supports, the bound's arrays); the normal-force bound of each contact (lowered
        while it unloads). Called when the edit count moved (:class:`~hqp.tasks.base.Edits`).
        """
        s = self.step_core
        for i, (handle, task) in enumerate(self._braking):
            qdd = task.qdd_max
            key = (task._active_frames, task.airborne_braking, task.support_braking,
                   None if qdd is None else qdd.tobytes(), task.braking
                   if task.braking is None or np.isscalar(task.braking)
                   else np.asarray(task.braking).tobytes())
            if key == self._braking_keys[i]:
                continue
            self._braking_keys[i] = key
            s.set_braking(handle, np.asarray(task.braking_deceleration(self.model), dtype=float))
        f_max = self._f_max
        for task in self._contact_tasks:  # an unloading contact's bound falls step by step
            f = task.max_normal_force
            if f != f_max[task.name]:
                s.contact(self._contacts[task.name]).set_max_normal_force(f)
                f_max[task.name] = f

    def sync_ramps(self, ramping: list[Any], t: float, x_prev: np.ndarray | None) -> None:
        """Push the ramps of the tasks ramping in at ``t`` (``Stack.advance_native``).

        Each ramping kernel's rows keep ``1 - s`` of its offsets (``NativeStep.set_ramp``);
        offsets not recorded yet are recorded by the step from its own rows at ``x_prev``
        (``None``: zeros; given back to the stack by :meth:`collect_ramps`), offsets recorded
        by a Python step are pushed down. A kernel whose ramp ended gets its own rows again.
        """
        core = self.step_core
        self._recording.clear()
        running = set()
        for entry in ramping:
            h = self._handles[entry.task.name]
            running.add(h)
            core.set_ramp(h, self.stack.ramp_keep(entry, t))
            if entry.offsets is None:
                x = x_prev if x_prev is not None and np.isfinite(x_prev).all() else \
                    np.zeros(core.n)
                core.record_ramp(h, x)
                self._recording.append((h, entry))
                self._ramped[h] = None
            elif self._ramped.get(h) is not entry.offsets:
                sizes = [d.size for d in core.ramp_offsets(h)]
                core.set_ramp_offsets(h, *(np.zeros(k) if d is None else d
                                           for d, k in zip(entry.offsets, sizes)))
                self._ramped[h] = entry.offsets
        for h in [h for h in self._ramped if h not in running]:
            core.set_ramp(h, 0.0)
            del self._ramped[h]

    def collect_ramps(self) -> None:
        """Give the ramp offsets recorded by the last step to the stack's entries."""
        for h, entry in self._recording:
            entry.offsets = tuple(d if d.size else None for d in self.step_core.ramp_offsets(h))
            self._ramped[h] = entry.offsets
        self._recording.clear()

    def sync_contacts(self) -> bool:
        """Push each contact's activation and stabilisation reference to its kernel.

        Returns:
            False when a contact is active with its reference still to be captured (the
            Python step captures it at its next rows); True otherwise.

        """
        for task in self._contact_tasks:
            if task.active and task.reference is None and task.kp > 0.0:
                return False
            ref = None if task.reference is None else task.reference.homogeneous
            active, pushed = self._pushed[task.name]
            if active == task.active and (
                    (ref is None and pushed is None)
                    or (ref is not None and pushed is not None and np.array_equal(ref, pushed))):
                continue
            kernel = self.step_core.contact(self._contacts[task.name])
            if not task.active:
                kernel.deactivate()
            elif ref is None:
                kernel.activate()
            else:
                kernel.activate(ref)
            self._pushed[task.name] = (task.active, None if ref is None else ref.copy())
        return True

    def step(self, q: np.ndarray, v: np.ndarray, t: float) -> tuple[np.ndarray, np.ndarray]:
        """One native step at ``(q, v)`` and time ``t``: ``(x, tau)``.

        Raises:
            RuntimeError: The solve failed (the message says why).

        """
        self.push_goals(t)
        self.step_core.step(q, v, self.dt)
        return self.step_core.x, self.step_core.tau

    def record_errors(self, controller: Any = None) -> None:
        """Give each task the error of the last native step (what ``Task.error()`` returns).

        From its kernel; for a contact and the joint limits, from the Python model at the
        state (logs and behaviors read them). With the ``controller`` that ran the step, a
        task's error is fetched when the task's ``error()`` is first called after the step
        (``Task._fetch_error``, through this mirror's :class:`ErrorSource` for that
        controller: a control loop that reads none pays for none); the distances' errors
        (and their pair names, an attribute) are recorded at once.
        """
        core = self.step_core
        for handle, task, _obstacles, names in self._distances:
            task.record_error(core.margins(handle), names)
        if controller is None:
            for task in self._error_tasks:
                self.record_error(task)
            return
        source = self._source
        if source is None or source.controller is not controller:
            source = self._source = ErrorSource(self, controller)
            for task in self._error_tasks:
                task._error_source = source
        source.serial = controller.step_serial

    def quantity(self, name: str) -> np.ndarray | None:
        """Return a quantity of the last step's model pass (``RobotModel.provide``).

        ``"com"`` or ``"com_velocity"``; ``None`` for a quantity the core does not give.
        """
        if name == "com":
            return self.step_core.com_state()[0]
        if name == "com_velocity":
            return self.step_core.com_state()[1]
        return None

    def record_error(self, task: Any) -> None:
        """Record one task's error of the last native step (see :meth:`record_errors`)."""
        handle = self._error_handles[id(task)]
        if handle is None:
            task.record_error(self.model)
            return
        e, rate = self.step_core.kernel_error(handle)
        task.record_error(rate if isinstance(task, CentroidalMomentumTask) else e)

    def report(self, diagnostics: Diagnostics) -> tuple[
            Callable[[], tuple[TaskStatus, ...]], np.ndarray, None]:
        """Return the last step's task statuses (a function of none), level costs and ``None``.

        The statuses, each kernel's ``sigma_min`` and the level a conflict yields to were
        computed by the core inside the step (``NativeStep.report``: the projected singular
        values and the bisection over the bases of the optimal sets above, as
        :class:`~hqp.control.diagnostics.Diagnostics` defines them); here they are copied
        out, and the :class:`TaskStatus` objects made when the report's ``tasks`` are first
        read.
        """
        core = self.step_core
        if self._report_order is None:  # by built level, as Stack.build's spans
            self._report_order = sorted(enumerate(self._placements()), key=lambda e: e[1][2])
        settings = (diagnostics.tolerance, diagnostics.singular_tolerance,
                    diagnostics.mode == "full")
        if settings != self._report_settings:  # changed since the step: computed again
            core.set_report(*settings)
            core.compute_report()
            self._report_settings = settings
        costs, level_sigma, weak, residuals = core.report_data()
        codes, sigmas, yields = core.report_arrays()
        return _NativeStatuses(self, residuals, codes, sigmas, yields, weak), costs, None

    def reported_handles(self) -> np.ndarray:
        """Return the handles of the kernels with rows in the levels (:meth:`_statuses`')."""
        if self._reported is None:
            assert self._report_order is not None
            self._reported = np.array(
                [h for h, (_k, _l, built, _e0, neq, _i0, nin, _w) in self._report_order
                 if neq + nin and built >= 0], dtype=np.intp)
            self._reported_names = [self._names[h] for h in self._reported]
        return self._reported

    def reported_names(self) -> list[str]:
        """Names of :meth:`reported_handles`, in order."""
        self.reported_handles()
        return self._reported_names

    def _placements(self) -> list[tuple[Any, ...]]:
        """Return where each kernel's rows sit (``NativeStep.entry``, handle order)."""
        if self._entries is None:
            self._entries = [self.step_core.entry(h) for h in range(len(self._names))]
        return self._entries

    def built(self) -> tuple[BuiltStack, Solution]:
        """Return the last step's levels, task rows and solver reports, as Python has them.

        The rows of each task are its kernel's rows in the native levels divided by
        ``sqrt(weight)`` (unweighted, as :class:`~hqp.stack.BuiltStack` holds them).
        """
        core = self.step_core
        n = core.n
        raw = core.levels()
        weak = core.weak_directions()
        levels, reports, index = [], [], []
        names = self.stack.level_names
        for k, (level, A, b, C, lo, up) in enumerate(raw):
            cost, sigma, state = core.result(k)
            name = RATE_TASK if level == self._rate_at else names[self.stack_level(level)]
            levels.append(Level(A=A if A.shape[0] else None, b=b if A.shape[0] else None,
                                C=C if C.shape[0] else None, lower=lo if C.shape[0] else None,
                                upper=up if C.shape[0] else None, name=name,
                                weak_threshold=core.weak_threshold(level)))
            reports.append(LevelReport(name, cost, True, np.flatnonzero(state > 0),
                                       np.flatnonzero(state > 1), sigma, np.zeros(0),
                                       np.zeros(0), int(weak[k])))
            index.append(self.stack_level(level))
        spans, rows = [], {}
        for name, (_kind, level, built, eq0, neq, in0, nin, sqrt_w) in zip(
                self._names, self._placements()):
            if neq + nin == 0 or built < 0:
                continue
            _lv, A, b, C, lo, up = raw[built]
            rows[name] = Rows(
                A=A[eq0:eq0 + neq] / sqrt_w if neq else None,
                b=b[eq0:eq0 + neq] / sqrt_w if neq else None,
                C=C[in0:in0 + nin] / sqrt_w if nin else None,
                lower=lo[in0:in0 + nin] / sqrt_w if nin else None,
                upper=up[in0:in0 + nin] / sqrt_w if nin else None)
            if name == RATE_TASK and level == self._rate_at:  # the servo's own level
                spans.append(TaskSpan(name, self._rate_index, built, slice(0, 0),
                                      slice(in0, in0 + nin), 1.0, 1.0, True))
                continue
            spans.append(TaskSpan(name, self.stack_level(level), built, slice(eq0, eq0 + neq),
                                  slice(in0, in0 + nin), self.stack.task(name).weight))
        spans.sort(key=lambda s: s.built_level)
        solution = Solution(np.array(core.x), tuple(reports), backend="native",
                            algorithm="basis", qp_count=core.qp_count)
        return BuiltStack(levels, tuple(index), tuple(spans), rows, n), solution


_FEASIBILITY = (Feasibility.SATISFIED, Feasibility.CONFLICT, Feasibility.SINGULAR)
"""The core's status codes 0, 1, 2 (``NativeStep.report_arrays``)."""


class _NativeStatuses:
    """The statuses of one native step, made from the core's report when first called."""

    __slots__ = ("mirror", "residuals", "codes", "sigmas", "yields", "weak")

    def __init__(self, mirror: NativeStepMirror, residuals: np.ndarray, codes: np.ndarray,
                 sigmas: np.ndarray, yields: np.ndarray, weak: np.ndarray) -> None:
        self.mirror = mirror
        self.residuals = residuals
        self.codes = codes
        self.sigmas = sigmas
        self.yields = yields
        self.weak = weak

    def status(self, handle: int) -> TaskStatus:
        """Return the status of one reported kernel."""
        mirror = self.mirror
        _kind, level, built_level, *_ = mirror._placements()[handle]
        y = int(self.yields[handle])
        return TaskStatus(mirror._names[handle], mirror.stack_level(level),
                          _FEASIBILITY[int(self.codes[handle])], float(self.residuals[handle]),
                          None if y < 0 else mirror.stack_level(y), float(self.sigmas[handle]),
                          int(self.weak[built_level]))

    def __call__(self) -> tuple[TaskStatus, ...]:
        return tuple(self.status(h) for h in self.mirror.reported_handles().tolist())

    def any_conflict(self) -> bool:
        """Whether a reported kernel is in conflict."""
        return bool(np.any(self.codes[self.mirror.reported_handles()] == 1))

    def names(self) -> list[str]:
        """Return the names of the statuses, in their order."""
        return self.mirror.reported_names()

    def conflicts(self) -> list[TaskStatus]:
        """Return the statuses of the kernels in conflict alone."""
        handles = self.mirror.reported_handles()
        return [self.status(h) for h in handles[self.codes[handles] == 1].tolist()]


def error_norms(tasks: Sequence[Any]) -> np.ndarray:
    """Norm of each task's :meth:`~hqp.tasks.base.Task.error` (``inf`` where it is empty).

    What ``np.linalg.norm(task.error())`` gives, without fetching each error: the tasks whose
    error waits in a native step (:class:`ErrorSource`) are read in one call per step
    (``NativeStep.error_norms``); the others through ``error()``. A behavior records every
    active task's error at every step.
    """
    out = np.empty(len(tasks))
    norms: dict[int, tuple[np.ndarray, np.ndarray]] = {}
    for i, task in enumerate(tasks):
        source = task._error_source
        if source is not None and source.controller.step_serial == source.serial:
            mirror = source.mirror
            handle = mirror._error_handles.get(id(task))
            if handle is not None:
                pair = norms.get(id(mirror))
                if pair is None:
                    pair = norms[id(mirror)] = mirror.step_core.error_norms()
                out[i] = pair[1 if isinstance(task, CentroidalMomentumTask) else 0][handle]
                continue
        err = np.asarray(task.error(), dtype=float).ravel()
        out[i] = math.sqrt(float(err @ err)) if err.size else math.inf
    return out


class ErrorSource:
    """Where the tasks of a native step fetch that step's error when it is first read.

    The tasks of a mirror hold it (``Task._error_source``) from the first step the mirror
    runs for a controller; its ``serial`` is the controller's ``step_serial`` of the last
    such step. ``Task._fetch_error`` calls :meth:`fetch` once per ``serial``, which records
    the task's error from the mirror (:meth:`NativeStepMirror.record_error`) only if that
    step is still the controller's last one; otherwise the error was computed since, by a
    Python step's rows or by another mirror.
    """

    __slots__ = ("mirror", "controller", "serial")

    def __init__(self, mirror: Any, controller: Any) -> None:
        self.mirror = mirror
        self.controller = controller
        self.serial = -1

    def fetch(self, task: Any) -> None:
        """Record ``task``'s error of this step, if the step is the controller's last."""
        if self.controller.step_serial == self.serial:
            self.mirror.record_error(task)


def _tau_bytes(task: Any) -> tuple[Any, ...]:
    tau = None if task.tau_max is None else np.asarray(task.tau_max, dtype=float).tobytes()
    return (tau,)


def _obstacle_ids(task: Any) -> tuple[Any, ...]:
    try:
        obstacles: tuple[int, ...] | None = tuple(id(o) for o in task.selected_obstacles())
    except HQPError:  # the Python step raises it
        obstacles = None
    return tuple(id(p) for p in task.proxies) + (id(task.world), obstacles)


def _dynamic_gains(task: Any) -> tuple[Any, ...]:
    reference = getattr(task, "reference", None)
    return _gains(task) if reference is not None and hasattr(reference, "kp") else ()


_Extractor = Callable[[Any], tuple[Any, ...]]

_GAIN_FIELDS = ("reference.kp", "reference.kv", "reference.max_velocity",
                "reference.max_acceleration")
"""A tracking task's PD reference (always a :class:`~hqp.tasks.reference.PDReference`)."""


def _extractor(cls: type) -> _Extractor:
    """Return the function of :func:`_parameters` for a task class (chosen once per class).

    The plain attributes of a class are read by one ``operator.attrgetter``; arrays are
    compared by their bytes, obstacles and pairs by identity.
    """
    extra: _Extractor | None = None
    names: tuple[str, ...] = ()
    if issubclass(cls, Contact):  # (max_normal_force: pushed each step, push_goals)
        names = ("mu", "f_min", "kp", "kd")
    elif issubclass(cls, TorqueLimits):
        names, extra = ("scale",), _tau_bytes
    elif issubclass(cls, JointLimits):
        names = ("position_margin", "velocity_scale", "reserve", "velocity_time",
                 "approach_time", "inactive_beyond", "acceleration_bounds")

        def extra(t: Any) -> tuple[Any, ...]:
            return (t.qdd_max is None,
                    None if t.recovery is None else t.recovery.tobytes())
    elif issubclass(cls, GazeTask):
        names = ("frame",)

        def extra(t: Any) -> tuple[Any, ...]:
            return (t.axis.tobytes(),)
    elif issubclass(cls, PoseTask):
        names = ("frame", "angular_reference.max_velocity", "angular_reference.max_acceleration")
        if issubclass(cls, HybridTask):
            names += ("contact", "force_axes")
    elif issubclass(cls, InternalForcesTask):
        names = ("contacts", "_components")
    elif issubclass(cls, SelfCollision):
        names = ("d_safe", "d_influence", "xi", "kv")

        def extra(t: Any) -> tuple[Any, ...]:
            return tuple((id(a), id(b)) for a, b in t.pairs)
    elif issubclass(cls, ObstacleAvoidance):
        names, extra = ("d_safe", "d_influence", "xi", "kv"), _obstacle_ids
    elif issubclass(cls, EffortTask):
        def extra(t: Any) -> tuple[Any, ...]:
            return (t._w.tobytes(),)
    elif issubclass(cls, CoPTask):
        names = ("contacts", "height")
    if issubclass(cls, (TrackingTask, CentroidalMomentumTask)):
        names += _GAIN_FIELDS
    elif not issubclass(cls, Contact):  # (a contact's reference is its placement)
        inner = extra

        def extra(t: Any) -> tuple[Any, ...]:
            return (() if inner is None else inner(t)) + _dynamic_gains(t)
    fields = operator.attrgetter("weight", *names)
    if extra is None:
        def parameters(task: Any) -> tuple[Any, ...]:
            return (id(task), fields(task))
    else:
        more = extra

        def parameters(task: Any) -> tuple[Any, ...]:
            return (id(task), fields(task), more(task))
    return parameters


_EXTRACTORS: dict[type, _Extractor] = {}


def _parameters(task: Any) -> tuple[Any, ...]:
    """Return what a kernel copies of a task when built (a change means a new mirror)."""
    cls = type(task)
    extract = _EXTRACTORS.get(cls)
    if extract is None:
        extract = _EXTRACTORS[cls] = _extractor(cls)
    return extract(task)


class NativeEngine:
    """The native step of a controller, as the controller runs it (see the module docstring).

    Args:
        robot: The bundled robot of the controller's model.
        rank_tol: The solver's rank tolerance.

    """

    def __init__(self, robot: Robot, rank_tol: float = 1e-9) -> None:
        self.robot = robot
        self.rank_tol = float(rank_tol)
        self.mirror: NativeStepMirror | None = None
        self.unsupported: str | None = None
        self._signature: tuple[Any, ...] | None = None
        self._key: tuple[Any, ...] | None = None  # what ready() checked at the last step
        self._mirrors: dict[tuple[Any, ...], NativeStepMirror] = {}  # by signature
        self._t = -np.inf  # the time of the last step
        self.steps = 0
        self.steady = True
        """Whether the stack was steady at the last :meth:`ready` (else: ramps, unloading)."""

    KEPT = 8
    """Mirrors kept for a task set seen before (a behavior's phases alternate among a few).

    A mirror is built in milliseconds (two URDF passes and the kernels; tens of
    milliseconds on talos): a phase change back to a task set seen before takes its mirror
    again, whose pushed goals, contact activations, bounds and ramps are compared with the
    tasks' at the next step as those of the mirror in use."""

    def forget(self) -> None:
        """Check everything again at the next :meth:`ready` (a step left to Python after it)."""
        self._key = None

    def signature(self, controller: Any) -> tuple[Any, ...]:
        """Return what a mirror is built from: the controller's stack structure.

        The level of each task, the parameters its kernel copies, where the torque-rate
        level sits (``None``: none) and the levels' weak-direction thresholds.
        """
        stack = controller.stack
        rate = None if controller.max_torque_rate is None else int(controller._rate_after)
        return tuple((level, _parameters(t)) for level, t in stack.task_levels()) + (
            ("torque_rate", rate), ("weak_thresholds", stack.weak_thresholds),
            ("work_budget", getattr(controller, "work_budget", None)))

    def ready(self, controller: Any, t: float) -> NativeStepMirror | None:
        """Return the mirror to run this step, or ``None`` when the Python step must run it.

        A stack whose edit count (:class:`~hqp.tasks.base.Edits`), layout, torque-rate level
        and work budget are those of the last step checked here runs on the same mirror with
        nothing checked again: nothing the mirror copied can have changed (what a stack that
        is not steady changes at every step, its ramps and unloading bounds, the controller
        pushes after advancing it).
        Otherwise the mirror is rebuilt if the stack's signature changed, the contacts'
        activations are pushed, contact-aware tasks told the active contacts (a steady
        stack: :meth:`~hqp.stack.Stack.advance_steady`) and the joint limits' braking and
        the contacts' force bounds pushed (:meth:`NativeStepMirror.push_parameters`; a stack
        that is not steady pushes them after advancing).
        """
        resolver = controller.resolver
        if (getattr(resolver, "final_metric", None) is not None
                or getattr(resolver, "final_target", None) is not None):
            return None
        stack = controller.stack
        key = (Edits.count, stack, controller.layout, controller.max_torque_rate is None,
               controller.work_budget)
        last_t, self._t = self._t, t
        if key == self._key and self.steady and t >= last_t:
            return self.mirror  # steady, unedited, later: steady still (ramps only end)
        self.steady = stack.steady(t)
        if not self.steady and not stack.native_ready(t):  # ramps and unloading: native
            return None
        if key == self._key:
            return self.mirror
        self._key = None
        declared = stack.layout_contacts()
        if [(c.name, c.frame, c.kind) for c in controller.layout.contacts] != declared:
            return None
        signature = self.signature(controller)
        if signature != self._signature:
            self._signature = signature
            self.mirror, self.unsupported = self._mirrors.pop(signature, None), None
            if self.mirror is not None and (self.mirror.stack is not stack
                                            or self.mirror._layout is not controller.layout):
                self.mirror = None
            if self.mirror is None:
                try:
                    self.mirror = NativeStepMirror(self.robot, controller, self.rank_tol)
                except NotSupported as exc:
                    self.unsupported = str(exc)
            else:
                self.mirror.resume()
            if self.mirror is not None:  # the most recent last
                self._mirrors[signature] = self.mirror
                while len(self._mirrors) > self.KEPT:
                    del self._mirrors[next(iter(self._mirrors))]
        mirror = self.mirror
        if mirror is None or mirror._layout is not controller.layout:
            return None
        if not mirror.sync_contacts():
            return None
        if self.steady:
            stack.advance_steady()
            mirror.push_parameters()
        # after what the checks themselves set (the contact-aware tasks' supports); a stack
        # that is not steady advances after this, and an edit made there (a goal ramp
        # started, a contact released) brings the next step back here
        self._key = (Edits.count,) + key[1:]
        return mirror
