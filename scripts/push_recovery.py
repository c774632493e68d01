"""Find the largest horizontal push a standing robot survives (HQP controller or null-space law).

A push is a constant horizontal force on the floating base for ``--push-duration`` seconds,
starting at ``--push-at``; the run continues until ``--duration`` and the robot survives when
it has not fallen (pelvis above 0.6 x its standing height, only the feet touching the floor).
The largest surviving force is found by bisection on the force magnitude, in each requested
direction; the result (and every run) is printed as JSON on stdout, progress on stderr.

Not run in CI (minutes of simulation). Example::

    OMP_NUM_THREADS=1 python scripts/push_recovery.py --robot paper-humanoid --directions 0 90
    OMP_NUM_THREADS=1 python scripts/push_recovery.py --controller nullspace
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time

from hqp.control.presets import CONTROLLER_NAMES


def survives(robot_name: str, force: float, angle_deg: float, args: argparse.Namespace) -> dict:
    """One run: push of ``force`` [N] at ``angle_deg`` (0: +x forward, 90: +y left)."""
    import numpy as np

    import hqp.robots as robots
    from hqp.control.presets import make_standing_controller
    from hqp.sim import Push, simulate

    robot = robots.load(robot_name)
    extra: dict = {}
    if args.controller == "nullspace":
        extra["internal_forces"] = args.internal_forces
        if args.law_zones:
            extra.update(support_zone=args.law_zones[0], torque_zone=args.law_zones[1])
    controller = make_standing_controller(args.controller, robot, backend=args.backend,
                                          diagnostics="residuals", **extra)
    a = math.radians(angle_deg)
    push = Push(args.push_at, (force * math.cos(a), force * math.sin(a), 0.0), args.push_duration)
    start = time.perf_counter()
    log = simulate(robot, controller, args.duration, [push])
    return {
        "force_n": force,
        "impulse_ns": force * args.push_duration,
        "angle_deg": angle_deg,
        "fell": log.fell,
        "fell_at": log.fell_at,
        "clip_count": log.clip_count,
        "safe_mode_steps": int(log.safe_mode.sum()),
        "max_foot_slip_m": float(log.foot_slip().max()),
        "min_support_margin_m": float(np.nanmin(log.support_margin)),
        "wall_s": time.perf_counter() - start,
    }


def main(argv: list[str] | None = None) -> int:
    """Bisection on the push force; JSON on stdout."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--robot", default="paper-humanoid")
    p.add_argument("--directions", type=float, nargs="+", default=[0.0],
                   help="push directions [deg] (0: forward +x, 90: left +y)")
    p.add_argument("--push-at", type=float, default=0.3, help="start of the push [s]")
    p.add_argument("--push-duration", type=float, default=0.1, help="length of the push [s]")
    p.add_argument("--duration", type=float, default=2.0, help="length of each run [s]")
    p.add_argument("--max-force", type=float, default=800.0, help="upper end of the search [N]")
    p.add_argument("--tolerance", type=float, default=10.0, help="bisection resolution [N]")
    p.add_argument("--backend", default="proxsuite", help="QP backend of the HQP controller")
    p.add_argument("--controller", default="hqp", choices=CONTROLLER_NAMES,
                   help="standing controller: HQP or the papers' null-space law")
    p.add_argument("--law-zones", type=float, nargs=2, metavar=("SUPPORT", "TORQUE"),
                   help="null-space law only: support and torque activation zones "
                        "(fractions, e.g. 0.8 0.95; default: the plain law)")
    p.add_argument("--internal-forces", default="min-norm",
                   choices=("none", "min-norm", "balanced"),
                   help="null-space law only: choice of the internal contact forces")
    args = p.parse_args(argv)

    results = []
    for angle in args.directions:
        lo, hi = 0.0, args.max_force
        runs = []
        top = survives(args.robot, hi, angle, args)
        runs.append(top)
        print(f"[{angle:g} deg] {hi:.0f} N: {'fell' if top['fell'] else 'survived'}",
              file=sys.stderr)
        if not top["fell"]:
            lo = hi
        while hi - lo > args.tolerance and top["fell"]:
            mid = 0.5 * (lo + hi)
            run = survives(args.robot, mid, angle, args)
            runs.append(run)
            print(f"[{angle:g} deg] {mid:.0f} N: {'fell' if run['fell'] else 'survived'} "
                  f"({run['wall_s']:.0f} s)", file=sys.stderr)
            if run["fell"]:
                hi = mid
            else:
                lo = mid
        results.append({"angle_deg": angle, "largest_survived_n": lo,
                        "largest_survived_impulse_ns": lo * args.push_duration,
                        "smallest_fallen_n": hi if lo < hi else None, "runs": runs})
    print(json.dumps({"robot": args.robot, "push_duration_s": args.push_duration,
                      "push_at_s": args.push_at, "run_duration_s": args.duration,
                      "controller": args.controller, "law_zones": args.law_zones,
                      "internal_forces": args.internal_forces,
                      "backend": args.backend,
                      "directions": results}, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
