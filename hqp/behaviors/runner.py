"""Run a behavior in closed loop with MuJoCo (``hqp run``) and measure it.

The loop, every control period ``dt`` (1 ms by default):

1. read the simulated state (pinocchio convention) and the sensed foot contacts;
2. ``command = controller.step(state, t)``;
3. ``behavior.update(state, t, command.report)`` (phase switches and goals for the
   next step);
4. apply the torques and step MuJoCo.

Measured and reported (the JSON of ``hqp run --json``): whether the robot fell
(pelvis below 0.6 of its standing height, or anything but a foot touching the
floor), the phases visited, the footsteps completed (a swing foot out of contact
for at least 0.1 s that lands at least 0.10 m ahead of where it lifted), the
feasibility events, the longest flight (no foot in contact) and the highest the lower
foot site rose during flights (``flight_clearance_m``), the largest ratio of
a commanded torque to its limit, and for planned behaviors the mean forward speed
and the largest horizontal centre-of-mass tracking error.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from hqp.behaviors.behavior import Behavior
from hqp.behaviors.factory import TaskFactory
from hqp.behaviors.inputs import InputStream
from hqp.behaviors.loader import load_behavior
from hqp.behaviors.planners import PlacoWalkPlanner
from hqp.behaviors.spec import BehaviorSpec
from hqp.errors import BehaviorFileError, UnknownName

logger = logging.getLogger(__name__)

CONTROLLERS = ("hqp", "nullspace")
"""Controllers ``hqp run`` can use."""

STEP_MIN_AIR_TIME = 0.1
"""A footstep: the swing foot is out of contact at least this long [s] ..."""
STEP_MIN_ADVANCE = 0.10
"""... and lands at least this far ahead (world x) of where it lifted [m]."""
from hqp.sim.simulator import FALL_HEIGHT_RATIO  # noqa: E402  (pelvis below 0.6 x standing)


@dataclass
class FootTracker:
    """Counts footsteps of one foot from its sensed contact and position."""

    name: str
    in_contact: bool = True
    lift_t: float = 0.0
    lift_x: np.ndarray = field(default_factory=lambda: np.zeros(3))
    steps: list[dict[str, float]] = field(default_factory=list)

    def update(self, contact: bool, position: np.ndarray, t: float) -> None:
        """Record a lift-off or a landing."""
        if self.in_contact and not contact:
            self.lift_t, self.lift_x = t, position.copy()
        elif not self.in_contact and contact:
            air = t - self.lift_t
            advance = float(position[0] - self.lift_x[0])
            if air >= STEP_MIN_AIR_TIME and advance >= STEP_MIN_ADVANCE:
                self.steps.append({"foot": self.name, "t_lift": round(self.lift_t, 4),
                                   "t_land": round(t, 4), "air_time_s": round(air, 4),
                                   "advance_m": round(advance, 4)})
        self.in_contact = contact


def build_controller(
    robot: Any,
    controller: str,
    *,
    diagnostics: str = "residuals",
    backend: str | None = None,
    max_joint_acceleration: float | None = None,
) -> Any:
    """Build a whole-body controller holding only the constraint levels of docs/architecture.md.

    The standing controllers (:func:`hqp.controller.standing_controller`,
    :func:`hqp.nullspace.standing_nullspace_controller`: physics
    with both soles as contacts, friction / centre-of-pressure / torque limits, viable joint
    limits for HQP or the papers' activation zones for the null-space law), without their
    standing tasks: the behavior writes its own task sets.

    Args:
        robot: The bundled robot.
        controller: ``"hqp"`` or ``"nullspace"``.
        diagnostics: ``"residuals"`` (per-task residuals, cheap) or ``"full"``.
        backend: QP backend of the HQP controller (``None``: its default).
        max_joint_acceleration: Clip of the HQP controller's joint-acceleration bounds
            [rad/s^2] (``None``: its default; the null-space law has activation zones instead).

    Raises:
        UnknownName: Unknown controller.

    """
    from hqp.tasks.centroidal import CentroidalMomentumTask
    from hqp.tasks.com import CoMTask
    from hqp.tasks.orientation import OrientationTask
    from hqp.tasks.posture import PostureTask

    if controller not in CONTROLLERS:
        raise UnknownName("controller", controller, CONTROLLERS)
    if controller == "hqp":
        from hqp.controller import standing_controller

        kwargs: dict[str, Any] = {} if backend is None else {"backend": backend}
        if max_joint_acceleration is not None:
            kwargs["max_joint_acceleration"] = max_joint_acceleration
        ctrl = standing_controller(robot, diagnostics=diagnostics, **kwargs)
    else:
        from hqp.nullspace import standing_nullspace_controller

        ctrl = standing_nullspace_controller(robot, diagnostics=diagnostics)
    for task in list(ctrl.stack.tasks):
        # the standing tasks (the angular-momentum damping of the standing balance level
        # included: left in, it sat strictly above every task of a behavior's lower levels)
        if isinstance(task, (CoMTask, OrientationTask, PostureTask, CentroidalMomentumTask)):
            ctrl.stack.remove(task.name)
    ctrl.stack.pop_events()
    return ctrl


@dataclass
class RunResult:
    """Outcome of :func:`run_behavior` (see :meth:`as_json`)."""

    behavior: str
    robot: str
    controller: str
    duration_s: float
    fell: bool
    fall_reason: str | None
    phases: list[str]
    steps: list[dict[str, float]]
    feasibility_events: list[dict[str, Any]]
    metrics: dict[str, Any]

    def as_json(self) -> dict[str, Any]:
        """Return the JSON object of ``hqp run --json``."""
        return {
            "behavior": self.behavior, "robot": self.robot, "controller": self.controller,
            "duration_s": round(self.duration_s, 6), "fell": self.fell,
            "fall_reason": self.fall_reason, "phases": self.phases, "steps": len(self.steps),
            "footsteps": self.steps, "feasibility_events": self.feasibility_events,
            **self.metrics,
        }


def _contacts_of(spec: BehaviorSpec, robot: Any) -> dict[str, str]:
    if spec.contact_frames:
        return dict(spec.contact_frames)
    return {c.name: c.frame for c in robot.contacts}


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
        robot: Robot name (default: the behavior's).
        controller: ``"hqp"`` or ``"nullspace"``.
        inputs: Inputs file (default: the behavior's ``inputs_file``, else defaults).
        overrides: Input defaults to replace, by input name (e.g. a jump target).
        backend: QP backend of the HQP controller (default: the behavior's ``backend``,
            else the controller's default).

    Returns:
        ``(behavior, controller, robot)``.

    """
    from hqp import robots
    from hqp.behaviors.spec import InputSpec

    spec = source if isinstance(source, BehaviorSpec) else load_behavior(source)
    robot_obj = robots.load(robot or spec.robot)
    ctrl = build_controller(robot_obj, controller,
                            backend=backend if backend is not None else spec.backend,
                            max_joint_acceleration=spec.max_joint_acceleration)
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
    if overrides:
        new_inputs = dict(spec.inputs)
        for k, v in overrides.items():
            if k not in new_inputs:
                raise UnknownName("input", k, new_inputs)
            old = new_inputs[k]
            new_inputs[k] = InputSpec(k, old.shape, np.asarray(v, dtype=float).reshape(old.shape),
                                      old.interpolate, old.description)
        from dataclasses import replace

        spec = replace(spec, inputs=new_inputs)
    factory = TaskFactory(model, contacts, robot_obj.q_standing, feet=robot_obj.feet)
    inputs_path = inputs if inputs is not None else spec.inputs_file
    stream = InputStream(spec.inputs, inputs_path)
    planner = None
    if spec.planner is not None:
        surface = robot_obj.contact(robot_obj.feet[0])
        planner = PlacoWalkPlanner(robot_obj.urdf_path, spec.planner.params,
                                   foot_length=2 * surface.half_length,
                                   foot_width=2 * surface.half_width, where=str(path))
    behavior = Behavior(spec, ctrl, factory, inputs=stream, planner=planner,
                        standing=robot_obj.q_standing)
    return behavior, ctrl, robot_obj


def run_behavior(
    source: str | Path | BehaviorSpec,
    *,
    robot: str | None = None,
    controller: str = "hqp",
    duration: float | None = None,
    inputs: str | Path | None = None,
    overrides: dict[str, Any] | None = None,
    video: str | Path | None = None,
    stop_on_fall: bool = True,
    progress: Callable[[float, float], None] | None = None,
    backend: str | None = None,
    plot: str | Path | None = None,
) -> RunResult:
    """Run a behavior in MuJoCo and measure it (see the module docstring).

    Args:
        source: Library name, file path or spec.
        robot: Robot name (default: the behavior's).
        controller: ``"hqp"`` or ``"nullspace"``.
        duration: Simulated duration [s] (default: the behavior's).
        inputs: Inputs file (JSON Lines).
        overrides: Input defaults to replace.
        video: Write an MP4 (or PNG frames) here, if rendering is available.
        stop_on_fall: End the run when the robot falls.
        progress: Called as ``progress(t, duration)`` every 0.1 s of simulated time.
        backend: QP backend of the HQP controller (default: the behavior's, see
            :func:`prepare`).
        plot: Write a PNG of the run here (centre-of-gravity height and vertical velocity,
            feet heights, normal forces, largest torque ratio; phase changes as vertical
            lines); its path is reported as ``plot`` in the metrics.

    Returns:
        The measurements.

    """
    behavior, ctrl, robot_obj = prepare(source, robot=robot, controller=controller,
                                        inputs=inputs, overrides=overrides, backend=backend)
    spec = behavior.spec
    T = float(duration if duration is not None else spec.duration)
    from hqp.sim.simulator import Simulator

    sim = Simulator(robot_obj)
    dt = sim.dt
    ctrl.dt = dt
    model = ctrl.model
    trackers = {c: FootTracker(c) for c in robot_obj.feet}
    n = int(round(T / dt))
    state = sim.state()
    behavior.start(state, 0.0)
    torque_ratio = 0.0
    clipped = 0
    fell, reason = False, None
    flight, flight_start, max_flight = False, 0.0, 0.0
    clearance = 0.0  # highest height of the lower foot while no foot touches [m]
    com_err_max = 0.0
    com_err_t = None
    pelvis_min = np.inf
    x_start = model.com[0]
    safe_steps = 0
    tau_prev, tau_jump, tau_jump_t = None, 0.0, None
    step_times = []
    renderer = _Renderer(sim, video) if video is not None else None
    trace: dict[str, list[Any]] | None = (
        None if plot is None else {"t": [], "com": [], "vz": [], "feet": [], "fn": [], "tau": []})
    t = 0.0
    k = 0
    for k in range(n):
        t = k * dt
        c0 = time.perf_counter()
        cmd = ctrl.step(state, t)
        behavior.update(state, t, cmd.report)
        step_times.append(time.perf_counter() - c0)
        if cmd.safe_mode:
            safe_steps += 1
        ratio = float(np.max(np.abs(cmd.tau) / np.maximum(model.tau_max, 1e-9)))
        torque_ratio = max(torque_ratio, ratio)
        if tau_prev is not None:
            jump = float(np.max(np.abs(cmd.tau - tau_prev)))
            if jump > tau_jump:
                tau_jump, tau_jump_t = jump, t
        tau_prev = cmd.tau
        if any("clipped" in note for note in cmd.report.notes):
            clipped += 1
        sim.step(cmd.tau)
        state = sim.state()
        # measurements at the new state (MuJoCo's contacts: for logs and tests only)
        reading = sim.contacts()
        sensed = state.contacts or {}
        for i, (c, tr) in enumerate(trackers.items()):
            tr.update(bool(reading.foot_contact[i]), reading.foot_position[i], (k + 1) * dt)
        airborne = not any(sensed.get(c, False) for c in trackers)
        if airborne and not flight:
            flight, flight_start = True, (k + 1) * dt
        elif not airborne and flight:
            flight = False
            max_flight = max(max_flight, (k + 1) * dt - flight_start)
        if airborne:
            clearance = max(clearance, float(np.min(reading.foot_position[:, 2])))
        if trace is not None:
            for key, value in (("t", (k + 1) * dt), ("com", model.com[2]),
                               ("vz", model.com_velocity[2]),
                               ("feet", reading.foot_position[:, 2].copy()),
                               ("fn", reading.normal_force.copy()), ("tau", ratio)):
                trace[key].append(value)
        if behavior.planner is not None and behavior.planner.trajectory is not None:
            plan = behavior.planner.outputs(t)
            if plan["started"] and not plan["done"]:
                err = float(np.linalg.norm(model.com[:2] - plan["com"][:2]))
                if err > com_err_max:
                    com_err_max, com_err_t = err, t
        pelvis = sim.base_height()
        pelvis_min = min(pelvis_min, pelvis)
        if pelvis < FALL_HEIGHT_RATIO * robot_obj.standing_height:
            fell, reason = True, f"pelvis at {pelvis:.3f} m below {FALL_HEIGHT_RATIO} x standing"
        if reading.other_contact:
            fell, reason = True, f"{', '.join(reading.other_contact)} touches the floor"
        if renderer is not None:
            renderer.maybe_capture((k + 1) * dt)
        if progress is not None and k % 100 == 0:
            progress(t, T)
        if fell and stop_on_fall:
            break
    t_end = (k + 1) * dt
    if flight:
        max_flight = max(max_flight, t_end - flight_start)
    video_path = None if renderer is None else str(renderer.close())
    steps = sorted((s for tr in trackers.values() for s in tr.steps), key=lambda s: s["t_land"])
    metrics: dict[str, Any] = {
        "max_torque_ratio": round(torque_ratio, 4),
        "max_torque_jump_nm": round(tau_jump, 3),
        "max_torque_jump_t": None if tau_jump_t is None else round(tau_jump_t, 3),
        "controller_clipped_steps": clipped,
        "sim_clipped_torques": int(sim.clip_count),
        "safe_mode_steps": safe_steps,
        "flight_time_s": round(max_flight, 4),
        "flight_clearance_m": round(clearance, 4),
        "pelvis_min_m": round(float(pelvis_min), 4),
        "step_time_median_ms": round(1e3 * float(np.median(step_times)), 3) if step_times else 0,
        "backend": getattr(ctrl, "backend", None),
        "video": video_path,
    }
    if behavior.planner is not None:
        x_end = model.com[0]
        metrics["distance_m"] = round(float(x_end - x_start), 4)
        metrics["mean_speed_m_s"] = round(float(x_end - x_start) / t_end, 4)
        if steps:
            walk_time = steps[-1]["t_land"] - steps[0]["t_lift"]
            x_steps = sum(s["advance_m"] for s in steps) / 2
            metrics["walking_time_s"] = round(walk_time, 4)
            metrics["step_speed_m_s"] = round(x_steps / walk_time, 4) if walk_time > 0 else 0.0
        metrics["com_tracking_error_max_m"] = round(com_err_max, 4)
        metrics["com_tracking_error_max_t"] = None if com_err_t is None else round(com_err_t, 3)
    metrics.update(behavior.metrics())
    if trace is not None and plot is not None:
        metrics["plot"] = str(_plot_run(trace, metrics["phase_times"], list(trackers), plot,
                                        f"{spec.name} on {robot_obj.name} ({controller})"))
    return RunResult(
        behavior=spec.name, robot=robot_obj.name, controller=controller, duration_s=t_end,
        fell=fell, fall_reason=reason, phases=list(behavior.visited), steps=steps,
        feasibility_events=[e.as_dict() for e in behavior.events], metrics=metrics,
    )


def _plot_run(trace: dict[str, list[Any]], phases: list[dict[str, Any]], feet: list[str],
              path: str | Path, title: str) -> Path:
    """Draw the run's trace (see :func:`run_behavior`'s ``plot``)."""
    from hqp.plots import Line, Panel, plot_panels

    t = np.asarray(trace["t"])
    events = tuple(float(p["t"]) for p in phases[1:])
    feet_z = np.asarray(trace["feet"]).reshape(len(t), -1)
    normal = np.asarray(trace["fn"]).reshape(len(t), -1)
    panels = [
        Panel("Centre of gravity height", "z [m]", t, (Line("CoG", np.asarray(trace["com"])),),
              events),
        Panel("Centre of gravity vertical velocity", "vz [m/s]", t,
              (Line("CoG", np.asarray(trace["vz"])),), events),
        Panel("Feet heights (MuJoCo sites)", "z [mm]", t,
              tuple(Line(f, 1e3 * feet_z[:, i]) for i, f in enumerate(feet)), events),
        Panel("Normal forces (MuJoCo)", "force [N]", t,
              tuple(Line(f, normal[:, i]) for i, f in enumerate(feet)), events),
        Panel("Largest torque / limit", "ratio", t,
              (Line("max |tau| / tau_max", np.asarray(trace["tau"])),
               Line("limit", np.ones_like(t), "dashed")), events),
    ]
    names = ", ".join(f"{p['phase']} {p['t']:g} s" for p in phases)
    return plot_panels(panels, path, title=f"{title}\nphases: {names}")


class _Renderer:
    """Offscreen frames at ``fps``, written as an MP4 (imageio) or a folder of PNGs."""

    def __init__(self, sim: Any, path: str | Path, fps: int = 30) -> None:
        import mujoco

        from hqp.sim.render import RenderUnavailable, rendering_available

        ok, message = rendering_available()
        if not ok:
            raise RenderUnavailable(message)
        self.sim = sim
        self.path = Path(path)
        self.fps = fps
        self.next_t = 0.0
        self.frames: list[np.ndarray] = []
        self.renderer = mujoco.Renderer(sim.mj_model, 480, 640)
        self.camera = mujoco.MjvCamera()
        self.camera.distance = 3.5
        self.camera.elevation = -15.0
        self.camera.azimuth = 120.0

    def maybe_capture(self, t: float) -> None:
        """Grab a frame when one is due at simulated time ``t`` [s]."""
        if t + 1e-9 < self.next_t:
            return
        self.next_t += 1.0 / self.fps
        self.camera.lookat[:] = self.sim.mj_data.qpos[:3]
        self.renderer.update_scene(self.sim.mj_data, self.camera)
        self.frames.append(self.renderer.render().copy())

    def close(self) -> Path:
        """Write the frames; return the path written."""
        self.renderer.close()
        if self.path.suffix == ".mp4":
            try:
                import imageio.v2 as imageio

                self.path.parent.mkdir(parents=True, exist_ok=True)
                imageio.mimwrite(self.path, self.frames, fps=self.fps)
                return self.path
            except Exception as exc:  # noqa: BLE001 - imageio or its ffmpeg plugin missing
                logger.warning("MP4 writing failed (%s): writing PNG frames instead", exc)
        import matplotlib.pyplot as plt

        folder = self.path.with_suffix("")
        folder.mkdir(parents=True, exist_ok=True)
        for i, frame in enumerate(self.frames):
            plt.imsave(folder / f"frame_{i:05d}.png", frame)
        return folder
