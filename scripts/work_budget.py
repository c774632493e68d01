"""Step times of the README's standing controller under a push, for several work budgets.

For each budget (``WholeBodyController(work_budget=...)``; 0: unbounded) the robot stands in
MuJoCo at 1 kHz for 1.5 s with a forward push on its base from 0.3 s to 0.4 s; the script
prints the CPU time per control step (median, p99, p99.9, max), the steps whose QP the budget
cut, whether and when the robot fell, the largest torque change per step and where the centre
of mass ended::

    OMP_NUM_THREADS=1 python scripts/work_budget.py --robot g1 --force 120 --budgets 0 500 1000
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import hqp


def run(robot_name: str, force: float, budget: int, steps: int = 1500) -> dict[str, object]:
    """One pushed standing run with a work budget; its step times and outcome."""
    robot = hqp.robots.load(robot_name)
    controller = hqp.standing_controller(robot, work_budget=budget)
    sim = hqp.Simulator(robot)
    cpu, cut, fell, jump, last = [], 0, None, 0.0, None
    push = np.array([force, 0.0, 0.0])
    for k in range(steps):
        state = sim.state()
        t0 = time.thread_time()
        command = controller.step(state, k * sim.dt)
        cpu.append(1e3 * (time.thread_time() - t0))
        cut += any("work budget" in note for note in command.report.notes)
        if last is not None:
            jump = max(jump, float(np.abs(command.tau - last).max()))
        last = command.tau
        sim.step(command.tau, push if 300 <= k < 400 else None)
        if sim.fallen():
            fell = round(k * sim.dt, 3)
            break
    t = np.asarray(cpu)
    return {"robot": robot_name, "force_n": force, "budget": budget,
            "median_ms": round(float(np.median(t)), 3),
            "p99_ms": round(float(np.percentile(t, 99)), 3),
            "p999_ms": round(float(np.percentile(t, 99.9)), 3),
            "max_ms": round(float(t.max()), 3), "cut_steps": cut, "fell_at_s": fell,
            "max_torque_jump_nm": round(jump, 3),
            "final_com_m": [round(float(c), 4) for c in sim.com()]}


def main() -> int:
    """Print one line per budget."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robot", default="g1")
    parser.add_argument("--force", type=float, default=120.0, help="push [N]")
    parser.add_argument("--budgets", type=int, nargs="+", default=[0, 500, 1000, 2000])
    args = parser.parse_args()
    for budget in args.budgets:
        print(run(args.robot, args.force, budget), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
