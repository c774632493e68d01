"""The simulation side of ``hqp view``: a behavior in closed loop on its own thread.

:class:`ViewSession` runs a library behavior the way ``hqp run`` does
(:func:`hqp.behaviors.setup.prepare`, :func:`hqp.sim.closed_loop` with the clock ``k dt``, the
hooks of :class:`hqp.app.run._Meter`), on a thread of its own, and takes commands from any
other thread (the web page's callbacks): pick a behavior, pause, single step, reset, push,
move a goal. It never waits on the page: commands go into a queue that the loop drains
between control steps, and the loop publishes a :class:`Snapshot` (body poses, the
feasibility report, strip-chart samples) that the page reads when it draws. The loop
publishes at the page's frame rate (:data:`PUBLISH_PERIOD` of wall-clock time), not at every
step, and rebuilds the task panel and the charts' arrays only every :data:`PANEL_PERIOD`;
between two publishes a control step costs the loop no Python allocation of its own. Paced,
the loop sleeps until a deadline clock (simulated time over wall-clock time since the loop
last started or stalled), so pacing does not drift.

Goals reach the tasks through the runtime-input path of behavior files
(:class:`hqp.behaviors.inputs.InputStream`): each behavior runs with an inputs file of its
own (JSON Lines), and a goal moved in the page is a line ``{"t": ..., "<input>": [...]}``
appended to it, read by the behavior as simulated time advances, and tracked by the task's
saturated PD reference like any goal. The file is also the record: ``hqp run BEHAVIOR
--inputs FILE`` replays the goals given in the page.

What was done in the page (behaviors picked, goals, pushes, pauses, resets) is recorded with
the simulated time of each action; :meth:`ViewSession.record` returns the run JSON (one
``hqp run --json`` object per behavior run, each with its actions) and writes it, with an MP4
where offscreen rendering is available, when the session has a record folder.
"""

from __future__ import annotations

import inspect
import json
import logging
import tempfile
import threading
import time
from collections import deque
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from hqp import robots
from hqp.app.run import BehaviorRun, _Meter
from hqp.behaviors.behavior import Behavior
from hqp.behaviors.loader import library_names
from hqp.behaviors.setup import prepare
from hqp.control.diagnostics import Diagnostics
from hqp.control.presets import CONTROLLER_NAMES
from hqp.errors import InvalidInput, UnknownName
from hqp.sim.loop import Step, closed_loop
from hqp.sim.render import Video, rendering_available
from hqp.sim.simulator import ContactReading, Simulator

logger = logging.getLogger(__name__)

GOAL_TYPES = ("position", "orientation", "pose")
"""Task types whose goals get a handle in the page (when a goal reads a runtime input)."""
CHART_SIGNALS = ("cog_error_mm", "torque_ratio", "torque_change_nm")
"""Strip-chart signals: horizontal distance of the centre of gravity from its goal [mm], the
largest ratio of a commanded torque to its limit, the largest torque change in one step
[N m]."""
CHART_LENGTH = 600
"""Samples kept per strip chart (one every :data:`CHART_PERIOD` of simulated time)."""
CHART_PERIOD = 0.01
"""Simulated time between two strip-chart samples [s]."""
PUBLISH_PERIOD = 1.0 / 30.0
"""Wall-clock time between two snapshots the loop publishes [s] (the page's frame rate)."""
PANEL_PERIOD = 0.2
"""Wall-clock time between two refreshes of a snapshot's task panel and charts [s]."""
RATE_WINDOW = 1.0
"""Wall-clock window of the real-time factor a snapshot shows [s]."""
PACE_SLACK = 0.1
"""How far behind the deadline clock the paced loop may fall before it restarts the clock
instead of catching up [s]."""
SEGMENT_DURATION = 1e7
"""Duration given to :func:`~hqp.sim.closed_loop` [s]: a behavior runs until the page ends it."""


@dataclass(frozen=True)
class GoalHandle:
    """A goal the page can move: a runtime input read by an active task's goal.

    Attributes:
        input: The input's name (``input.<name>`` in the behavior file).
        task: The task whose goal reads it.
        kind: ``"position"`` (a point ``(3,)`` [m], world frame) or ``"orientation"``
            (roll-pitch-yaw ``(3,)`` [rad]).
        value: Its value at the last control step.

    """

    input: str
    task: str
    kind: str
    value: tuple[float, ...]


