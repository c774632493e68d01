"""The ``controller`` suite: whole control steps of every controller on the standing task set.

Per robot (``paper-humanoid``, ``g1``, ``talos``), the same states are handed to:

- ``hqp/<algorithm>/<backend>`` (but ``hqp/basis/native``, below):
  :func:`hqp.control.presets.standing_controller` (both soles in
  contact, centre of mass, trunk upright, posture, torque, friction, centre-of-pressure and
  viable joint limits; ``diagnostics="residuals"``: per-task residual flags, no per-task SVDs)
  without the servo's torque-rate level (:data:`RATE_LEVEL`);
- ``hqp/basis/native``: the README's controller, :func:`hqp.control.presets.standing_controller`
  with every default (the native step: model pass, rows, strict hierarchy, torques and the
  full feasibility report in one call into the C++ core; the servo's torque-rate level; the
  solver's work budget);
- ``nullspace``: :func:`hqp.control.presets.standing_nullspace_controller` (same stack, joint limits
  as the papers' activation zones; inequalities not enforced);
- ``placo``: PlaCo's ``DynamicsSolver`` on the same task set (:mod:`hqp.bench.placo_step`);
- ``tsid``: TSID's ``InverseDynamicsFormulationAccForce`` on the same task set
  (:mod:`hqp.bench.tsid_step`).

PlaCo and TSID run in worker processes of their own environments (``python -m
hqp.bench.peer_env placo`` / ``tsid`` makes them; :mod:`hqp.bench.worker`). Their calls are
interleaved with the others' in the same rounds; their times are those the worker measures
around its own step (the pipe's round trip is reported apart, ``round_trip_median_ms``); the
row carries the peer's version (``placo_version``, ``tsid_version``), ``pinocchio_version``
and ``solve_failures``. Without its environment a peer's row says so (``skipped``, with the
command that makes it) and has no times.

A unit of work is one full control step: model update, task rows, solve (and for hqp and the
law, torques and the feasibility report). States: :data:`SEQUENCE_STEPS` consecutive states of
a closed loop of the robot in MuJoCo (the README's controller holding it through a forward push,
:func:`states`), stepped through in order by every configuration, each with its own warm starts
(one jump back to the first state per pass); steps are made at ``t >= 1 s`` (task ramps done).
Timing: :func:`hqp.bench.interleave.interleaved`, all configurations of a robot in the same
rounds, one BLAS thread (PlaCo is single-threaded). Beside the median and p95 of the wall
time, ``cpu_p99_ms`` and ``cpu_max_ms`` give the tail of the CPU time per step.

Extra fields: ``phases_ms`` (median model update, rows, solve, torques, report of the step),
``levels_ms`` (median time of each level in the solve), ``over_placo`` (median over PlaCo's
median, same robot, same run), ``level_cost_excess`` and ``cost_excess`` (level costs over the
tightest hqp configuration, on the levels of the hqp controller at the same states; the contract
excess of :func:`hqp.bench.accuracy.relative_excess`, largest over the states).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from hqp.bench.accuracy import ExcessTracker, level_costs
from hqp.bench.interleave import Samples, interleaved
from hqp.bench.placo_step import PlacoStanding
from hqp.bench.tsid_step import TsidStanding
from hqp.bench.worker import PeerUnavailable
from hqp.control.presets import standing_controller, standing_nullspace_controller
from hqp.model import RobotState
from hqp.robots import load as load_robot
from hqp.solver import ALGORITHMS, available_backends, supports

ROBOTS = ("paper-humanoid", "g1", "talos")
"""Robots of the suite."""

NATIVE_STEP = "hqp/basis/native"
"""The native core's whole step (the contract's row name): the controller on the native step."""

RATE_LEVEL: float | None = None
"""The servo's torque-rate level of the ``hqp/<algorithm>/<backend>`` rows: none (their
Python step is timed as a solver of the same levels). ``hqp/basis/native`` is the README's
controller with every default, the torque-rate level included."""

SEQUENCE_STEPS = 200
"""Consecutive closed-loop states of a robot the suite steps through, in order."""

PUSH_PER_KG = 1.5
"""The sequence's forward push on the base, per kilogram of the robot [N/kg], over 0.1 s."""

T0 = 1.0
"""Control time of the first measured step [s] (after the stack's task ramps)."""

TSID = "tsid"
"""TSID's row (the contract's name)."""

PLACO = "placo"
"""PlaCo's row (the contract's name)."""

