"""A controller in MuJoCo, logged: :func:`simulate` and its :class:`Log`.

:func:`simulate` runs a controller on a robot through the closed loop of :mod:`hqp.sim.loop`
(pushes on the base, timed changes of goals, tasks and contacts, noise and delay), and returns
a :class:`Log` of what happened, read from MuJoCo where it concerns contacts (which geoms
touch the floor, slip and lift-off of the feet, centre of pressure) and from the controller's
commands otherwise (torques, task errors, feasibility flags).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from hqp.sim.loop import Event, Noise, Outcome, Push, Step, check_run, closed_loop
from hqp.sim.simulator import Simulator, inside_polygon

if TYPE_CHECKING:
    from hqp.controller import Controller
    from hqp.robots import Robot

__all__ = ["Event", "Log", "Noise", "Push", "simulate"]


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
        fall_reason: Why it fell (``Simulator.fall_reason``, or a diverged simulation).
        wall_time: Wall-clock duration of the closed loop [s] (controller, MuJoCo, logging).

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
    fall_reason: str | None = None
    wall_time: float = 0.0

    @property
    def realtime_factor(self) -> float:
        """Simulated seconds per wall-clock second of the closed loop (0 when nothing ran)."""
        simulated = float(self.t[-1] - self.t[0]) + self.dt if self.t.size else 0.0
        return simulated / self.wall_time if self.wall_time > 0.0 else 0.0

    @property
    def dt(self) -> float:
        """Control period of the run [s] (0 with fewer than two steps)."""
        return float(self.t[1] - self.t[0]) if self.t.size > 1 else 0.0

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
            "realtime_factor": self.realtime_factor,
        }


class _Recorder:
    """The ``before_step`` hook of :func:`simulate`: one row of the :class:`Log` per step."""

    def __init__(self, sim: Simulator, controller: Any,
                 on_step: Callable[[Simulator, Any], None] | None, capacity: int) -> None:
        self.sim = sim
        self.controller = controller
        self.on_step = on_step
        self.capacity = capacity
        self.n = 0
        # one array per quantity, preallocated for ``capacity`` steps at its first value
        # (that value's shape and type: the array ``np.array`` would make of the rows)
        self.rows: dict[str, np.ndarray | None] = dict.fromkeys((
            "t", "q", "v", "tau", "com", "base", "fc", "fp", "fn", "other", "cop", "corners",
            "safe", "susp", "time"))
        self.errors: dict[str, list[float]] = {}
        self.residuals: dict[str, list[float]] = {}
        self.status: dict[str, list[str]] = {}

    def __call__(self, step: Step) -> None:
        sim, cmd, reading, k = self.sim, step.command, step.reading, step.k
        for key, value in (
                ("t", step.t), ("q", step.state.q), ("v", step.state.v),
                ("tau", cmd.tau), ("com", sim.com()), ("base", sim.base_height()),
                ("fc", reading.foot_contact), ("fp", reading.foot_position),
                ("fn", reading.normal_force), ("other", bool(reading.other_contact)),
                ("cop", reading.cop), ("corners", sim.sole_corners()), ("safe", cmd.safe_mode),
                ("susp", cmd.report.strictness_suspended), ("time", step.wall_time)):
            rows = self.rows[key]
            if rows is None:
                first = np.asarray(value)
                rows = self.rows[key] = np.empty((self.capacity, *first.shape), first.dtype)
            rows[k] = value
        self.n = k + 1
        for s in cmd.report.tasks:
            if s.name not in self.status:
                self.status[s.name] = [""] * k
                self.residuals[s.name] = [float("nan")] * k
            self.status[s.name].append(s.status.value)
            self.residuals[s.name].append(s.residual)
        for task in self.controller.stack.tasks:
            err = task.error()
            if task.name not in self.errors:
                self.errors[task.name] = [float("nan")] * k
            self.errors[task.name].append(float(np.linalg.norm(err)) if err.size else 0.0)
        for table, fill in ((self.status, ""), (self.residuals, float("nan")),
                            (self.errors, float("nan"))):
            for name in table:
                if len(table[name]) < k + 1:
                    table[name].append(fill)
        if self.on_step is not None:
            self.on_step(sim, cmd)

    def log(self, robot: Robot, clipped: list[int], outcome: Outcome) -> Log:
        sim, nfeet, n = self.sim, len(robot.feet), self.n

        def arr(key: str, shape: tuple[int, ...]) -> np.ndarray:
            rows = self.rows[key]
            return rows[:n] if rows is not None and n else np.zeros((0, *shape))

        # Support margin: CoM inside the hull of the sole corners of the feet in contact.
        margins = np.full(n, np.nan)
        for i, (corners, touching, com) in enumerate(zip(arr("corners", ()), arr("fc", ()),
                                                         arr("com", ()))):
            if np.any(touching):
                margins[i] = inside_polygon(com[:2], corners[touching].reshape(-1, 3)[:, :2])
        return Log(
            robot=robot.name, t=arr("t", ()), q=arr("q", (sim.nq,)), v=arr("v", (sim.nv,)),
            tau=arr("tau", (sim.na,)), com=arr("com", (3,)), base_height=arr("base", ()),
            foot_contact=arr("fc", (nfeet,)).astype(bool), foot_position=arr("fp", (nfeet, 3)),
            normal_force=arr("fn", (nfeet,)), other_contact=arr("other", ()).astype(bool),
            cop=arr("cop", (2,)), support_margin=margins,
            task_errors={k: np.array(v) for k, v in self.errors.items()},
            residuals={k: np.array(v) for k, v in self.residuals.items()},
            status=self.status, safe_mode=arr("safe", ()).astype(bool),
            strictness_suspended=arr("susp", ()).astype(bool),
            clipped=np.array(clipped, dtype=int), step_time=arr("time", ()),
            events=outcome.events, standing_height=robot.standing_height,
            fell_at=outcome.fell_at, fall_reason=outcome.fall_reason,
            wall_time=outcome.wall_time,
        )


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
    """Run a controller in closed loop on a robot in MuJoCo and log it (:func:`closed_loop`).

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
    check_run(duration, delay_steps, "simulate")
    if sim is None:
        sim = Simulator(robot, dt=getattr(controller, "dt", 0.001))
        sim.reset(q0, v0)
    elif q0 is not None or v0 is not None:
        sim.reset(q0, v0)
    recorder = _Recorder(sim, controller, on_step, int(round(duration / sim.dt)))
    clipped: list[int] = []
    outcome = closed_loop(
        sim, controller, duration, events, noise=noise, delay_steps=delay_steps,
        before_step=recorder, after_step=lambda step, reading: clipped.append(sim.last_clipped),
        stop_on_fall=stop_on_fall, progress=progress)
    return recorder.log(robot, clipped, outcome)
