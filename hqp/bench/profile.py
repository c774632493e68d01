"""Where the time of a control step goes (``python -m hqp.bench.profile --robot g1``).

Runs the standing controller (:func:`hqp.controller.standing_controller`) on the states of the
``controller`` suite and reports:

1. the step's phases from :attr:`hqp.controller.Command.timings` (model update, task rows,
   solve, torques, feasibility report) and each level's share of the solve
   (:attr:`hqp.solver.Solution.timings`), medians over the steps, in CPU time of the process
   with ``--clock cpu`` (the default: on a shared machine wall-clock time also counts the
   periods when the process waits for a core; the controller's and the solver's clock,
   ``time.perf_counter``, is swapped for ``time.process_time`` while they run, see
   :func:`cpu_clock`);
2. the task-rows phase split by task (each task's ``rows``, CPU time, medians) and the stack's
   own work (the rows phase minus its tasks: scaling, stacking, spans, levels);
3. a :mod:`cProfile` of the same steps (clock: CPU time), the functions with the largest own
   time, and the number of Python function calls per step (the interpreter's overhead per
   call is what separates a Python step from a C++ one such as PlaCo's).
"""

from __future__ import annotations

import argparse
import contextlib
import cProfile
import io
import pstats
import sys
import time
from collections.abc import Iterator
from typing import Any

import numpy as np

from hqp.bench.suite_controller import RATE_LEVEL, T0, states
from hqp.controller import standing_controller
from hqp.model import RobotState
from hqp.robots import load
from hqp.threads import single_blas_thread


@contextlib.contextmanager
def cpu_clock(enabled: bool = True) -> Iterator[None]:
    """Make ``time.perf_counter`` read the process's CPU time while the block runs.

    The controller and the solver time their phases with ``time.perf_counter`` (looked up at
    each call); inside this block those timings are CPU time of the process
    (``time.process_time``), restored on exit.
    """
    if not enabled:
        yield
        return
    saved = time.perf_counter
    time.perf_counter = time.process_time
    try:
        yield
    finally:
        time.perf_counter = saved


def _controller(robot_name: str, backend: str, algorithm: str, diagnostics: str) -> Any:
    # the controller suite's configuration (its RATE_LEVEL: states replayed out of sequence)
    return standing_controller(load(robot_name), backend=backend, algorithm=algorithm,
                               diagnostics=diagnostics, max_torque_rate=RATE_LEVEL)


def phase_table(robot_name: str, steps: int = 200, backend: str = "proxsuite",
                algorithm: str = "basis", diagnostics: str = "residuals",
                clock: str = "cpu") -> dict[str, Any]:
    """Median duration of each phase of the step and of each level of the solve [ms].

    Timings come from the controller's and the solver's own clock, CPU time of the process
    with ``clock="cpu"`` (:func:`cpu_clock`), wall-clock time with ``clock="wall"``; the
    medians over ``steps`` steps are robust to the occasional preemption.
    """
    ctrl = _controller(robot_name, backend, algorithm, diagnostics)
    sts = states(robot_name)
    phases: list[dict[str, float]] = []
    levels: list[list[float]] = []
    qps: list[int] = []
    with cpu_clock(clock == "cpu"):
        for i in range(steps + 20):
            q, v = sts[i % len(sts)]
            t = T0 + i * 1e-3
            cmd = ctrl.step(RobotState(q, v, t), t)
            if i < 20:
                continue
            phases.append(dict(cmd.timings))
            sol = ctrl.last_solution
            if sol is not None:
                levels.append([sol.timings[f"level_{k}"] for k in range(len(sol.levels))]
                              + [sol.timings["final"]])
                qps.append(sol.qp_count)
    built = ctrl.last_built
    names = [lv.name for lv in built.levels] + ["final"] if built is not None else []
    return {
        "robot": robot_name, "backend": backend, "algorithm": algorithm,
        "diagnostics": diagnostics, "clock": clock, "n": ctrl.layout.n, "steps": steps,
        "phases_ms": {k: round(1e3 * float(np.median([p[k] for p in phases])), 4)
                      for k in phases[0]},
        "levels_ms": {names[k]: round(1e3 * float(np.median([lv[k] for lv in levels])), 4)
                      for k in range(len(names)) if levels and len(levels[-1]) == len(names)},
        "qp_count_median": float(np.median(qps)) if qps else 0.0,
    }


def task_table(robot_name: str, steps: int = 200, backend: str = "proxsuite",
               algorithm: str = "basis", diagnostics: str = "residuals") -> dict[str, float]:
    """Median CPU time [ms] of each task's ``rows`` within the steps, and of the rest of the phase.

    Each task's ``rows`` is wrapped (for this run only) by a CPU timer; ``"stack (rest)"`` is
    the median of the rows phase minus the sum of its tasks (the stack's own work), ``"rows"``
    the median of the whole phase, both in CPU time (:func:`cpu_clock`). The timers add a few
    microseconds per task to the phase.
    """
    ctrl = _controller(robot_name, backend, algorithm, diagnostics)
    sts = states(robot_name)
    spent: dict[str, float] = {}
    clock = time.process_time

    def timed(task: Any) -> Any:
        inner = task.rows

        def rows(*args: Any, **kwargs: Any) -> Any:
            t0 = clock()
            try:
                return inner(*args, **kwargs)
            finally:
                spent[task.name] = spent.get(task.name, 0.0) + clock() - t0
        return rows

    tasks = list(ctrl.stack.tasks)
    for task in tasks:
        task.rows = timed(task)
    per_task: dict[str, list[float]] = {task.name: [] for task in tasks}
    rest: list[float] = []
    total: list[float] = []
    try:
        with cpu_clock():
            for i in range(steps + 20):
                q, v = sts[i % len(sts)]
                t = T0 + i * 1e-3
                spent.clear()
                cmd = ctrl.step(RobotState(q, v, t), t)
                if i < 20:
                    continue
                for name in per_task:
                    per_task[name].append(spent.get(name, 0.0))
                total.append(cmd.timings["rows"])
                rest.append(cmd.timings["rows"] - sum(spent.values()))
    finally:
        for task in tasks:
            del task.rows
    out = {name: round(1e3 * float(np.median(v)), 4) for name, v in per_task.items()}
    out["stack (rest)"] = round(1e3 * float(np.median(rest)), 4)
    out["rows"] = round(1e3 * float(np.median(total)), 4)
    return out


