"""Closed loop: simulator state -> (noise, delay) -> controller -> torques -> simulator.

:func:`simulate` runs a controller on a robot in MuJoCo for a duration, applies events at given
times (pushes on the base, changes of goals, tasks and contacts), and returns a :class:`Log` of
what happened, read from MuJoCo where it concerns contacts (which geoms touch the floor, slip
and lift-off of the feet, centre of pressure) and from the controller's commands otherwise
(torques, task errors, feasibility flags).
"""

from __future__ import annotations

import collections
import logging
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from hqp.errors import InvalidInput, check_array
from hqp.model import RobotState
from hqp.sim.simulator import FALL_HEIGHT_RATIO, Simulator, inside_polygon

if TYPE_CHECKING:
    from hqp.controller import Controller
    from hqp.robots import Robot

logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class Push:
    """A horizontal (or any) force on the floating base during an interval.

    Attributes:
        t: Start [s].
        force: World force ``(3,)`` [N] applied at the base body's centre of mass.
        duration: Length of the push [s].

    """

    t: float
    force: tuple[float, float, float]
    duration: float = 0.1


@dataclass(frozen=True)
class Event:
    """A callable run once at a time: ``action(sim, controller, t)``.

    Use it to move goals, add or remove tasks, make or release contacts.

    Attributes:
        t: Time [s] at which it runs (at the first control step with ``time >= t``).
        action: The callable.
        name: A label for the log.

    """

    t: float
    action: Callable[[Simulator, Any, float], None]
    name: str = ""


@dataclass(frozen=True)
class Noise:
    """Gaussian measurement noise added to the state the controller sees.

    Attributes:
        q_std: Standard deviation on actuated joint positions [rad] and base position [m].
        v_std: Standard deviation on every velocity [rad/s or m/s].
        seed: Seed of the generator (runs are deterministic).

    """

    q_std: float = 0.0
    v_std: float = 0.0
    seed: int = 0


@dataclass
class Log:
    """What a closed-loop run recorded, one row per control step.

    Attributes:
        robot: Robot name.
        t: Times ``(N,)`` [s].
        q: Configurations ``(N, nq)`` (pinocchio convention, true state).
        v: Velocities ``(N, nv)``.
        tau: Commanded torques ``(N, na)`` [N m] (before any clipping).
        com: Centre of mass read from MuJoCo ``(N, 3)`` [m].
        base_height: Height of the floating base ``(N,)`` [m].
        foot_contact: Whether each foot touches the floor ``(N, nfeet)``.
        foot_position: Foot site positions ``(N, nfeet, 3)`` [m].
        normal_force: Floor normal force on each foot ``(N, nfeet)`` [N].
        other_contact: Whether any body but the feet touched the floor ``(N,)``.
        cop: Centre of pressure ``(N, 2)`` [m] (``nan`` when airborne).
        support_margin: Signed distance of the horizontal CoM inside the convex hull of the
            sole corners of the feet in contact ``(N,)`` [m] (``nan`` when no foot touches).
        task_errors: Norm of each task's task-space error (``Task.error()``: goal minus
            current) by task name ``(N,)`` (``nan`` when absent).
        residuals: Norm of each task's unweighted row residual from the feasibility report by
            task name ``(N,)`` (``nan`` when absent).
        status: Feasibility status (``Feasibility.value``) of each task by name per step.
        safe_mode: Whether the safe command was sent ``(N,)``.
        strictness_suspended: Whether torques were being blended ``(N,)``.
        clipped: Number of torque entries clipped by the simulator at each step ``(N,)``.
        step_time: Wall-clock time of each controller step ``(N,)`` [s].
        events: ``(t, name)`` of the events applied.
        standing_height: Base height of the robot's standing configuration [m].
        fell_at: Time of the first fall (``None`` if it did not fall).

    """

    robot: str
    t: np.ndarray
    q: np.ndarray
    v: np.ndarray
    tau: np.ndarray
    com: np.ndarray
    base_height: np.ndarray
    foot_contact: np.ndarray
    foot_position: np.ndarray
    normal_force: np.ndarray
    other_contact: np.ndarray
    cop: np.ndarray
    support_margin: np.ndarray
    task_errors: dict[str, np.ndarray]
    residuals: dict[str, np.ndarray]
    status: dict[str, list[str]]
    safe_mode: np.ndarray
    strictness_suspended: np.ndarray
    clipped: np.ndarray
    step_time: np.ndarray
    events: list[tuple[float, str]] = field(default_factory=list)
    standing_height: float = 0.0
    fell_at: float | None = None

    @property
    def fell(self) -> bool:
        """Whether the robot fell during the run."""
        return self.fell_at is not None

    @property
    def clip_count(self) -> int:
        """Total number of clipped torque entries."""
        return int(self.clipped.sum())

    def _from(self, since: float) -> int:
        """Index of the first logged step at or after ``since`` [s]."""
        return int(np.searchsorted(self.t, since - 1e-9))

    def foot_slip(self, since: float = 0.0) -> np.ndarray:
        """Largest horizontal displacement of each foot from its position at ``since`` [s].

        Returns:
            ``(nfeet,)`` [m].

        """
        p = self.foot_position[self._from(since):, :, :2]
        if p.shape[0] == 0:
            return np.zeros(self.foot_position.shape[1])
        return np.linalg.norm(p - p[:1], axis=2).max(axis=0)

    def foot_lift(self, since: float = 0.0) -> np.ndarray:
        """Largest rise of each foot above its height at ``since`` [s] ``(nfeet,)`` [m]."""
        z = self.foot_position[self._from(since):, :, 2]
        if z.shape[0] == 0:
            return np.zeros(self.foot_position.shape[1])
        return (z - z[:1]).max(axis=0)

    def max_torque_jump(self) -> float:
        """Largest change of a commanded torque between consecutive steps [N m]."""
        if self.tau.shape[0] < 2:
            return 0.0
        return float(np.abs(np.diff(self.tau, axis=0)).max())

    def summary(self, settle: float = 0.05) -> dict[str, float | bool | int]:
        """Scalar figures of the run (for tables and scripts).

        Args:
            settle: Contact and slip figures start at this time [s] (the soft contacts of a
                robot placed exactly on the floor engage during the first milliseconds).

        """
        k = self._from(settle)
        margin = self.support_margin[k:]
        margin = margin[np.isfinite(margin)]
        return {
            "duration_s": float(self.t[-1] - self.t[0]) if self.t.size else 0.0,
            "fell": self.fell,
            "min_support_margin_m": float(margin.min()) if margin.size else float("nan"),
            "max_foot_slip_m": float(self.foot_slip(settle).max()),
            "max_foot_lift_m": float(self.foot_lift(settle).max()),
            "feet_always_in_contact": bool(self.foot_contact[k:].all()),
            "clip_count": self.clip_count,
            "safe_mode_steps": int(self.safe_mode.sum()),
            "max_torque_jump_nm": self.max_torque_jump(),
            "step_time_median_ms": float(np.median(self.step_time) * 1e3),
            "step_time_p95_ms": float(np.percentile(self.step_time, 95) * 1e3),
        }