SLOW_SECONDS = 0.25
"""A configuration taking more CPU time than this per step (median of a probe pass over the
states) is not interleaved: its row reports the probe (``"probe_only": true``)."""


def states(robot_name: str, count: int = SEQUENCE_STEPS) -> list[tuple[np.ndarray, np.ndarray]]:
    """Consecutive closed-loop states ``(q, v)`` of a robot, in order (module docstring).

    The README's standing controller (every default) holds the robot in MuJoCo at 1 kHz; a
    forward push of :data:`PUSH_PER_KG` times its mass acts on the base from 0.3 s to 0.4 s;
    the states of the ``count`` steps from 0.25 s on are recorded (calm, pushed, recovering).
    """
    from hqp.sim import Simulator

    robot = load_robot(robot_name)
    ctrl = standing_controller(robot)
    sim = Simulator(robot)
    push = np.array([PUSH_PER_KG * ctrl.model.mass, 0.0, 0.0])
    out: list[tuple[np.ndarray, np.ndarray]] = []
    start = 250
    for k in range(start + count):
        state = sim.state()
        if k >= start:
            out.append((np.array(state.q), np.array(state.v)))
        command = ctrl.step(state, k * sim.dt)
        sim.step(command.tau, push if 300 <= k < 400 else None)
    return out


def configurations(backends: Sequence[str] | None = None,
                   algorithms: Sequence[str] = ALGORITHMS) -> list[str]:
    """Return the configuration names: ``hqp/<algorithm>/<backend>``, ``nullspace``, ``placo``."""
    bk = list(backends) if backends is not None else available_backends()
    return [f"hqp/{a}/{b}" for a in algorithms for b in bk if supports(b, a)] + [
        "nullspace", "placo", TSID]


class _Stepper:
    """One controller stepping through the suite's states (cycling), timings kept."""

    def __init__(self, name: str, robot: Any, sts: list[tuple[np.ndarray, np.ndarray]],
                 dt: float = 1e-3) -> None:
        self.name = name
        self.states = sts
        self.dt = dt
        self.i = 0
        self.phases: list[dict[str, float]] = []
        self.levels: list[list[float]] = []
        self.record = False
        self.peer: TsidStanding | PlacoStanding | None = None
        """A peer's client (its worker times its own steps)."""
        if name in (TSID, PLACO):
            self.peer = TsidStanding(robot, dt) if name == TSID else PlacoStanding(robot, dt)
            self.ctrl = None
        elif name == NATIVE_STEP:  # the README's controller, every default
            self.ctrl = standing_controller(robot, dt=dt)
            if self.ctrl.native is None:
                raise RuntimeError("the standing controller has no native step")
        elif name == "nullspace":
            self.ctrl = standing_nullspace_controller(robot, dt=dt, diagnostics="residuals")
        else:
            _, algorithm, backend = name.split("/")
            self.ctrl = standing_controller(robot, dt=dt, backend=backend, algorithm=algorithm,
                                            diagnostics="residuals", max_torque_rate=RATE_LEVEL)

    def __call__(self) -> object:
        q, v = self.states[self.i % len(self.states)]
        t = T0 + self.i * self.dt
        self.i += 1
        if self.peer is not None:
            return self.peer.step(q, v)
        assert self.ctrl is not None
        cmd = self.ctrl.step(RobotState(q, v, t), t)
        if self.record:
            self.phases.append(dict(cmd.timings))
            sol = getattr(self.ctrl, "last_solution", None)
            if sol is not None and self.name != "nullspace":
                self.levels.append([sol.timings[k] for k in sorted(sol.timings)
                                    if k.startswith("level_")])
        return cmd


def _accuracy(steppers: dict[str, _Stepper], sts: list[tuple[np.ndarray, np.ndarray]]
              ) -> tuple[dict[str, np.ndarray], dict[str, float]]:
    """Excess per level and contract excess (largest over the states) on the hqp levels."""
    hqp_names = [n for n in steppers if n.startswith("hqp/") and n != NATIVE_STEP]
    if not hqp_names:
        return {}, {}
    ref_name = hqp_names[0]
    tracker = ExcessTracker()
    t = T0 + 10.0
    for q, v in sts:
        xs = {}
        for name, st in steppers.items():
            if st.ctrl is None:
                continue
            st.ctrl.step(RobotState(q, v, t), t)
            x = st.ctrl.last_x
            if x is not None:
                xs[name] = x
        t += 1e-3
        levels = steppers[ref_name].ctrl.last_built.levels  # type: ignore[union-attr]
        n = steppers[ref_name].ctrl.layout.n  # type: ignore[union-attr]
        costs = {k: level_costs(levels, x) for k, x in xs.items() if x.size == n}
        contract = {k: c for k, c in costs.items() if k.startswith("hqp/")}
        if not contract:
            continue
        tracker.add(costs, contract)
    return tracker.level, tracker.contract


