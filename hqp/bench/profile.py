"""Where the time of a control step goes (``python -m hqp.bench.profile --robot g1``).

Runs the standing controller (:func:`hqp.controller.standing_controller`) on the states of the
``controller`` suite and reports:

1. the step's phases from :attr:`hqp.controller.Command.timings` (model update, task rows,
   solve, torques, feasibility report) and each level's share of the solve
   (:attr:`hqp.solver.Solution.timings`), medians over the steps, in CPU time of the process
   when ``--cpu`` (the default: on a shared machine wall-clock time also counts the periods
   when the process waits for a core);
2. a :mod:`cProfile` of the same steps (clock: CPU time), the functions with the largest own
   time, and the number of Python function calls per step (the interpreter's overhead per
   call is what separates a Python step from a C++ one such as PlaCo's).
"""

from __future__ import annotations

import argparse
import cProfile
import io
import pstats
import sys
import time
from typing import Any

import numpy as np


def phase_table(robot_name: str, steps: int = 200, backend: str = "proxsuite",
                algorithm: str = "basis", diagnostics: str = "residuals") -> dict[str, Any]:
    """Median duration of each phase of the step and of each level of the solve [ms].

    Timings come from the controller's own clock (``time.perf_counter``); the medians over
    ``steps`` steps are robust to the occasional preemption.
    """
    from hqp.bench.suite_controller import T0, states
    from hqp.controller import standing_controller
    from hqp.model import RobotState
    from hqp.robots import load

    robot = load(robot_name)
    ctrl = standing_controller(robot, backend=backend, algorithm=algorithm,
                               diagnostics=diagnostics)
    sts = states(robot_name)
    phases: list[dict[str, float]] = []
    levels: list[list[float]] = []
    qps: list[int] = []
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
        "diagnostics": diagnostics, "n": ctrl.layout.n, "steps": steps,
        "phases_ms": {k: round(1e3 * float(np.median([p[k] for p in phases])), 4)
                      for k in phases[0]},
        "levels_ms": {names[k]: round(1e3 * float(np.median([lv[k] for lv in levels])), 4)
                      for k in range(len(names))},
        "qp_count_median": float(np.median(qps)) if qps else 0.0,
    }


def profile(robot_name: str, steps: int = 200, backend: str = "proxsuite",
            algorithm: str = "basis", diagnostics: str = "residuals", top: int = 25
            ) -> tuple[str, float, float, dict[str, float]]:
    """Profile ``steps`` control steps (cProfile, CPU clock).

    Returns:
        ``(the top functions by own time as text, Python function calls per step, CPU ms per
        step under the profiler, the CPU breakdown of :func:`cpu_breakdown`)``.

    """
    from hqp.bench.suite_controller import T0, states
    from hqp.controller import standing_controller
    from hqp.model import RobotState
    from hqp.robots import load

    robot = load(robot_name)
    ctrl = standing_controller(robot, backend=backend, algorithm=algorithm,
                               diagnostics=diagnostics)
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
    ("step", "controller.py", "step"),
    ("model update", "model.py", "update"),
    ("rows (stack.build)", "stack.py", "build"),
    ("solve", "hierarchy.py", "solve"),
    ("  QP backend calls", "hierarchy.py", "_qp"),
    ("  validation (check_level)", "level.py", "check_level"),
    ("  level reports", "hierarchy.py", "_report"),
    ("  sigma_min", "hierarchy.py", "_sigma_level"),
    ("torques", "controller.py", "torques"),
    ("feasibility report", "controller.py", "_statuses"),
)
"""Rows of the CPU breakdown: (label, file name, function name) of a profiled function."""


def cpu_breakdown(stats: pstats.Stats, steps: int) -> dict[str, float]:
    """Cumulative CPU time per step [ms] of the functions of :data:`BREAKDOWN`.

    Functions of the same name in the same file are summed (e.g. every ``_qp`` call).
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
    args = parser.parse_args(argv)
    from comparisons.threads import single_blas_thread

    single_blas_thread()
    table = phase_table(args.robot, args.steps, args.backend, args.algorithm, args.diagnostics)
    print(f"robot {table['robot']}  n = {table['n']}  {args.algorithm}/{args.backend}  "
          f"diagnostics={args.diagnostics}  median QPs per step {table['qp_count_median']}")
    print("phases [ms, median]:  " + "  ".join(f"{k} {v:.3f}"
                                               for k, v in table["phases_ms"].items()))
    print("solve by level [ms]:  " + "  ".join(f"{k} {v:.3f}"
                                               for k, v in table["levels_ms"].items()))
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