def profile(robot_name: str, steps: int = 200, backend: str = "proxsuite",
            algorithm: str = "basis", diagnostics: str = "residuals", top: int = 25
            ) -> tuple[str, float, float, dict[str, float]]:
    """Profile ``steps`` control steps (cProfile, CPU clock).

    Returns:
        ``(the top functions by own time as text, Python function calls per step, CPU ms per
        step under the profiler, the CPU breakdown of :func:`cpu_breakdown`)``.

    """
    ctrl = _controller(robot_name, backend, algorithm, diagnostics)
    sts = states(robot_name)
    for i in range(20):
        q, v = sts[i % len(sts)]
        ctrl.step(RobotState(q, v, T0 + i * 1e-3), T0 + i * 1e-3)
    pr = cProfile.Profile(time.process_time)
    pr.enable()
    for i in range(20, 20 + steps):
        q, v = sts[i % len(sts)]
        ctrl.step(RobotState(q, v, T0 + i * 1e-3), T0 + i * 1e-3)
    pr.disable()
    out = io.StringIO()
    st = pstats.Stats(pr, stream=out)
    st.sort_stats("tottime").print_stats(top)
    calls = st.total_calls / steps  # type: ignore[attr-defined]
    return out.getvalue(), calls, 1e3 * st.total_tt / steps, cpu_breakdown(st, steps)  # type: ignore[attr-defined]


BREAKDOWN = (
    ("step", "servo.py", "step"),
    ("model update", "model.py", "update"),
    ("rows (stack.build)", "stack.py", "build"),
    ("solve", "solver/hierarchy.py", "solve"),
    ("  QP backend calls", "solver/qp.py", "solve_qp"),
    ("  validation (check_level)", "level.py", "check_level"),
    ("  level reports", "solver/report.py", "level_report"),
    ("  sigma_min", "solver/report.py", "sigma_level"),
    ("torques", "dynamics.py", "joint_torques"),
    ("feasibility report", "diagnostics.py", "hqp_statuses"),
)
"""Rows of the CPU breakdown: (label, file name, function name) of a profiled function."""


def cpu_breakdown(stats: pstats.Stats, steps: int) -> dict[str, float]:
    """Cumulative CPU time per step [ms] of the functions of :data:`BREAKDOWN`.

    Functions of the same name in the same file are summed (e.g. every ``solve_qp`` call).
    """
    raw = stats.stats  # type: ignore[attr-defined]
    out: dict[str, float] = {}
    for label, file, func in BREAKDOWN:
        total = 0.0
        for (path, _line, name), (_cc, _nc, _tt, ct, _callers) in raw.items():
            if name == func and path.endswith(file):
                total += ct
        out[label] = round(1e3 * total / steps, 4)
    return out


def main(argv: list[str] | None = None) -> int:
    """Print the phase table and the profile of one robot's standing control step."""
    parser = argparse.ArgumentParser(prog="python -m hqp.bench.profile", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--robot", default="g1")
    parser.add_argument("--backend", default="proxsuite")
    parser.add_argument("--algorithm", default="basis")
    parser.add_argument("--diagnostics", default="residuals", choices=("residuals", "full"))
    parser.add_argument("--steps", type=int, default=200)
    parser.add_argument("--top", type=int, default=25)
    parser.add_argument("--clock", default="cpu", choices=("cpu", "wall"),
                        help="clock of the phase table (default: CPU time of the process)")
    parser.add_argument("--no-cprofile", action="store_true", help="skip the cProfile pass")
    args = parser.parse_args(argv)
    single_blas_thread()
    table = phase_table(args.robot, args.steps, args.backend, args.algorithm, args.diagnostics,
                        args.clock)
    print(f"robot {table['robot']}  n = {table['n']}  {args.algorithm}/{args.backend}  "
          f"diagnostics={args.diagnostics}  median QPs per step {table['qp_count_median']}")
    print(f"phases [ms, median, {args.clock} clock]:  "
          + "  ".join(f"{k} {v:.3f}" for k, v in table["phases_ms"].items()))
    print("solve by level [ms]:  " + "  ".join(f"{k} {v:.3f}"
                                               for k, v in table["levels_ms"].items()))
    tasks = task_table(args.robot, args.steps, args.backend, args.algorithm, args.diagnostics)
    print("rows by task [ms, median, cpu clock]:  "
          + "  ".join(f"{k} {v:.3f}" for k, v in tasks.items()))
    if args.no_cprofile:
        return 0
    text, calls, ms, parts = profile(args.robot, args.steps, args.backend, args.algorithm,
                                     args.diagnostics, args.top)
    print(f"\ncProfile (CPU clock): {calls:.0f} Python function calls per step, "
          f"{ms:.2f} ms CPU per step under the profiler")
    print("CPU per step [ms] (cumulative, under the profiler):")
    for label, value in parts.items():
        print(f"  {label:<28} {value:8.3f}")
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
