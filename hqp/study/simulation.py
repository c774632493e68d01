"""One simulation of a study, from its params to its record (:func:`run_simulation`).

The params (a flat dictionary of JSON scalars) name the target and everything that differs
between the simulations of a study:

- ``target``: ``"standing"`` (default: a standing controller of the registry,
  :func:`hqp.control.presets.make_standing_controller`, in :func:`hqp.sim.simulate`),
  ``"behavior:NAME"`` (``hqp run``'s runner, :func:`hqp.app.run.run_behavior`) or
  ``"scenario:NAME"`` (a paper scenario of ``hqp compare``, one hierarchy);
- ``controller``, ``robot``, ``duration`` [s], ``backend`` (``None`` or absent: the
  controller's default, so a faster default step reaches every study unchanged);
- standing only: ``push_force`` [N], ``push_angle_deg`` (0: +x forward, 90: +y left),
  ``push_at`` [s], ``push_duration`` [s]; ``noise_q_std``, ``noise_v_std`` (measurement
  noise, :class:`hqp.sim.Noise`); ``init_q_std`` [rad], ``init_v_std`` [rad/s] (Gaussian
  perturbation of the initial joint positions and velocities); ``seed`` (of both); any
  other key is a keyword of the standing stack (``com_kp``, ``posture_kp``, ``torque_scale``,
  ... and the null-space law's ``zone``, ``internal_forces``, ...);
- behaviors: ``set.INPUT`` replaces an input's default (``hqp run --set``);
- scenarios: ``hierarchy`` (default: the scenario's first).

Every simulation is deterministic given its params, so the record's ``command``
(``hqp sweep --one PARAMS``) re-runs it alone. Errors inside the simulation, and a run
longer than its wall-clock timeout, become a record (``status`` ``"error"`` or
``"timeout"``), never an exception.
"""

from __future__ import annotations

import faulthandler
import inspect
import json
import math
import os
import shlex
import socket
import time
import traceback
from collections.abc import Mapping
from typing import Any

import numpy as np

import comparisons
from comparisons.metrics import run_metrics
from hqp import robots
from hqp.app.run import run_behavior
from hqp.control.presets import (
    CONTROLLER_NAMES,
    make_standing_controller,
    standing_nullspace_controller,
    standing_stack,
)
from hqp.errors import HQPError, InvalidInput, UnknownName
from hqp.sim import Noise, Push, simulate
from hqp.study.spec import simulation_id
from hqp.threads import single_blas_thread

TARGETS = ("standing", "behavior:NAME", "scenario:NAME")
"""What a simulation runs."""

STANDING = {
    "robot": "paper-humanoid", "duration": 5.0, "backend": None,
    "push_force": 0.0, "push_angle_deg": 0.0, "push_at": 0.3, "push_duration": 0.1,
    "noise_q_std": 0.0, "noise_v_std": 0.0, "init_q_std": 0.0, "init_v_std": 0.0, "seed": 0,
}
"""Parameters of a standing simulation and their defaults (the others are gains).

The 5 s default leaves a pushed robot 4.7 s to fall: a 2 s run misses slow falls
(docs/results/push-recovery.md).
"""

COMMON = ("target", "controller", "robot", "duration", "backend")
"""Parameters every target takes."""

TIMING = ("step_time_median_ms", "step_time_p95_ms", "realtime_factor")
"""Measured figures that depend on the machine: kept apart from the metrics (``timing``)."""

STANDING_METRICS = ("fell", "fell_at_s", "diverged", "duration_s", "min_support_margin_m",
                    "max_foot_slip_m", "max_foot_lift_m", "feet_always_in_contact",
                    "clip_count", "safe_mode_steps", "max_torque_jump_nm")
"""Metrics of a standing simulation (:meth:`hqp.sim.Log.summary`; ``diverged``: MuJoCo reset
its state, counted as a fall)."""


HARD_TIMEOUT_GRACE = 30.0
"""Seconds past twice its timeout after which a simulation's process ends (:func:`hard_timeout`)."""


def hard_timeout(timeout: float) -> float:
    """Return when a simulation that never reaches its timeout's check is ended [s].

    The timeout is checked every 100 control steps; a step that never returns (a solver
    that does not stop) is ended with its process, its traceback on stderr
    (:func:`faulthandler.dump_traceback_later`): on Ray, the worker's log, and the record
    says the worker died.
    """
    return 2.0 * timeout + HARD_TIMEOUT_GRACE


class SimulationTimeout(HQPError):
    """A simulation ran longer than its wall-clock limit."""


def _gain_names() -> dict[str, frozenset[str]]:
    """Keywords of the standing controllers that a study may set, per controller."""
    stack = set(inspect.signature(standing_stack).parameters) - {"robot", "model"}
    law = set(inspect.signature(standing_nullspace_controller).parameters) - {
        "robot", "dt", "backend", "algorithm", "diagnostics", "gains"}
    return {"hqp": frozenset(stack), "nullspace": frozenset(stack | law)}