@dataclass(frozen=True)
class TaskRow:
    """One line of the task panel: a task of the feasibility report.

    Attributes:
        name: Task name.
        level: Its level (0 is the highest priority).
        status: ``satisfied``, ``conflict``, ``singular`` or ``inactive``.
        yields_to: For a conflict, the level it yields to (``None``: not computed or none).
        residual: Norm of its unweighted residual (row units).
        sigma_min: Smallest singular value of its projected rows (``nan``: not computed).
        error: Norm of the task's error (task units: m, rad, ...; ``nan`` when it has none).

    """

    name: str
    level: int
    status: str
    yields_to: int | None
    residual: float
    sigma_min: float
    error: float


@dataclass(frozen=True)
class Snapshot:
    """What the page draws, published by the loop (read-only copies).

    Attributes:
        t: Simulated time of the behavior [s].
        behavior: Its name.
        phase: Its active phase.
        paused: Whether the loop is paused.
        fell: Fall reason, or ``None``.
        xpos: MuJoCo body positions ``(nbody, 3)`` [m].
        xmat: MuJoCo body rotations ``(nbody, 9)``.
        tasks: The task panel, in level order (behavior tasks and constraints).
        goals: Goals the page can move.
        frames: World position ``(3,)`` [m] of each goal's task frame.
        realtime_factor: Simulated seconds per wall-clock second over the last second.
        steps: Control steps of this behavior run.
        chart_t: Times of the strip-chart samples [s].
        charts: Samples of each of :data:`CHART_SIGNALS`.

    """

    t: float
    behavior: str
    phase: str
    paused: bool
    fell: str | None
    xpos: np.ndarray
    xmat: np.ndarray
    tasks: tuple[TaskRow, ...]
    goals: tuple[GoalHandle, ...]
    frames: dict[str, tuple[float, float, float]]
    realtime_factor: float
    steps: int
    chart_t: np.ndarray
    charts: dict[str, np.ndarray]


class _EndRun(Exception):
    """Raised from a loop hook to end the behavior's closed loop (new behavior, reset, stop)."""


class _PushedSimulator:
    """The simulator as :func:`~hqp.sim.closed_loop` sees it, plus the page's pushes.

    Pushes given in the page start at a simulated time that is not known when the loop
    starts, so they cannot be :class:`~hqp.sim.Push` events of the loop; this adds their
    force to the one the loop applies, at the base body as :meth:`Simulator.step` does.
    """

    def __init__(self, sim: Simulator) -> None:
        self._sim = sim
        self.pushes: list[tuple[float, np.ndarray, float]] = []  # (start, force, end) [s, N]
        self.clock = 0.0  # control time of the step being run [s]

    def __getattr__(self, name: str) -> Any:
        value = getattr(self._sim, name)
        if inspect.ismethod(value):
            setattr(self, name, value)  # a bound method: looked up once, not at every step
        return value

    def step(self, tau: np.ndarray | None = None, force: np.ndarray | None = None) -> None:
        if self.pushes:
            t = self.clock
            self.pushes = [p for p in self.pushes if p[2] > t]
            extra = sum((p[1] for p in self.pushes if p[0] <= t), np.zeros(3))
            if np.any(extra):
                force = extra if force is None else force + extra
        self._sim.step(tau, force)


@dataclass
class _Run:
    """One behavior run of the session (a segment between two behavior picks or resets)."""

    name: str
    behavior: Behavior
    controller: Any
    meter: _Meter
    inputs_path: Path
    inputs_file: Any
    actions: list[dict[str, Any]] = field(default_factory=list)
    steps: int = 0
    t_end: float = 0.0
    wall: float = 0.0
    cpu: float = 0.0
    fell_at: float | None = None
    fall_reason: str | None = None
    last_input: dict[str, tuple[float, np.ndarray]] = field(default_factory=dict)


