"""``hqp run``: a behavior in closed loop with MuJoCo, measured.

:func:`run_behavior` prepares a behavior (:func:`hqp.behaviors.setup.prepare`) and drives it
through :func:`hqp.sim.closed_loop` (clock ``k dt``). Measured and reported (the JSON of
``hqp run --json``, :meth:`BehaviorRun.as_json`): whether the robot fell
(:meth:`hqp.sim.Simulator.fall_reason`), the phases visited, the footsteps completed (a swing
foot out of contact for at least 0.1 s that lands at least 0.10 m ahead of where it lifted),
the feasibility events, the longest flight (no foot in contact) and the highest the lower foot
site rose during flights (``flight_clearance_m``), the largest ratio of a commanded torque to
its limit, the largest per-step torque change (``max_torque_jump_nm``; the landings after a
flight apart: ``impacts`` and ``max_torque_jump_outside_impacts_nm``), and for planned
behaviors the mean forward speed and the largest horizontal centre-of-mass tracking error.
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from hqp import robots
from hqp.app.console import fallback_note, output_path_problem, progress_bar, stdout_to_stderr
from hqp.behaviors.behavior import Behavior
from hqp.behaviors.setup import prepare
from hqp.behaviors.spec import BehaviorSpec
from hqp.control.presets import CONTROLLER_NAMES
from hqp.errors import InvalidInput, UnknownBackend
from hqp.plots import Line, Panel, plot_panels
from hqp.sim.loop import Step, closed_loop
from hqp.sim.render import Video
from hqp.sim.simulator import ContactReading, Simulator
from hqp.solver.backends import known_backends
from hqp.solver.qp import last_resort_count

STEP_MIN_AIR_TIME = 0.1
"""A footstep: the swing foot is out of contact at least this long [s] ..."""
STEP_MIN_ADVANCE = 0.10
"""... and lands at least this far ahead (world x) of where it lifted [m]."""
IMPACT_WINDOW_S = 0.05
"""The steps of an impact: commands at most this long after a foot meets the floor at the
end of a flight (no foot in contact) [s]; their torque changes are reported apart."""


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


@dataclass
class BehaviorRun:
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


class _Meter:
    """The hooks of a behavior run: what :class:`BehaviorRun` reports, step by step."""

    def __init__(self, behavior: Behavior, sim: Simulator, feet: list[str], trace: bool,
                 video: Video | None, capacity: int = 0) -> None:
        self.behavior, self.sim, self.video = behavior, sim, video
        self.model = behavior.controller.model
        self.trackers = {c: FootTracker(c) for c in feet}
        self._trackers = list(self.trackers.values())
        self.torque_ratio = 0.0
        self.clipped = 0
        self.safe_steps = 0
        self.flight, self.flight_start, self.max_flight = False, 0.0, 0.0
        self.clearance = 0.0  # highest height of the lower foot while no foot touches [m]
        self.com_err_max, self.com_err_t = 0.0, None
        self.pelvis_min = np.inf
        self.x_start = self.model.com[0]
        self.tau_prev: np.ndarray | None = None
        self.tau_jump, self.tau_jump_t = 0.0, None
        # per-step logs, preallocated for ``capacity`` steps (grown if a run takes more)
        self.n_steps = 0
        self.step_times = np.empty(capacity)  # wall-clock time of each controller step [s]
        self.jump_t = np.empty(capacity)  # time of each per-step torque change [s] ...
        self.jump = np.empty(capacity)  # ... and the change [N m]
        self.n_jumps = 0
        self.landings: list[float] = []  # times a foot met the floor after a flight [s]
        self.ratio = 0.0
        self._tau_max = self.model.tau_max
        self._tau_scale = np.maximum(self._tau_max, 1e-9)
        self._tau_work = np.empty_like(self._tau_scale)
        self.trace: dict[str, list[Any]] | None = (
            {"t": [], "com": [], "vz": [], "feet": [], "fn": [], "tau": [], "errors": []}
            if trace else None)

    def _grow(self) -> None:
        """Double the capacity of the per-step logs."""
        size = max(2 * self.step_times.size, 1024)
        for name in ("step_times", "jump_t", "jump"):
            old = getattr(self, name)
            new = np.empty(size)
            new[:old.size] = old
            setattr(self, name, new)

    def before_step(self, step: Step) -> None:
        """Figures of the command (before MuJoCo's step)."""
        cmd, t = step.command, step.t
        if self.n_steps == self.step_times.size:
            self._grow()
        self.step_times[self.n_steps] = step.wall_time
        self.n_steps += 1
        if cmd.safe_mode:
            self.safe_steps += 1
        if self.model.tau_max is not self._tau_max:  # (a model whose limits were replaced)
            self._tau_max = self.model.tau_max
            self._tau_scale = np.maximum(self._tau_max, 1e-9)
        tau, work = cmd.tau, self._tau_work
        np.abs(tau, out=work)
        np.divide(work, self._tau_scale, out=work)
        self.ratio = float(work.max())
        self.torque_ratio = max(self.torque_ratio, self.ratio)
        if self.tau_prev is not None:
            np.subtract(tau, self.tau_prev, out=work)
            np.abs(work, out=work)
            jump = float(work.max())
            n = self.n_jumps
            self.jump_t[n], self.jump[n] = t, jump
            self.n_jumps = n + 1
            if jump > self.tau_jump:
                self.tau_jump, self.tau_jump_t = jump, t
        self.tau_prev = tau
        notes = cmd.report.notes
        if notes and any("clipped" in note for note in notes):
            self.clipped += 1

    def after_step(self, step: Step, reading: ContactReading) -> None:
        """Figures of the new state (MuJoCo's contacts: for logs and tests only)."""
        t_new = (step.k + 1) * self.sim.dt
        contact = reading.foot_contact.tolist()
        positions = reading.foot_position
        trackers = self._trackers
        for i, tr in enumerate(trackers):
            tr.update(contact[i], positions[i], t_new)
        airborne = not any(contact[:len(trackers)])
        if airborne and not self.flight:
            self.flight, self.flight_start = True, t_new
        elif not airborne and self.flight:
            self.flight = False
            self.max_flight = max(self.max_flight, t_new - self.flight_start)
            self.landings.append(t_new)
        if airborne:
            self.clearance = max(self.clearance, float(positions[:, 2].min()))
        if self.trace is not None:
            for key, value in (("t", t_new), ("com", self.model.com[2]),
                               ("vz", self.model.com_velocity[2]),
                               ("feet", reading.foot_position[:, 2].copy()),
                               ("fn", reading.normal_force.copy()), ("tau", self.ratio),
                               ("errors", self.behavior.task_errors())):
                self.trace[key].append(value)
        planner = self.behavior.planner
        if planner is not None and planner.planned:
            if planner.output("started", step.t) and not planner.output("done", step.t):
                com = planner.output("com", step.t)
                d = self.model.com[:2] - com[:2]
                err = float(np.sqrt(d.dot(d)))  # (np.linalg.norm's operations)
                if err > self.com_err_max:
                    self.com_err_max, self.com_err_t = err, step.t
        self.pelvis_min = min(self.pelvis_min, self.sim.base_height())
        if self.video is not None:
            self.video.capture(t_new)

    def steps(self) -> list[dict[str, float]]:
        """Footsteps of both feet, by landing time."""
        return sorted((s for tr in self.trackers.values() for s in tr.steps),
                      key=lambda s: s["t_land"])

    def metrics(self, t_end: float, backend: str | None) -> dict[str, Any]:
        """Return the figures of the run, rounded for its JSON."""
        if self.flight:
            self.max_flight = max(self.max_flight, t_end - self.flight_start)
        metrics: dict[str, Any] = {
            "max_torque_ratio": round(self.torque_ratio, 4),
            "max_torque_jump_nm": round(self.tau_jump, 3),
            "max_torque_jump_t": None if self.tau_jump_t is None else round(self.tau_jump_t, 3),
            **self._impact_metrics(),
            "controller_clipped_steps": self.clipped,
            "sim_clipped_torques": int(self.sim.clip_count),
            "safe_mode_steps": self.safe_steps,
            "flight_time_s": round(self.max_flight, 4),
            "flight_clearance_m": round(self.clearance, 4),
            "pelvis_min_m": round(float(self.pelvis_min), 4),
            "step_time_median_ms": (
                round(1e3 * float(np.median(self.step_times[:self.n_steps])), 3)
                if self.n_steps else 0),
            "backend": backend,
            "video": None,
        }
        if self.behavior.planner is not None:
            metrics.update(self._walk_metrics(t_end))
        return metrics

    def _impact_metrics(self) -> dict[str, Any]:
        """Return the torque changes of the impacts (landings after a flight), apart.

        A step belongs to an impact when its command comes at most :data:`IMPACT_WINDOW_S`
        after a landing: ``impacts`` lists each landing with its largest per-step torque
        change, ``max_torque_jump_outside_impacts_nm`` is the largest of the other steps.
        """
        impacts = []
        inside = np.zeros(self.n_jumps, dtype=bool)
        t = self.jump_t[:self.n_jumps]
        jump = self.jump[:self.n_jumps]
        for t_land in self.landings:
            window = (t >= t_land - 1e-9) & (t <= t_land + IMPACT_WINDOW_S + 1e-9)
            inside |= window
            k = int(np.argmax(np.where(window, jump, -1.0))) if window.any() else None
            impacts.append({
                "t": round(t_land, 4),
                "max_torque_jump_nm": None if k is None else round(float(jump[k]), 3),
                "max_torque_jump_t": None if k is None else round(float(t[k]), 4)})
        rest = jump[~inside]
        return {"impacts": impacts,
                "max_torque_jump_outside_impacts_nm": round(float(rest.max()), 3)
                if rest.size else 0.0}

    def _walk_metrics(self, t_end: float) -> dict[str, Any]:
        x_end = self.model.com[0]
        out: dict[str, Any] = {
            "distance_m": round(float(x_end - self.x_start), 4),
            "mean_speed_m_s": round(float(x_end - self.x_start) / t_end, 4),
        }
        steps = self.steps()
        if steps:
            walk_time = steps[-1]["t_land"] - steps[0]["t_lift"]
            x_steps = sum(s["advance_m"] for s in steps) / 2
            out["walking_time_s"] = round(walk_time, 4)
            out["step_speed_m_s"] = round(x_steps / walk_time, 4) if walk_time > 0 else 0.0
        out["com_tracking_error_max_m"] = round(self.com_err_max, 4)
        out["com_tracking_error_max_t"] = (None if self.com_err_t is None
                                           else round(self.com_err_t, 3))
        return out


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
) -> BehaviorRun:
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
            :func:`~hqp.behaviors.setup.prepare`).
        plot: Write a PNG of the run here (centre-of-gravity height and vertical velocity,
            feet heights, normal forces, largest torque ratio, the active tasks' error
            norms; phase changes as vertical lines); its path is reported as ``plot`` in the
            metrics.

    Raises:
        InvalidInput: A duration that is not a positive number, an output path that cannot
            be written (checked before anything is loaded).

    """
    if duration is not None and not (np.isfinite(duration) and duration > 0):
        raise InvalidInput(f"run_behavior: duration expects a positive number of seconds, "
                           f"got {duration}")
    check_output_paths(plot=plot, video=video)
    behavior, ctrl, robot_obj = prepare(source, robot=robot, controller=controller,
                                        inputs=inputs, overrides=overrides, backend=backend)
    spec = behavior.spec
    total = float(duration if duration is not None else spec.duration)
    sim = Simulator(robot_obj)
    ctrl.dt = sim.dt
    behavior.start(sim.state(), 0.0)
    recorder = (None if video is None
                else Video(sim, video, distance=3.5, azimuth=120.0, elevation=-15.0))
    meter = _Meter(behavior, sim, list(robot_obj.feet), plot is not None, recorder,
                   capacity=int(round(total / sim.dt)))
    fallbacks = last_resort_count()
    outcome = closed_loop(sim, behavior, total, before_step=meter.before_step,
                          after_step=meter.after_step, clock="steps", stop_on_fall=stop_on_fall,
                          progress=None if progress is None else lambda t: progress(t, total))
    metrics = meter.metrics(outcome.t_end, getattr(ctrl, "backend", None))
    metrics["realtime_factor"] = round(outcome.realtime_factor, 3)
    metrics["qp_fallbacks"] = last_resort_count() - fallbacks
    if recorder is not None:
        metrics["video"] = str(recorder.close())
    metrics.update(behavior.metrics())
    if meter.trace is not None and plot is not None:
        metrics["plot"] = str(_plot_run(meter.trace, metrics["phase_times"],
                                        list(meter.trackers), plot,
                                        f"{spec.name} on {robot_obj.name} ({controller})"))
    return BehaviorRun(
        behavior=spec.name, robot=robot_obj.name, controller=controller,
        duration_s=outcome.t_end, fell=outcome.fell, fall_reason=outcome.fall_reason,
        phases=list(behavior.visited), steps=meter.steps(),
        feasibility_events=[e.as_dict() for e in behavior.events], metrics=metrics,
    )


def _plot_run(trace: dict[str, list[Any]], phases: list[dict[str, Any]], feet: list[str],
              path: str | Path, title: str) -> Path:
    """Draw the run's trace (see :func:`run_behavior`'s ``plot``)."""
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
    tasks = sorted({name for step in trace["errors"] for name in step})
    if tasks:
        panels.append(Panel(
            "Task errors (norm, each task's units)", "error [m or rad]", t,
            tuple(Line(n, np.array([step.get(n, np.nan) for step in trace["errors"]]))
                  for n in tasks), events, log=True))
    names = ", ".join(f"{p['phase']} {p['t']:g} s" for p in phases)
    return plot_panels(panels, path, title=f"{title}\nphases: {names}")


# ------------------------------------------------------------------ the command
def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    """Add ``hqp run BEHAVIOR [--robot] [--controller] [--duration] [--json] ...``."""
    p = subparsers.add_parser(
        "run", help="run a behavior (library name or .toml file) in MuJoCo",
        description="Run a behavior in closed loop with MuJoCo and report what happened: "
                    "phases visited, fall, footsteps, feasibility events.")
    p.add_argument("behavior", help="library name (see `hqp behaviors`) or a .toml file")
    p.add_argument("--robot", default=None,
                   help="robot name or robot TOML file (default: the behavior's)")
    p.add_argument("--controller", default="hqp", choices=CONTROLLER_NAMES)
    p.add_argument("--backend", default=None,
                   help="QP backend of the HQP controller: proxsuite, daqp, quadprog, osqp "
                        "(default: the behavior's, else proxsuite)")
    p.add_argument("--duration", type=float, default=None,
                   help="simulated time [s], a positive number (default: the behavior's)")
    p.add_argument("--inputs", default=None,
                   help="runtime inputs, JSON Lines of {\"t\": ..., \"<input>\": ...}")
    p.add_argument("--set", action="append", default=[], metavar="INPUT=JSON",
                   help="replace an input's default, e.g. --set takeoff_height=1.2")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.add_argument("--video", default=None, help="write an MP4 of the run")
    p.add_argument("--plot", default=None,
                   help="write a PNG of the run (CoG height and velocity, feet heights, "
                        "normal forces, torque ratio; phase changes as vertical lines)")
    p.set_defaults(func=command)
    return p


def _overrides(items: list[str]) -> dict[str, Any]:
    """Parse ``--set INPUT=JSON`` items (their values are checked by the behavior's inputs).

    Raises:
        InvalidInput: An item that is not ``INPUT=JSON``.

    """
    overrides: dict[str, Any] = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key:
            raise InvalidInput(f"hqp run: --set expects INPUT=JSON, got {item!r}")
        try:
            overrides[key] = json.loads(value)
        except (json.JSONDecodeError, RecursionError) as exc:
            raise InvalidInput(f"hqp run: --set {key}: not JSON ({exc})") from None
    return overrides


def check_arguments(args: argparse.Namespace) -> dict[str, Any]:
    """Check ``hqp run``'s arguments before anything is loaded; return the ``--set`` values.

    Raises:
        InvalidInput: A duration that is not a positive finite number, a backend given to
            the null-space law, an unknown backend, an output path that cannot be written.
        UnknownName: A robot that is neither bundled nor a file.

    """
    if args.duration is not None and not (np.isfinite(args.duration) and args.duration > 0):
        raise InvalidInput(f"hqp run: --duration expects a positive number of seconds, "
                           f"got {args.duration}")
    if args.backend is not None:
        if args.controller != "hqp":
            raise InvalidInput(f"hqp run: --backend applies to the HQP controller, not to "
                               f"--controller {args.controller}")
        if args.backend not in known_backends():
            raise UnknownBackend(args.backend, known_backends())
    check_output_paths(plot=args.plot, video=args.video, prefix="--")
    if args.robot is not None:
        robots.check(args.robot)
    return _overrides(args.set)


def check_output_paths(prefix: str = "", **paths: str | Path | None) -> None:
    """Refuse output paths that cannot be written, before a run.

    Raises:
        InvalidInput: Names the option and says why.

    """
    for name, path in paths.items():
        why = None if path is None else output_path_problem(path)
        if why is not None:
            raise InvalidInput(f"{prefix}{name} {str(path)!r}: {why}")


def _summary(data: dict[str, Any]) -> str:
    """Return the readable summary of ``hqp run`` (without ``--json``)."""
    outcome = f"FELL ({data['fall_reason']})" if data["fell"] else "did not fall"
    moves = [f"footsteps: {data['steps']}"]
    if data["flight_time_s"] > 0:
        moves.append(f"longest flight: {data['flight_time_s']:.3f} s")
    lines = [
        f"behavior {data['behavior']} on {data['robot']} ({data['controller']}), "
        f"{data['duration_s']:.2f} s: {outcome}",
        f"  phases: {' -> '.join(data['phases'])}",
        f"  {', '.join(moves)}",
        f"  max |tau|/tau_max: {data['max_torque_ratio']:.2f}, largest torque change in one "
        f"step: {data['max_torque_jump_nm']:.1f} N m",
    ]
    for impact in data.get("impacts", []):
        lines.append(f"  landing at {impact['t']:.3f} s: largest torque change in one step "
                     f"within {1e3 * IMPACT_WINDOW_S:.0f} ms {impact['max_torque_jump_nm']} N m; "
                     f"outside the landings {data['max_torque_jump_outside_impacts_nm']:.1f} N m")
    if "mean_speed_m_s" in data:
        speed = round(data["mean_speed_m_s"], 3) or 0.0  # no "-0.000"
        lines.append(f"  mean speed {speed:.3f} m/s, CoM tracking error max "
                     f"{1e3 * data['com_tracking_error_max_m']:.1f} mm")
    lines.extend(_events_summary(data["feasibility_events"]))
    if data.get("qp_fallbacks"):
        lines.append(f"  {fallback_note(data['qp_fallbacks'])}")
    return "\n".join(lines)



def _events_summary(events: list[dict[str, Any]], most: int = 4) -> list[str]:
    """Return the lines of the feasibility events: per task and word, how often, first when."""
    if not events:
        return ["  feasibility events: none"]
    lines = [f"  feasibility events: {len(events)} (each in --json)"]
    groups: dict[tuple[str, str, Any], list[dict[str, Any]]] = {}
    for e in events:
        groups.setdefault((e["task"], e["status"], e.get("yields_to")), []).append(e)
    ranked = sorted(groups.items(), key=lambda kv: (-len(kv[1]), kv[0][:2]))
    for (task, word, yields_to), group in ranked[:most]:
        first = group[0]
        lines.append(f"    {task} (level {first['level']}): {_event_words(word, yields_to)}, "
                     f"{len(group)} x, first at {first['t']:.2f} s in {first['phase']}")
    if len(ranked) > most:
        lines.append(f"    ... and {len(ranked) - most} more")
    return lines


def _event_words(word: str, yields_to: int | None) -> str:
    """Return what an event word means, in a sentence (docs/concepts/report.md)."""
    if word == "conflict":
        return ("in conflict with a higher level" if yields_to is None
                else f"in conflict with level {yields_to}")
    return {"infeasible": "infeasible (its own rows cannot hold)",
            "satisfied": "satisfied again",
            "safety": "sent the behavior to its safety phase"}.get(word, word)


def command(args: argparse.Namespace) -> int:
    """Run ``hqp run``; print JSON (``--json``) or a short summary. Returns 0, or 1 on a fall.

    The arguments are checked first (:func:`check_arguments`); a progress bar on stderr
    follows the simulated time (:func:`hqp.app.console.progress_bar`).
    """
    overrides = check_arguments(args)
    # C libraries (PlaCo) print to stdout: keep stdout for the one JSON object
    with stdout_to_stderr() as out:
        with progress_bar(args.behavior, "s") as progress:
            result = run_behavior(args.behavior, robot=args.robot, controller=args.controller,
                                  duration=args.duration, inputs=args.inputs,
                                  overrides=overrides, video=args.video, progress=progress,
                                  backend=args.backend, plot=args.plot)
        data = result.as_json()
        if args.json:
            out.write(json.dumps(data) + "\n")
    if not args.json:
        print(_summary(data))
    return 1 if data["fell"] else 0
