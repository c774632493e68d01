"""Process CPU time of each closed-loop step of a behavior run, and what is not the controller.

For each behavior run as ``hqp run`` runs it (:func:`hqp.app.run.run_behavior`, its own robot
unless ``BEHAVIOR@ROBOT``), the process CPU time (not wall time: the machine may be shared)
of the whole loop (:func:`hqp.sim.closed_loop`), of the controller's steps
(``controller.step``) and of MuJoCo's (``mujoco.mj_step``), per step; ``other_cpu_ms`` is the
rest: the behavior's state machine and goals, the state conversion, the contact reading, the
run's hooks. With ``--calls``, the Python function calls (``sys.setprofile``) and C calls per
step outside ``controller.step`` (slower: the CPU figures of that run are not comparable).
Prints one JSON object per run, with the run's ``realtime_factor``:

    OMP_NUM_THREADS=1 python scripts/loop_cost.py walk@g1 walk reach stand
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from typing import Any

import mujoco

import hqp.app.run as run_module
from hqp.app.run import run_behavior


def measure(behavior: str, robot: str | None, calls: bool) -> dict[str, Any]:
    """Run ``behavior`` and return its per-step CPU figures (see the module docstring)."""
    loop, mj_step = run_module.closed_loop, mujoco.mj_step
    cpu = {"loop": 0.0, "controller": 0.0, "mujoco": 0.0}
    counts = {"call": 0, "c_call": 0}
    box: dict[str, int] = {}

    def count(frame: Any, event: str, arg: Any) -> None:
        if event in counts:
            counts[event] += 1

    def timed_mj_step(m: Any, d: Any) -> None:
        start = time.process_time()
        mj_step(m, d)
        cpu["mujoco"] += time.process_time() - start

    def timed_loop(sim: Any, driven: Any, duration: float, **kwargs: Any) -> Any:
        controller = driven.controller
        step = controller.step

        def timed_step(state: Any, t: float) -> Any:
            if calls:
                sys.setprofile(None)
            start = time.process_time()
            try:
                return step(state, t)
            finally:
                cpu["controller"] += time.process_time() - start
                if calls:
                    sys.setprofile(count)

        controller.step = timed_step
        start = time.process_time()
        if calls:
            sys.setprofile(count)
        try:
            outcome = loop(sim, driven, duration, **kwargs)
        finally:
            sys.setprofile(None)
            cpu["loop"] += time.process_time() - start
            del controller.step
        box["steps"] = outcome.steps
        return outcome

    run_module.closed_loop, mujoco.mj_step = timed_loop, timed_mj_step
    try:
        run = run_behavior(behavior, robot=robot)
    finally:
        run_module.closed_loop, mujoco.mj_step = loop, mj_step
    data, n = run.as_json(), box["steps"]
    out: dict[str, Any] = {
        "behavior": behavior, "robot": run.robot, "steps": n,
        "realtime_factor": data["realtime_factor"],
        "step_time_median_ms": data["step_time_median_ms"],
        "loop_cpu_ms": round(1e3 * cpu["loop"] / n, 4),
        "controller_cpu_ms": round(1e3 * cpu["controller"] / n, 4),
        "mujoco_cpu_ms": round(1e3 * cpu["mujoco"] / n, 4),
        "other_cpu_ms": round(1e3 * (cpu["loop"] - cpu["controller"] - cpu["mujoco"]) / n, 4),
    }
    if calls:
        out["python_calls_per_step"] = round(counts["call"] / n, 1)
        out["c_calls_per_step"] = round(counts["c_call"] / n, 1)
    return out


def main() -> None:
    """Measure the runs named on the command line."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", nargs="+", help="BEHAVIOR or BEHAVIOR@ROBOT")
    parser.add_argument("--calls", action="store_true", help="count the calls per step")
    args = parser.parse_args()
    for item in args.runs:
        behavior, _, robot = item.partition("@")
        print(json.dumps(measure(behavior, robot or None, args.calls)), flush=True)


if __name__ == "__main__":
    main()