def _probe(steppers: dict[str, _Stepper], count: int,
           failed: dict[str, str]) -> dict[str, Samples]:
    """One pass over the states per configuration (also the warm-up of persistent QPs).

    A configuration that raises is moved from ``steppers`` to ``failed``.
    """
    probe: dict[str, Samples] = {}
    for name, st in list(steppers.items()):
        d = []
        c = []
        try:
            for _ in range(count):
                c0 = time.process_time()
                t0 = time.perf_counter()
                st()
                d.append(time.perf_counter() - t0)
                c.append(time.process_time() - c0)
        except Exception as exc:  # noqa: BLE001 - a failing controller is a result
            failed[name] = f"{type(exc).__name__}: {exc}"
            del steppers[name]
            continue
        probe[name] = Samples(np.asarray(d), False, np.asarray(c))
    return probe


def _shape(steppers: dict[str, _Stepper]) -> tuple[int | None, int | None, int | None]:
    """``(n, levels, rows)`` of the first hqp configuration's last built stack."""
    ref_st = next((st for n, st in steppers.items() if n.startswith("hqp/")), None)
    if ref_st is None:
        return None, None, None
    ctrl = ref_st.ctrl
    levels = ctrl.last_built.levels  # type: ignore[union-attr]
    n_rows = sum(0 if lv.A is None else np.shape(lv.A)[0] for lv in levels)
    n_rows += sum(0 if lv.C is None else np.shape(lv.C)[0] for lv in levels)
    return ctrl.layout.n, len(levels), n_rows  # type: ignore[union-attr]


def _measured(row: dict[str, Any], st: _Stepper, t: Samples, probe_only: bool) -> None:
    """Add the timings and the step's phases and levels to a row."""
    cpu = 1e3 * t.cpu if t.cpu.size else 1e3 * t.samples
    row.update(median_ms=round(t.median_ms, 4), p95_ms=round(t.p95_ms, 4),
               cpu_p99_ms=round(float(np.percentile(cpu, 99)), 4),
               cpu_max_ms=round(float(cpu.max()), 4),
               settled=t.settled, samples=int(t.samples.size),
               cpu_median_ms=round(t.cpu_median_ms, 4) if t.cpu.size else None)
    if probe_only:
        row["probe_only"] = True
    if st.phases:
        keys = [k for k in st.phases[0] if k != "total"]
        row["phases_ms"] = {k: round(1e3 * float(np.median([p[k] for p in st.phases])), 4)
                            for k in keys}
    if st.levels:
        L = min(len(lv) for lv in st.levels)
        row["levels_ms"] = [round(1e3 * float(np.median([lv[k] for lv in st.levels])), 4)
                            for k in range(L)]


def _ratios(rows: list[dict[str, Any]]) -> None:
    """Add each row's time over PlaCo's and over the null-space law's (wall and CPU)."""
    for key, suffix in (("median_ms", ""), ("cpu_median_ms", "_cpu")):
        placo = next((r[key] for r in rows if r["solver"] == "placo" and r.get(key)), None)
        law = next((r[key] for r in rows if r["solver"] == "nullspace" and r.get(key)), None)
        for r in rows:
            if r.get(key):
                if placo:
                    r["over_placo" + suffix] = round(r[key] / placo, 3)
                if law:
                    r["over_nullspace" + suffix] = round(r[key] / law, 3)


def run_robot(robot_name: str, names: Sequence[str], *, quick: bool = False,
              progress: Callable[[str], None] | None = None) -> list[dict[str, Any]]:
    """Rows of one robot (a bundled name or a robot TOML file; rows carry its name)."""
    robot = load_robot(robot_name)
    sts = states(robot_name, count=20 if quick else SEQUENCE_STEPS)
    steppers: dict[str, _Stepper] = {}
    failed: dict[str, str] = {}
    skipped: dict[str, str] = {}
    for name in names:
        try:
            steppers[name] = _Stepper(name, robot, sts)
        except PeerUnavailable as exc:
            skipped[name] = str(exc)
            if progress is not None:
                progress(f"controller: {robot_name}: {name} skipped: {exc}")
        except Exception as exc:  # noqa: BLE001 - an unavailable configuration is reported
            failed[name] = f"{type(exc).__name__}: {exc}"
    try:
        return _measure(robot.name, names, steppers, sts, failed, skipped, quick, progress)
    finally:
        for st in steppers.values():
            if st.peer is not None:
                st.peer.close()


