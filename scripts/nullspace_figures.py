"""Figures of the null-space cross-check (not run in CI).

``push``: the largest horizontal push on the base that a standing controller survives in
MuJoCo (bisection over the force magnitude; a push lasts ``--duration`` seconds from t = 1 s,
the run goes on for ``--settle`` seconds after it; survived = not fallen).

``timing``: the step time of the law beside the HQP controller's on the same standing stacks
and the same states (the stack of :func:`hqp.controller.standing_controller`; the law's copy
has the papers' joint-limit activation zones instead of the viable bounds).

Examples::

    python scripts/nullspace_figures.py push --controller nullspace --direction 1 0
    python scripts/nullspace_figures.py timing --robots paper-humanoid g1 --steps 200

Both print one JSON object on stdout.
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import sys
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402


def survives(kind: str, robot_name: str, force: float, direction: np.ndarray, duration: float,
             settle: float, backend: str = "quadprog") -> bool:
    """Whether the standing controller ``kind`` survives a push of ``force`` [N]."""
    from hqp.nullspace import make_standing_controller
    from hqp.robots import load
    from hqp.sim.run import Push, simulate

    robot = load(robot_name)
    extra = {"backend": backend} if kind == "hqp" else {}
    ctrl = make_standing_controller(kind, robot, diagnostics="residuals", **extra)
    f = force * np.array([direction[0], direction[1], 0.0])
    log = simulate(robot, ctrl, 1.0 + duration + settle, [Push(1.0, tuple(f), duration)])
    return not log.fell


def largest_push(kind: str, robot_name: str, direction: np.ndarray, duration: float,
                 settle: float, high: float, resolution: float,
                 backend: str = "quadprog") -> dict[str, object]:
    """Bisection over the push force: the largest force survived within ``resolution`` [N]."""
    lo, hi = 0.0, high
    trials = []
    while survives(kind, robot_name, hi, direction, duration, settle, backend):
        trials.append((hi, True))
        lo, hi = hi, 2.0 * hi
    trials.append((hi, False))
    while hi - lo > resolution:
        mid = 0.5 * (lo + hi)
        ok = survives(kind, robot_name, mid, direction, duration, settle, backend)
        trials.append((mid, ok))
        lo, hi = (mid, hi) if ok else (lo, mid)
        print(f"{kind}: {mid:.1f} N {'survived' if ok else 'fell'}", file=sys.stderr)
    name = kind if kind != "hqp" else f"hqp/basis/{backend}"
    return {"controller": name, "robot": robot_name, "direction": direction.tolist(),
            "push_duration_s": duration, "largest_survived_N": lo, "first_fall_N": hi,
            "impulse_Ns": lo * duration, "trials": trials}


def timing(robots: list[str], steps: int, backend: str) -> dict[str, object]:
    """Median and 95th percentile step times of both controllers on the same states."""
    from hqp.model import RobotState
    from hqp.nullspace import make_standing_controller
    from hqp.robots import load

    rows = []
    for name in robots:
        robot = load(name)
        ctrls = {
            f"hqp/basis/{backend}": make_standing_controller(
                "hqp", robot, backend=backend, diagnostics="residuals"),
            "nullspace": make_standing_controller("nullspace", robot, diagnostics="residuals"),
        }
        rng = np.random.default_rng(0)
        nv = next(iter(ctrls.values())).model.nv
        states = []
        for _ in range(steps):
            q = robot.q_standing.copy()
            q[7:] += rng.normal(scale=0.02, size=q.size - 7)
            states.append((q, rng.normal(scale=0.05, size=nv)))
        times: dict[str, list[float]] = {k: [] for k in ctrls}
        solve: dict[str, list[float]] = {k: [] for k in ctrls}
        for i, (q, v) in enumerate(states):  # interleaved: both see the same machine load
            for key, ctrl in ctrls.items():
                t0 = time.perf_counter()
                cmd = ctrl.step(RobotState(q, v), 1.0 + 1e-3 * i)
                times[key].append(time.perf_counter() - t0)
                solve[key].append(cmd.timings.get("solve", float("nan")))
        for key, ctrl in ctrls.items():
            t = np.array(times[key]) * 1e3
            rows.append({"robot": name, "solver": key, "levels": ctrl.stack.n_levels,
                         "n": ctrl.layout.n, "median_ms": round(float(np.median(t)), 3),
                         "p95_ms": round(float(np.percentile(t, 95)), 3),
                         "solve_median_ms": round(float(np.median(solve[key]) * 1e3), 3)})
    return {"suite": "nullspace-vs-hqp", "rows": rows}


def main() -> None:
    """Command line."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("push", help="largest push survived standing")
    p.add_argument("--controller", default="nullspace", choices=["nullspace", "hqp"])
    p.add_argument("--robot", default="paper-humanoid")
    p.add_argument("--direction", type=float, nargs=2, default=[1.0, 0.0])
    p.add_argument("--duration", type=float, default=0.1, help="push length [s]")
    p.add_argument("--settle", type=float, default=2.0, help="time after the push [s]")
    p.add_argument("--start", type=float, default=100.0, help="first force tried [N]")
    p.add_argument("--resolution", type=float, default=10.0, help="bisection stop [N]")
    p.add_argument("--backend", default="quadprog", help="QP backend of the HQP controller")
    t = sub.add_parser("timing", help="step time of the law beside HQP's")
    t.add_argument("--robots", nargs="+", default=["paper-humanoid", "g1", "talos"])
    t.add_argument("--steps", type=int, default=200)
    t.add_argument("--backend", default="proxsuite")
    args = parser.parse_args()
    logging.basicConfig(level=logging.ERROR)
    if args.command == "push":
        d = np.array(args.direction, dtype=float)
        d /= np.linalg.norm(d)
        out = largest_push(args.controller, args.robot, d, args.duration, args.settle,
                           args.start, args.resolution, args.backend)
    else:
        out = timing(args.robots, args.steps, args.backend)
    print(json.dumps(out))


if __name__ == "__main__":
    main()
