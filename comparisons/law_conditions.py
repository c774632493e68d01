"""The papers' law under the papers' conditions: ``python -m comparisons.law_conditions``.

Seed 003's Figures 4-5 come from the null-space law on a simulated humanoid whose feet are
rigid contacts and whose joints have no torque limits. This runs ``hand-reach`` with the law
(``nullspace``) on welded feet (``--contacts welded``), once with ``paper-humanoid``'s torque
limits and once with them multiplied by ``--torque-scale`` (default 10: no limit is reached),
both hierarchies, and prints one JSON object per run: the contract's metrics and, to locate
where the run leaves the paper's behaviour,

- ``zone_entry_s``: the first time a joint enters its activation zone (``zone`` of a limit),
  with ``zone_joints`` the joints in their zones then and ``zone_entry_speed_rad_s`` their
  speeds (finite differences of the logged positions);
- ``before_zone``: the largest CoG errors (x, y) [mm] and the hand's distance to its target
  [cm] up to that time;
- ``saturated``: the joints whose commanded torque reached its limit (within 0.1 %), with the
  first time.
"""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any

import numpy as np

from comparisons.base import RunResult
from comparisons.hand_reach import HandReach, HandReachParameters
from hqp.threads import single_blas_thread


def zone_report(run: RunResult, zone: float) -> dict[str, Any]:
    """Zone entry, the errors before it and the torque saturations of one run."""
    tr = run.trace
    gap = np.minimum(tr.q - tr.q_lower, tr.q_upper - tr.q)  # (N, na)
    inside = gap < zone
    hit = np.flatnonzero(inside.any(axis=1))
    k = int(hit[0]) if hit.size else tr.t.size - 1
    err = 1e3 * np.abs(tr.cog_error[: k + 1])
    dist = 1e2 * np.linalg.norm(tr.hand[: k + 1] - tr.hand_goal[: k + 1], axis=1)
    tau, tau_max = tr.tau, tr.tau_max
    sat = np.abs(tau) >= 0.999 * tau_max
    saturated = {tr.joint_names[j]: float(tr.t[np.flatnonzero(sat[:, j])[0]])
                 for j in np.flatnonzero(sat.any(axis=0))}
    joints = np.flatnonzero(inside[k]) if hit.size else np.zeros(0, dtype=int)
    speed = np.abs(tr.q[k] - tr.q[max(k - 1, 0)]) / max(float(tr.t[k] - tr.t[max(k - 1, 0)]), 1e-9)
    return {
        "zone_entry_s": float(tr.t[k]) if hit.size else None,
        "zone_joints": [tr.joint_names[j] for j in joints],
        "zone_entry_speed_rad_s": [round(float(speed[j]), 3) for j in joints],
        "before_zone": {"cog_x_max_mm": float(err[:, 0].max()),
                        "cog_y_max_mm": float(err[:, 1].max()),
                        "hand_distance_cm": float(dist[-1])},
        "saturated": dict(sorted(saturated.items(), key=lambda kv: kv[1])),
    }


def main(argv: list[str] | None = None) -> int:
    """Run the law on welded feet with and without torque limits; print JSON lines."""
    parser = argparse.ArgumentParser(prog="python -m comparisons.law_conditions",
                                     description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--duration", type=float, default=HandReach.duration,
                        help="simulated duration [s]")
    parser.add_argument("--torque-scale", type=float, default=10.0,
                        help="factor on the torque limits of the second set of runs")
    args = parser.parse_args(argv)
    single_blas_thread()
    for scale in (1.0, args.torque_scale):
        params = HandReachParameters(torque_scale=scale)
        result = HandReach(params).run(controllers=["nullspace"], duration=args.duration,
                                       contacts="welded",
                                       progress=lambda m: print(m, file=sys.stderr))
        for run in result.runs:
            keep = ("cog_error_x_max_mm", "cog_error_y_max_mm", "hand_final_distance_cm",
                    "joint_limit_violation_max_rad", "fell", "contacts",
                    "cop_outside_sole_max_mm", "cop_outside_sole_s", "normal_force_min_n")
            row = {"hierarchy": run.spec.hierarchy, "torque_scale": scale,
                   **{k: run.metrics[k] for k in keep}, **zone_report(run, params.zone)}
            print(json.dumps(row), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
