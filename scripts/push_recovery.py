"""Find the largest horizontal push a standing robot survives (HQP controller or null-space law).

Kept for its flags; it is now the ``push-map`` study of :mod:`hqp.study` (the same as
``hqp sweep push-map``): the directions run in parallel on Ray (a local instance, or
``--address``), every simulation is a record of ``--out`` (JSON Lines, resumable with
``--resume``), and the summary JSON goes to stdout.

A push is a constant horizontal force on the floating base for ``--push-duration`` seconds,
starting at ``--push-at``; the run continues until ``--duration`` and the robot survives when
it has not fallen (pelvis above 0.6 x its standing height, only the feet touching the floor).
The largest surviving force is found by bisection on the force magnitude, in each requested
direction (:mod:`hqp.study.pushmap`).

Not run in CI (minutes of simulation). Example::

    OMP_NUM_THREADS=1 python scripts/push_recovery.py --robot paper-humanoid --directions 0 90
    OMP_NUM_THREADS=1 python scripts/push_recovery.py --controller nullspace
"""

from __future__ import annotations

import argparse
import json
import sys

from hqp.control.presets import CONTROLLER_NAMES
from hqp.study import RecordFile, connect, make_plan, run_study, study_from_dict


def main(argv: list[str] | None = None) -> int:
    """Bisection on the push force in every direction, on Ray; JSON on stdout."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--robot", default="paper-humanoid")
    p.add_argument("--directions", type=float, nargs="+", default=[0.0],
                   help="push directions [deg] (0: forward +x, 90: left +y)")
    p.add_argument("--push-at", type=float, default=0.3, help="start of the push [s]")
    p.add_argument("--push-duration", type=float, default=0.1, help="length of the push [s]")
    p.add_argument("--duration", type=float, default=5.0,
                   help="length of each run [s] (long enough for a slow fall: 2 s was not)")
    p.add_argument("--max-force", type=float, default=800.0, help="upper end of the search [N]")
    p.add_argument("--tolerance", type=float, default=10.0, help="bisection resolution [N]")
    p.add_argument("--backend", default=None,
                   help="QP backend of the HQP controller (default: the controller's)")
    p.add_argument("--controller", default="hqp", choices=CONTROLLER_NAMES,
                   help="standing controller: HQP or the papers' null-space law")
    p.add_argument("--law-zones", type=float, nargs=2, metavar=("SUPPORT", "TORQUE"),
                   help="null-space law only: support and torque activation zones "
                        "(fractions, e.g. 0.8 0.95; default: the plain law)")
    p.add_argument("--internal-forces", default="min-norm",
                   choices=("none", "min-norm", "balanced"),
                   help="null-space law only: choice of the internal contact forces")
    p.add_argument("--repeats", type=int, default=1,
                   help="simulations per probed force (seeds 0..K-1 of --init-q-std): a force "
                        "is survived when all K survived; survival near the threshold flips "
                        "with rounding, so one run per force samples it "
                        "(docs/results/push-recovery.md)")
    p.add_argument("--init-q-std", type=float, default=None,
                   help="initial joint-angle perturbation [rad] of each repeat (default with "
                        "--repeats > 1: 1e-4)")
    p.add_argument("--timeout", type=float, default=0.0,
                   help="wall-clock limit of one simulation [s] (0: none)")
    p.add_argument("--workers", type=int, default=None, help="CPUs of the local Ray instance")
    p.add_argument("--address", default=None, help="a running Ray cluster")
    p.add_argument("--out", default="push_recovery.jsonl", help="records (JSON Lines)")
    p.add_argument("--resume", action="store_true", help="reuse the records of --out")
    args = p.parse_args(argv)

    fixed: dict = {} if args.backend is None else {"backend": args.backend}
    if args.controller == "nullspace":
        fixed["internal_forces"] = args.internal_forces
        if args.law_zones:
            fixed.update(support_zone=args.law_zones[0], torque_zone=args.law_zones[1])
    init_q_std = args.init_q_std if args.init_q_std is not None else (
        1e-4 if args.repeats > 1 else None)
    if init_q_std is not None:
        fixed["init_q_std"] = init_q_std
    study = study_from_dict({
        "study": "push-map", "name": "push_recovery", "controllers": [args.controller],
        "robot": args.robot, "duration": args.duration, "timeout": args.timeout,
        "fixed": fixed, "push": {"directions": args.directions, "max_force": args.max_force,
                                 "tolerance": args.tolerance, "at": args.push_at,
                                 "duration": args.push_duration, "repeats": args.repeats}})
    make_plan(study)
    records = RecordFile(args.out, resume=args.resume, overwrite=not args.resume)
    ray = connect(args.address, args.workers)
    try:
        summary = run_study(study, records, ray, progress=lambda done, expected: print(
            f"{done}/{expected} simulations", file=sys.stderr))
    finally:
        if args.address is None:
            ray.shutdown()
    print(json.dumps(summary, indent=1))
    return 1 if summary["failed"] else 0


if __name__ == "__main__":
    raise SystemExit(main())