GAINS = _gain_names()
"""Keywords of the standing stack (and of the law) a standing simulation passes on."""


def target_kind(params: Mapping[str, Any]) -> tuple[str, str]:
    """Return ``(kind, name)`` of the params' target (``("standing", "")`` by default).

    Raises:
        UnknownName: Not one of :data:`TARGETS`.

    """
    target = str(params.get("target", "standing"))
    kind, _, name = target.partition(":")
    if target == "standing":
        return "standing", ""
    if kind in ("behavior", "scenario") and name:
        return kind, name
    raise UnknownName("target", target, TARGETS)


def check_params(params: Mapping[str, Any]) -> None:
    """Check a simulation's params before anything runs.

    Raises:
        InvalidInput: A parameter its target does not take, or a value out of range.
        UnknownName: Unknown target, controller, robot, behavior or scenario.

    """
    kind, name = target_kind(params)
    controller = params.get("controller", "hqp")
    duration = params.get("duration", STANDING["duration"])
    if isinstance(duration, bool) or not isinstance(duration, (int, float)) \
            or not math.isfinite(duration) or duration <= 0.0:
        raise InvalidInput(f"study: duration must be a positive number [s], got {duration!r}")
    if "robot" in params:
        robots.check(str(params["robot"]))
    if kind == "standing":
        if controller not in CONTROLLER_NAMES:
            raise UnknownName("controller", str(controller), CONTROLLER_NAMES)
        allowed = set(COMMON) | set(STANDING) | GAINS[controller]
        for key in ("push_force", "push_duration", "push_at", "noise_q_std", "noise_v_std",
                    "init_q_std", "init_v_std"):
            value = params.get(key, 0.0)
            if isinstance(value, bool) or not isinstance(value, (int, float)) \
                    or not math.isfinite(value) or value < 0.0:
                raise InvalidInput(f"study: {key} must be a non-negative number, got {value!r}")
    elif kind == "behavior":
        if controller not in CONTROLLER_NAMES:
            raise UnknownName("controller", str(controller), CONTROLLER_NAMES)
        allowed = set(COMMON) | {k for k in params if k.startswith("set.")}
    else:
        scenario = comparisons.get_scenario(name)
        if controller not in scenario.controllers:
            raise UnknownName("controller", str(controller), scenario.controllers)
        hierarchy = params.get("hierarchy", scenario.hierarchies[0])
        if hierarchy not in scenario.hierarchies:
            raise UnknownName("hierarchy", str(hierarchy), scenario.hierarchies)
        allowed = set(COMMON) | {"hierarchy"}
    unknown = sorted(set(params) - allowed)
    if unknown:
        raise InvalidInput(f"study: target {params.get('target', 'standing')!r} with controller "
                           f"{controller!r} takes no parameter {unknown} (it takes: "
                           f"{sorted(allowed)})")


def rerun_command(params: Mapping[str, Any]) -> str:
    """Return the shell command that re-runs one simulation alone."""
    text = json.dumps(dict(params), sort_keys=True, separators=(",", ":"))
    return f"hqp sweep --one {shlex.quote(text)} --json"


class _Deadline:
    """A progress callback that raises :class:`SimulationTimeout` past a wall-clock limit."""

    def __init__(self, timeout: float) -> None:
        self.timeout = timeout
        self.start = time.perf_counter()

    def __call__(self, *args: Any) -> None:
        if self.timeout > 0.0 and time.perf_counter() - self.start > self.timeout:
            raise SimulationTimeout(f"simulation stopped after its timeout of {self.timeout:g} s")


def _standing(params: Mapping[str, Any], deadline: _Deadline) -> dict[str, Any]:
    p = {**STANDING, **params}
    controller = p.get("controller", "hqp")
    robot = robots.load(p["robot"])
    options: dict[str, Any] = {k: v for k, v in params.items() if k in GAINS[controller]}
    if p["backend"] is not None:
        options["backend"] = p["backend"]
    ctrl = make_standing_controller(controller, robot, diagnostics="residuals", **options)
    events = []
    if p["push_force"] > 0.0:
        angle = math.radians(p["push_angle_deg"])
        events.append(Push(p["push_at"], (p["push_force"] * math.cos(angle),
                                          p["push_force"] * math.sin(angle), 0.0),
                           p["push_duration"]))
    noise = (Noise(p["noise_q_std"], p["noise_v_std"], int(p["seed"]))
             if p["noise_q_std"] > 0.0 or p["noise_v_std"] > 0.0 else None)
    q0, v0 = robot.q_standing.copy(), None
    rng = np.random.default_rng([int(p["seed"]), 1])  # independent of the noise's stream
    if p["init_q_std"] > 0.0:
        q0[7:] += rng.normal(scale=p["init_q_std"], size=q0.size - 7)
    if p["init_v_std"] > 0.0:
        v0 = np.zeros(robot.model().nv)
        v0[6:] = rng.normal(scale=p["init_v_std"], size=v0.size - 6)
    log = simulate(robot, ctrl, float(p["duration"]), events, noise=noise, q0=q0, v0=v0,
                   progress=deadline)
    summary = log.summary()
    summary["fell_at_s"] = None if log.fell_at is None else round(log.fell_at, 4)
    # MuJoCo resets its state (time back to 0) when the simulation diverges; the loop does
    # not notice: the controller lost the robot, which counts as a fall here.
    resets = np.flatnonzero(np.diff(log.t) <= 0.0)
    summary["diverged"] = bool(resets.size)
    if resets.size:
        summary["fell"] = True
        summary["fell_at_s"] = round(float(log.t[resets[0]]), 4)
    return summary