class ViewSession:
    """A behavior in closed loop with MuJoCo on its own thread, driven by commands.

    Args:
        behavior: Library behavior to start with (see ``hqp behaviors``).
        robot: Robot name (default: each behavior's).
        controller: ``"hqp"`` or ``"nullspace"``.
        realtime: Pace the loop to the wall clock (else as fast as it runs).
        record_dir: Folder of the record (inputs files, ``run.json``, ``view.mp4``); ``None``:
            a temporary folder, nothing kept.
        video: Record an MP4 of the session (needs offscreen rendering).
        diagnostics: Feasibility report mode of the controller (``"full"``: the level a
            conflicting task yields to and per-task projected singular values).

    Raises:
        UnknownName: Unknown behavior or controller.

    """

    def __init__(self, behavior: str = "stand", *, robot: str | None = None,
                 controller: str = "hqp", realtime: bool = True,
                 record_dir: str | Path | None = None, video: bool = False,
                 diagnostics: str = "full") -> None:
        self.behaviors = library_names()
        if behavior not in self.behaviors:
            raise UnknownName("behavior", behavior, self.behaviors)
        if controller not in CONTROLLER_NAMES:
            raise UnknownName("controller", controller, CONTROLLER_NAMES)
        if robot is not None:
            robots.check(robot)
        self.robot_name = robot
        self.controller_name = controller
        self.realtime = bool(realtime)
        self.diagnostics = diagnostics
        self._tmp = None
        if record_dir is None:
            self._tmp = tempfile.TemporaryDirectory(prefix="hqp-view-")
            record_dir = self._tmp.name
        self.record_dir = Path(record_dir)
        self.record_dir.mkdir(parents=True, exist_ok=True)
        self.runs: list[_Run] = []
        # appended by the page's threads, popped by the loop (deque: atomic, no lock taken)
        self._commands: deque[tuple[str, Any]] = deque()
        self._lock = threading.Lock()
        self._snapshot: Snapshot | None = None
        self._stop = threading.Event()
        self._paused = False
        self._single = 0
        self._pending_behavior = behavior
        self._thread: threading.Thread | None = None
        self._error: BaseException | None = None
        self._chart_t: deque[float] = deque(maxlen=CHART_LENGTH)
        self._charts = {s: deque(maxlen=CHART_LENGTH) for s in CHART_SIGNALS}
        self._rate: deque[tuple[float, float]] = deque()  # (wall, sim) at each publish
        self._next_publish = 0.0  # wall clock of the next publish [s]
        self._next_panel = 0.0  # wall clock of the next task panel refresh [s]
        self._rows: tuple[TaskRow, ...] = ()
        self._chart_arrays: tuple[np.ndarray, dict[str, np.ndarray]] = (
            np.zeros(0), {s: np.zeros(0) for s in CHART_SIGNALS})
        self._video_wanted = bool(video)
        self.video: Video | None = None
        self.video_note: str | None = None
        self.session_time = 0.0  # simulated time over every run of the session [s]
        self.page_figures: dict[str, float] | None = None  # the page's, for the record
        self._pace = (0.0, 0.0)  # (wall clock, session time) the pacing counts from
        self._last_report: Any = None
        self._last_jump = 0.0
        self._next_chart = 0.0
        self.sim = self._first_simulator(behavior)

    # -- commands (any thread) ----------------------------------------------------------------

    def select(self, name: str) -> None:
        """Start behavior ``name`` from the current state."""
        if name not in self.behaviors:
            raise UnknownName("behavior", name, self.behaviors)
        self._commands.append(("select", name))

    def pause(self) -> None:
        """Pause the loop."""
        self._commands.append(("pause", None))

    def resume(self) -> None:
        """Resume the loop."""
        self._commands.append(("resume", None))

    def single_step(self) -> None:
        """Pause, then run one control step."""
        self._commands.append(("single", None))

    def reset(self) -> None:
        """Put the robot back standing at rest and restart the current behavior."""
        self._commands.append(("reset", None))

    def push(self, force: Any, duration: float = 0.1) -> None:
        """Push the floating base with a world force ``(3,)`` [N] for ``duration`` [s].

        Raises:
            InvalidInput: A force not ``(3,)`` finite, or a non-positive duration.

        """
        f = np.asarray(force, dtype=float)
        if f.shape != (3,) or not np.isfinite(f).all():
            raise InvalidInput(f"view: push force must be 3 finite numbers [N], got {force!r}")
        if not np.isfinite(duration) or duration <= 0.0:
            raise InvalidInput(f"view: push duration must be positive [s], got {duration}")
        self._commands.append(("push", (f, float(duration))))

    def set_goal(self, input_name: str, value: Any) -> None:
        """Move a goal: a new sample of runtime input ``input_name`` at the current time.

        Raises:
            InvalidInput: A value that is not 3 finite numbers.

        """
        v = np.asarray(value, dtype=float)
        if v.shape != (3,) or not np.isfinite(v).all():
            raise InvalidInput(f"view: goal {input_name!r} must be 3 finite numbers, "
                               f"got {value!r}")
        self._commands.append(("goal", (input_name, v)))

    def snapshot(self) -> Snapshot | None:
        """Return the last published snapshot (``None`` before the first step)."""
        with self._lock:
            return self._snapshot

    @property
    def error(self) -> BaseException | None:
        """The exception that ended the loop thread, if any."""
        return self._error

    # -- thread -----------------------------------------------------------------------------

    def start(self) -> None:
        """Start the loop thread."""
        self._thread = threading.Thread(target=self._main, name="hqp-view-loop", daemon=True)
        self._thread.start()

    def stop(self, timeout: float = 10.0) -> None:
        """Stop the loop thread (it ends within one control step) and close the files."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout)
        for run in self.runs:
            if not run.inputs_file.closed:
                run.inputs_file.close()
            run.behavior.inputs.close()

    def wait(self, predicate: Any, timeout: float = 30.0, poll: float = 0.02) -> Snapshot:
        """Block until ``predicate(snapshot)`` holds; return that snapshot (tests, scripts).

        Raises:
            TimeoutError: It did not hold within ``timeout`` [s] (or the loop died).

        """
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            if self._error is not None:
                raise TimeoutError(f"view: the loop thread failed: {self._error!r}")
            snap = self.snapshot()
            if snap is not None and predicate(snap):
                return snap
            time.sleep(poll)
        raise TimeoutError(f"view: condition not met within {timeout} s")

    def _first_simulator(self, behavior: str) -> Simulator:
        # the robot of the first behavior (or --robot) is the session's robot
        _, _, robot = prepare(behavior, robot=self.robot_name, controller=self.controller_name)
        self.robot = robot
        return Simulator(robot)

    def _main(self) -> None:
        try:
            while not self._stop.is_set():
                name = self._pending_behavior
                self._pending_behavior = None
                self._run(name)
        except BaseException as exc:  # noqa: BLE001 - reported to the page and the caller
            self._error = exc
            logger.exception("view: the simulation loop failed")
        finally:
            self._finish_video()

    # -- one behavior run -------------------------------------------------------------------

    def _new_run(self, name: str) -> _Run:
        index = len(self.runs) + 1
        path = self.record_dir / f"inputs_{index:02d}_{name}.jsonl"
        handle = path.open("w")
        # the session's robot: --robot (a name or a robot file), else the first behavior's
        source = self.robot_name if self.robot_name is not None else self.robot.name
        behavior, ctrl, robot = prepare(name, robot=source, controller=self.controller_name,
                                        inputs=path)
        if self.diagnostics != getattr(ctrl, "diagnostics", self.diagnostics):
            ctrl.feasibility = Diagnostics(ctrl.tolerance, ctrl.singular_tolerance,
                                           self.diagnostics)
            ctrl.diagnostics = self.diagnostics
        ctrl.dt = self.sim.dt
        if self._video_wanted and self.video is None and self.video_note is None:
            ok, message = rendering_available()
            if ok:
                self.video = Video(self.sim, self.record_dir / "view.mp4", distance=3.5,
                                   azimuth=120.0, elevation=-15.0)
            else:
                self.video_note = message
        meter = _Meter(behavior, self.sim, list(robot.feet), False, None)
        run = _Run(name, behavior, ctrl, meter, path, handle)
        self.runs.append(run)
        return run

    def _run(self, name: str) -> None:
        run = self._new_run(name)
        pushed = _PushedSimulator(self.sim)
        run.behavior.start(self.sim.state(), 0.0)
        self._action(run, 0.0, "behavior", name=name)
        wall0 = time.perf_counter()
        cpu0 = time.thread_time()
        self._pace = (time.perf_counter(), self.session_time)
        self._next_chart = 0.0
        self._next_publish = self._next_panel = 0.0

        def before(step: Step) -> None:
            pushed.clock = step.t
            self._before(run, step)

        def after(step: Step, reading: ContactReading) -> None:
            self._after(run, step, reading)
            run.wall = time.perf_counter() - wall0
            self._between_steps(run, pushed, step.t + self.sim.dt)

        self._between_steps(run, pushed, 0.0)
        try:
            closed_loop(pushed, run.behavior, SEGMENT_DURATION, before_step=before,
                        after_step=after, clock="steps", stop_on_fall=False)
        except _EndRun:
            pass
        run.cpu = time.thread_time() - cpu0
        run.inputs_file.close()

    def _before(self, run: _Run, step: Step) -> None:
        meter = run.meter
        n = meter.n_jumps
        meter.before_step(step)
        self._last_report = step.command.report
        # the meter's largest torque change of this step (none at the run's first step)
        self._last_jump = float(meter.jump[n]) if meter.n_jumps > n else 0.0

    def _after(self, run: _Run, step: Step, reading: ContactReading) -> None:
        run.meter.after_step(step, reading)
        run.steps = step.k + 1
        run.t_end = (step.k + 1) * self.sim.dt
        self.session_time += self.sim.dt
        if self.video is not None:
            self.video.capture(self.session_time)
        reason = self.sim.fall_reason(reading)
        if reason is not None and run.fell_at is None:
            run.fell_at, run.fall_reason = step.t, reason
            self._action(run, step.t, "fell", reason=reason)
        t = run.t_end
        if t + 1e-9 >= self._next_chart:
            self._next_chart = t + CHART_PERIOD
            self._chart_t.append(self.session_time)
            self._charts["cog_error_mm"].append(1e3 * self._cog_error(run))
            self._charts["torque_ratio"].append(run.meter.ratio)
            self._charts["torque_change_nm"].append(self._last_jump)
        now = time.perf_counter()
        if now >= self._next_publish:
            self._publish(run, t, now)

    def _between_steps(self, run: _Run, pushed: _PushedSimulator, t: float) -> None:
        """Apply the commands, wait while paused, pace to the wall clock."""
        while True:
            self._apply_commands(run, pushed, t)
            if self._stop.is_set():
                raise _EndRun
            if not self._paused:
                break
            if self._single > 0:
                self._single -= 1
                break
            self._publish(run, t, time.perf_counter(), panel=True)
            self._pace = (time.perf_counter(), self.session_time)
            time.sleep(0.01)
        if self.realtime:
            # the deadline of this step: its simulated time on the wall clock of the pace
            wall0, sim0 = self._pace
            ahead = (self.session_time - sim0) - (time.perf_counter() - wall0)
            if ahead > 0.002:
                time.sleep(ahead)
            elif ahead < -PACE_SLACK:  # slower than real time: do not try to catch up later
                self._pace = (time.perf_counter(), self.session_time)

    def _apply_commands(self, run: _Run, pushed: _PushedSimulator, t: float) -> None:
        commands = self._commands
        while commands:
            kind, arg = commands.popleft()
            if kind == "pause":
                self._paused = True
                self._action(run, t, "pause")
            elif kind == "resume":
                self._paused = False
                self._single = 0
                self._action(run, t, "resume")
            elif kind == "single":
                self._paused = True
                self._single += 1
                self._action(run, t, "step")
            elif kind == "push":
                force, duration = arg
                pushed.pushes.append((t, force, t + duration))
                self._action(run, t, "push", force_n=force.tolist(), duration_s=duration)
            elif kind == "goal":
                self._goal(run, t, *arg)
            elif kind == "select":
                self._action(run, t, "end", next=arg)
                self._pending_behavior = arg
                raise _EndRun
            elif kind == "reset":
                self._action(run, t, "reset")
                self.sim.reset()
                self._pending_behavior = run.name
                raise _EndRun

    def _goal(self, run: _Run, t: float, name: str, value: np.ndarray) -> None:
        if name not in run.behavior.spec.inputs:
            logger.warning("view: behavior %s has no input %r", run.name, name)
            return
        if run.behavior.spec.inputs[name].shape != (3,):
            logger.warning("view: input %r is not a 3-vector", name)
            return
        # the runtime-input path: one JSON line, read by the behavior as time advances
        rel = round(t, 6)
        run.inputs_file.write(json.dumps({"t": rel, name: [round(float(x), 6) for x in value]})
                              + "\n")
        run.inputs_file.flush()
        run.last_input[name] = (rel, value)
        self._action(run, t, "goal", input=name, value=[round(float(x), 6) for x in value])

    def _action(self, run: _Run, t: float, kind: str, **data: Any) -> None:
        run.actions.append({"t": round(t, 4), "action": kind, **data})

    # -- what the page reads ----------------------------------------------------------------

    def _cog_error(self, run: _Run) -> float:
        """Horizontal distance of the centre of gravity from its goal [m] (``nan``: no CoG task).

        The error of the active phase's CoG task at its last rows (goal minus current).
        """
        for ts in run.behavior.phase_spec.action.tasks:
            if ts.type == "com":
                err = np.asarray(run.behavior.tasks[ts.name].error(), dtype=float)
                if err.size >= 2:
                    return float(np.linalg.norm(err[:2]))
        return float("nan")

    def goal_handles(self, run: _Run, t: float) -> tuple[GoalHandle, ...]:
        """Goals of the active position, orientation and pose tasks that read an input."""
        behavior = run.behavior
        out: list[GoalHandle] = []
        seen: set[str] = set()
        phase = behavior.phase_spec
        for ts in phase.action.tasks:
            if ts.type not in GOAL_TYPES:
                continue
            goals = dict(ts.goals)
            goals.update(phase.goals.get(ts.name, {}))
            for gname, expr in goals.items():
                direct = [a for ns, a in expr.attributes if ns == "input"]
                if len(direct) != 1 or expr.source.strip() != f"input.{direct[0]}":
                    continue  # only goals that are an input itself get a handle
                iname = direct[0]
                if iname in seen or behavior.spec.inputs[iname].shape != (3,):
                    continue
                seen.add(iname)
                kind = ("orientation" if ts.type == "orientation" or gname == "goal_rotation"
                        else "position")
                value = behavior.inputs.value(iname, t)
                out.append(GoalHandle(iname, ts.name, kind, tuple(float(x) for x in value)))
        return tuple(out)

    def _task_rows(self, run: _Run) -> tuple[TaskRow, ...]:
        """Return the task panel of the last step's feasibility report, with the errors."""
        report = self._last_report
        active = set(run.behavior.phase_spec.action.task_names)
        rows: list[TaskRow] = []
        if report is not None:
            for s in report.tasks:
                task = run.behavior.tasks.get(s.name)
                err = float("nan")
                if task is not None and s.name in active:
                    e = np.asarray(task.error(), dtype=float)
                    err = float(np.linalg.norm(e)) if e.size else float("nan")
                rows.append(TaskRow(s.name, s.level, s.status.value, s.yields_to,
                                    float(s.residual), float(s.sigma_min), err))
        return tuple(rows)

    def _publish(self, run: _Run, t: float, now: float, panel: bool = False) -> None:
        """Publish a snapshot at wall clock ``now`` [s]; the panel and charts when due or asked."""
        self._next_publish = now + PUBLISH_PERIOD
        if panel or now >= self._next_panel:
            self._next_panel = now + PANEL_PERIOD
            self._rows = self._task_rows(run)
            self._chart_arrays = (np.asarray(self._chart_t),
                                  {k: np.asarray(v) for k, v in self._charts.items()})
        goals = self.goal_handles(run, t)
        model = run.controller.model
        frames = {}
        for g in goals:
            frame = run.behavior.spec.tasks[g.task].frames.get("frame")
            if frame is not None:
                frames[g.task] = tuple(float(x) for x in model.frame_placement(frame).translation)
        rate = self._rate
        rate.append((now, self.session_time))
        while len(rate) > 2 and rate[1][0] <= now - RATE_WINDOW:
            rate.popleft()
        rf = 0.0
        if len(rate) > 1:
            w0, s0 = rate[0]
            rf = (self.session_time - s0) / (now - w0) if now > w0 else 0.0
        data = self.sim.mj_data
        chart_t, charts = self._chart_arrays
        snap = Snapshot(
            t=t, behavior=run.name, phase=run.behavior.phase.value, paused=self._paused,
            fell=run.fall_reason, xpos=data.xpos.copy(), xmat=data.xmat.copy(),
            tasks=self._rows, goals=goals, frames=frames, realtime_factor=rf,
            steps=run.steps, chart_t=chart_t, charts=charts)
        with self._lock:
            self._snapshot = snap

    # -- the record -------------------------------------------------------------------------

    def record(self) -> dict[str, Any]:
        """Return the session's run JSON: one ``hqp run --json`` object per behavior run.

        Each run also holds ``actions`` (what was done in the page, with the simulated time
        of the run) and ``inputs_file`` (the goals given, replayable with ``hqp run
        --inputs``). Call it once the loop has stopped.
        """
        runs = []
        for run in self.runs:
            metrics = run.meter.metrics(run.t_end, getattr(run.controller, "backend", None))
            metrics["realtime_factor"] = round(run.t_end / run.wall, 3) if run.wall > 0 else 0.0
            # the loop thread's CPU time: its wall time less its sleeps and its waits for
            # the GIL or a core
            metrics["loop_cpu_s"] = round(run.cpu, 3)
            metrics.update(run.behavior.metrics())
            result = BehaviorRun(
                behavior=run.name, robot=self.robot.name, controller=self.controller_name,
                duration_s=run.t_end, fell=run.fell_at is not None,
                fall_reason=run.fall_reason, phases=list(run.behavior.visited),
                steps=run.meter.steps(),
                feasibility_events=[e.as_dict() for e in run.behavior.events],
                metrics=metrics)
            data = result.as_json()
            data["actions"] = run.actions
            data["inputs_file"] = str(run.inputs_path) if self._tmp is None else None
            runs.append(data)
        return {"viewer": {"robot": self.robot.name, "controller": self.controller_name,
                           "realtime": self.realtime, "page": self.page_figures,
                           "video": None if self.video is None else str(self.video.path),
                           "video_note": self.video_note},
                "runs": runs}

    def write_record(self) -> Path | None:
        """Write ``run.json`` into the record folder (``None``: no record folder)."""
        if self._tmp is not None:
            return None
        path = self.record_dir / "run.json"
        path.write_text(json.dumps(self.record(), indent=1) + "\n")
        return path

    def close(self) -> None:
        """Stop the loop and remove the temporary folder (when there is no record folder)."""
        self.stop()
        if self._tmp is not None:
            self._tmp.cleanup()

    def _finish_video(self) -> None:
        if self.video is not None:
            try:
                self.video.close()
            except Exception as exc:  # noqa: BLE001 - a record must not crash the viewer
                self.video_note = f"video not written: {exc}"


def rpy_to_wxyz(rpy: Any) -> tuple[float, float, float, float]:
    """Quaternion ``(w, x, y, z)`` of roll-pitch-yaw ``(3,)`` [rad] (the page's handles)."""
    q = pin.Quaternion(pin.rpy.rpyToMatrix(np.asarray(rpy, dtype=float)))
    return (float(q.w), float(q.x), float(q.y), float(q.z))


def wxyz_to_rpy(wxyz: Any) -> np.ndarray:
    """Roll-pitch-yaw ``(3,)`` [rad] of a quaternion ``(w, x, y, z)``."""
    w, x, y, z = (float(c) for c in wxyz)
    q = pin.Quaternion(w, x, y, z)
    q.normalize()
    return np.asarray(pin.rpy.matrixToRpy(q.toRotationMatrix()), dtype=float)


__all__ = ["CHART_SIGNALS", "GoalHandle", "Snapshot", "TaskRow", "ViewSession",
           "rpy_to_wxyz", "wxyz_to_rpy"]