def _noisy(state: RobotState, noise: Noise, rng: np.random.Generator, nq_base: int) -> RobotState:
    q = state.q.copy()
    v = state.v.copy()
    if noise.q_std > 0.0:
        q[:3] += rng.normal(scale=noise.q_std, size=3)
        q[nq_base:] += rng.normal(scale=noise.q_std, size=q.size - nq_base)
    if noise.v_std > 0.0:
        v += rng.normal(scale=noise.v_std, size=v.size)
    return RobotState(q=q, v=v, t=state.t, contacts=state.contacts, wrenches=state.wrenches)


def simulate(
    robot: Robot,
    controller: Controller,
    duration: float,
    events: Sequence[Event | Push] = (),
    *,
    noise: Noise | None = None,
    delay_steps: int = 0,
    sim: Simulator | None = None,
    q0: np.ndarray | None = None,
    v0: np.ndarray | None = None,
    stop_on_fall: bool = True,
    progress: Callable[[float], None] | None = None,
    on_step: Callable[[Simulator, Any], None] | None = None,
) -> Log:
    """Run a controller in closed loop on a robot in MuJoCo.

    One control step per simulation step (both at ``sim.dt``, 1 ms by default). The controller
    sees the state after optional Gaussian noise and a delay of ``delay_steps`` steps (the
    state measured ``delay_steps`` steps earlier); its torques are applied at once.

    Args:
        robot: The robot.
        controller: Any :class:`~hqp.controller.Controller` (HQP or null-space).
        duration: Simulated duration [s].
        events: Pushes and timed callables.
        noise: Measurement noise (default none).
        delay_steps: Measurement delay in steps (>= 0).
        sim: A simulator to use (default: a new one at the robot's standing configuration).
        q0: Initial configuration (pinocchio convention; default: ``robot.q_standing``).
        v0: Initial velocity (default zero).
        stop_on_fall: End the run at the first fall.
        progress: Called with the simulated time every 100 steps.
        on_step: Called after each control step with the simulator and the command (before
            the simulation step), e.g. to render frames.

    Returns:
        The log of the run.

    Raises:
        InvalidInput: Non-positive duration or negative delay.

    """
    if not np.isfinite(duration) or duration <= 0.0:
        raise InvalidInput(f"simulate: duration must be positive, got {duration}")
    if delay_steps < 0:
        raise InvalidInput(f"simulate: delay_steps must be >= 0, got {delay_steps}")
    if sim is None:
        sim = Simulator(robot, dt=getattr(controller, "dt", 0.001))
        sim.reset(q0, v0)
    elif q0 is not None or v0 is not None:
        sim.reset(q0, v0)
    steps = int(round(duration / sim.dt))
    rng = np.random.default_rng(noise.seed if noise is not None else 0)
    nq_base = 7
    timed = sorted([e for e in events if isinstance(e, Event)], key=lambda e: e.t)
    pushes = [e for e in events if isinstance(e, Push)]
    for p in pushes:
        check_array(p.force, (3,), "simulate: push force")
    nfeet = len(robot.feet)
    buf: collections.deque[RobotState] = collections.deque(maxlen=delay_steps + 1)

    rows: dict[str, list] = {k: [] for k in (
        "t", "q", "v", "tau", "com", "base", "fc", "fp", "fn", "other", "cop", "corners",
        "safe", "susp", "clip", "time")}
    errors: dict[str, list[float]] = {}
    residuals: dict[str, list[float]] = {}
    status: dict[str, list[str]] = {}
    applied: list[tuple[float, str]] = []
    fell_at = None
    next_event = 0
    for k in range(steps):
        t = sim.time
        while next_event < len(timed) and timed[next_event].t <= t + 1e-12:
            ev = timed[next_event]
            ev.action(sim, controller, t)
            applied.append((t, ev.name or f"event {next_event}"))
            next_event += 1
        reading = sim.contacts()
        true_state = sim.state(reading)
        measured = true_state if noise is None else _noisy(true_state, noise, rng, nq_base)
        buf.append(measured)
        seen = buf[0]
        seen = RobotState(q=seen.q, v=seen.v, t=t, contacts=seen.contacts, wrenches=seen.wrenches)
        w0 = time.perf_counter()
        cmd = controller.step(seen, t)
        w1 = time.perf_counter()
        force = np.zeros(3)
        for p in pushes:
            if p.t <= t < p.t + p.duration:
                force += np.asarray(p.force, dtype=float)
        corners = sim.sole_corners()
        com = sim.com()
        rows["t"].append(t)
        rows["q"].append(true_state.q)
        rows["v"].append(true_state.v)
        rows["tau"].append(np.array(cmd.tau))
        rows["com"].append(com)
        rows["base"].append(sim.base_height())
        rows["fc"].append(reading.foot_contact)
        rows["fp"].append(reading.foot_position)
        rows["fn"].append(reading.normal_force)
        rows["other"].append(bool(reading.other_contact))
        rows["cop"].append(reading.cop)
        rows["corners"].append(corners)
        rows["safe"].append(cmd.safe_mode)
        rows["susp"].append(cmd.report.strictness_suspended)
        rows["time"].append(w1 - w0)
        for s in cmd.report.tasks:
            if s.name not in status:
                status[s.name] = [""] * k
                residuals[s.name] = [float("nan")] * k
            status[s.name].append(s.status.value)
            residuals[s.name].append(s.residual)
        for task in controller.stack.tasks:
            err = task.error()
            if task.name not in errors:
                errors[task.name] = [float("nan")] * k
            errors[task.name].append(float(np.linalg.norm(err)) if err.size else 0.0)
        for table, fill in ((status, ""), (residuals, float("nan")), (errors, float("nan"))):
            for name in table:
                if len(table[name]) < k + 1:
                    table[name].append(fill)
        if on_step is not None:
            on_step(sim, cmd)
        sim.step(cmd.tau, force if np.any(force) else None)
        rows["clip"].append(sim.last_clipped)
        if fell_at is None and (
            sim.base_height() < FALL_HEIGHT_RATIO * robot.standing_height
            or reading.other_contact
        ):
            fell_at = t
            logger.info("t=%.3f: fell (base %.3f m, other contacts %s)", t, sim.base_height(),
                        reading.other_contact)
            if stop_on_fall:
                break
        if progress is not None and k % 100 == 0:
            progress(t)

    def arr(key: str, shape: tuple[int, ...]) -> np.ndarray:
        return np.array(rows[key]) if rows[key] else np.zeros((0, *shape))

    # Support margin: CoM inside the hull of the sole corners of the feet in contact.
    margins = np.full(len(rows["t"]), np.nan)
    for i, (corners, touching, com) in enumerate(zip(rows["corners"], rows["fc"], rows["com"])):
        if np.any(touching):
            margins[i] = inside_polygon(com[:2], corners[touching].reshape(-1, 3)[:, :2])

    return Log(
        robot=robot.name,
        t=arr("t", ()),
        q=arr("q", (sim.nq,)),
        v=arr("v", (sim.nv,)),
        tau=arr("tau", (sim.na,)),
        com=arr("com", (3,)),
        base_height=arr("base", ()),
        foot_contact=arr("fc", (nfeet,)).astype(bool),
        foot_position=arr("fp", (nfeet, 3)),
        normal_force=arr("fn", (nfeet,)),
        other_contact=arr("other", ()).astype(bool),
        cop=arr("cop", (2,)),
        support_margin=margins,
        task_errors={k: np.array(v) for k, v in errors.items()},
        residuals={k: np.array(v) for k, v in residuals.items()},
        status=status,
        safe_mode=arr("safe", ()).astype(bool),
        strictness_suspended=arr("susp", ()).astype(bool),
        clipped=arr("clip", ()).astype(int),
        step_time=arr("time", ()),
        events=applied,
        standing_height=robot.standing_height,
        fell_at=fell_at,
    )