def _worker_samples(st: _Stepper, timed: Samples) -> Samples:
    """Return the worker's own times of the last timed calls of a peer's configuration."""
    assert st.peer is not None
    n = timed.samples.size
    return Samples(np.asarray(st.peer.wall[-n:]), timed.settled, np.asarray(st.peer.cpu[-n:]))


def _measure(robot_name: str, names: Sequence[str], steppers: dict[str, _Stepper],
             sts: list[tuple[np.ndarray, np.ndarray]], failed: dict[str, str],
             skipped: dict[str, str], quick: bool,
             progress: Callable[[str], None] | None) -> list[dict[str, Any]]:
    """Probe, interleave and time the configurations of one robot; return its rows."""
    probe = _probe(steppers, len(sts), failed)
    slow = {n for n in steppers if np.median(probe[n].cpu) > SLOW_SECONDS}
    for st in steppers.values():
        st.record = True
    fns = {n: st for n, st in steppers.items() if n not in slow}
    settings = dict(warmup=2, batch=2, min_samples=4, max_seconds=3.0) if quick else dict(
        warmup=len(sts), batch=len(sts), min_samples=len(sts), max_seconds=45.0)
    timings = interleaved(fns, **settings) if fns else {}  # type: ignore[arg-type]
    round_trip: dict[str, Samples] = {}
    for name, st in steppers.items():
        if st.peer is not None and name in timings:
            round_trip[name] = timings[name]
            timings[name] = _worker_samples(st, timings[name])
    ex, contract_excess = _accuracy(steppers, sts[::20])
    n_var, n_levels, n_rows = _shape(steppers)
    rows: list[dict[str, Any]] = []
    for name in names:
        parts = name.split("/")
        row: dict[str, Any] = {
            "suite": "controller", "robot": robot_name, "solver": name,
            "algorithm": parts[1] if len(parts) == 3 else None,
            "backend": parts[2] if len(parts) == 3 else None,
            "levels": n_levels, "n": n_var, "rows": n_rows, "states": len(sts), "threads": 1,
        }
        if name in failed:
            row.update(median_ms=None, p95_ms=None, failed=failed[name])
            rows.append(row)
            continue
        if name in skipped:
            row.update(median_ms=None, p95_ms=None, skipped=skipped[name])
            rows.append(row)
            continue
        _measured(row, steppers[name], timings[name] if name in timings else probe[name],
                  name in slow)
        peer = steppers[name].peer
        if peer is not None:
            row[f"{name}_version"] = (peer.tsid_version if isinstance(peer, TsidStanding)
                                      else peer.placo_version)
            row.update(pinocchio_version=peer.pinocchio_version, solve_failures=peer.failures)
            if name in round_trip:
                row["round_trip_median_ms"] = round(round_trip[name].median_ms, 4)
        if name in ex:
            row["level_cost_excess"] = [float(f"{v:.3g}") for v in ex[name]]
            row["cost_excess"] = float(f"{contract_excess[name]:.3g}")
        rows.append(row)
    _ratios(rows)
    return rows


def run(*, quick: bool = False, robots: Sequence[str] | None = None,
        backends: Sequence[str] | None = None, algorithms: Sequence[str] = ALGORITHMS,
        progress: Callable[[str], None] | None = None) -> list[dict[str, Any]]:
    """Run the ``controller`` suite.

    Args:
        quick: ``g1`` only, ``hqp/basis/proxsuite``, ``nullspace``, ``placo`` and ``tsid``,
            a few samples
            (for tests; times are not meaningful).
        robots: Robots (default :data:`ROBOTS`).
        backends: Backends (default: every installed one).
        algorithms: Algorithms of the hqp configurations (default: basis and cascade).
        progress: Status lines (stderr).

    """
    if quick:
        names = ["hqp/basis/proxsuite", "nullspace", "placo", TSID]
        robot_list = list(robots) if robots else ["g1"]
    else:
        names = configurations(backends, algorithms)
        robot_list = list(robots) if robots else list(ROBOTS)
    rows: list[dict[str, Any]] = []
    for r in robot_list:
        if progress is not None:
            progress(f"controller: {r}")
        rows.extend(run_robot(r, names, quick=quick, progress=progress))
    return rows