def _behavior(name: str, params: Mapping[str, Any], deadline: _Deadline) -> dict[str, Any]:
    overrides = {k.removeprefix("set."): v for k, v in params.items() if k.startswith("set.")}
    run = run_behavior(name, robot=params.get("robot"),
                       controller=params.get("controller", "hqp"),
                       duration=params.get("duration"), overrides=overrides,
                       backend=params.get("backend"), progress=deadline)
    data = run.as_json()
    data["feasibility_events"] = len(data["feasibility_events"])
    data["phases"] = " > ".join(data["phases"])
    return {k: v for k, v in data.items() if not isinstance(v, (list, dict))}


def _scenario(name: str, params: Mapping[str, Any], deadline: _Deadline) -> dict[str, Any]:
    scenario = comparisons.get_scenario(name)
    robot = scenario.check_robot(params.get("robot"))
    spec = comparisons.RunSpec(params.get("controller", "hqp"),
                               params.get("hierarchy", scenario.hierarchies[0]))
    duration = float(params.get("duration", scenario.duration))
    result = scenario.simulate(robot, spec, duration, deadline)
    metrics = {**run_metrics(result.trace), **result.metrics}
    return {k: v for k, v in metrics.items() if not isinstance(v, (list, dict))}


def measure(params: Mapping[str, Any], timeout: float = 0.0) -> dict[str, Any]:
    """Run one simulation and return all its figures (metrics and timing, unsplit).

    Raises:
        SimulationTimeout: It ran longer than ``timeout`` [s] (0: no limit).
        HQPError: Bad params, or what the simulation raises.

    """
    check_params(params)
    kind, name = target_kind(params)
    deadline = _Deadline(timeout)
    if kind == "standing":
        return _standing(params, deadline)
    if kind == "behavior":
        return _behavior(name, params, deadline)
    return _scenario(name, params, deadline)


def _clean(value: Any) -> Any:
    """Return a JSON-ready scalar (NaN and infinities: ``None``; numpy scalars: Python's)."""
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def run_simulation(params: Mapping[str, Any], timeout: float = 0.0,
                   metrics: tuple[str, ...] = ()) -> dict[str, Any]:
    """Run one simulation and return its record (never raises for the simulation's errors).

    Args:
        params: The simulation's params (see the module docstring).
        timeout: Wall-clock limit [s] (0: none).
        metrics: Metrics to keep (empty: all).

    Returns:
        ``{"id", "params", "status", "metrics", "timing", "error", "worker", "command"}``:
        ``status`` is ``"ok"``, ``"error"`` (an exception, in ``error``) or ``"timeout"``;
        ``timing`` holds the machine-dependent figures (step times, real-time factor,
        ``wall_s``); ``worker`` is ``host:pid``.

    """
    single_blas_thread()
    start = time.perf_counter()
    record: dict[str, Any] = {"id": simulation_id(params), "params": dict(params),
                              "status": "ok", "metrics": {}, "timing": {}, "error": None}
    if timeout > 0.0:  # the backstop of a step that never returns to the timeout's check
        faulthandler.dump_traceback_later(hard_timeout(timeout), exit=True)
    try:
        figures = measure(params, timeout)
    except SimulationTimeout as exc:
        record.update(status="timeout", error=str(exc))
    except Exception as exc:  # a simulation's failure is a result of the study
        frame = traceback.extract_tb(exc.__traceback__)[-1]
        record.update(status="error", error=f"{type(exc).__name__}: {exc} "
                                            f"({os.path.basename(frame.filename)}:{frame.lineno})")
    else:
        record["timing"] = {k: _clean(figures.pop(k)) for k in TIMING if k in figures}
        record["metrics"] = {k: _clean(v) for k, v in figures.items()
                             if not metrics or k in metrics}
    finally:
        faulthandler.cancel_dump_traceback_later()
    record["timing"]["wall_s"] = round(time.perf_counter() - start, 3)
    record["worker"] = f"{socket.gethostname()}:{os.getpid()}"
    record["command"] = rerun_command(params)
    return record
