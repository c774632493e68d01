"""Compare hqp's walk planner with PlaCo's plan, recorded in PlaCo's own environment.

PlaCo pins another pinocchio than hqp, so it does not run here: ``placo_walk_plan.py``
records its plan in PlaCo's environment from the standing state this script writes, and
this script compares the two plans and runs the ``walk`` behavior in MuJoCo on either::

    python scripts/walk_plan_compare.py state state.json            # hqp's environment
    /path/to/placo-env/bin/python scripts/placo_walk_plan.py state.json placo.json
    python scripts/walk_plan_compare.py plans placo.json            # footsteps, CoM, ZMP
    python scripts/walk_plan_compare.py run placo.json              # hqp run walk --json
    python scripts/walk_plan_compare.py run placo.json --replay     # ... on PlaCo's plan

``--replay`` swaps the behavior's planner for one that reads PlaCo's recorded footsteps,
supports and centre of mass (interpolated between its samples); the swing feet, unloading
and every task are the behavior's own. Not run in CI (each run simulates the whole walk).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

from hqp import robots
from hqp.behaviors import setup
from hqp.behaviors.loader import load_behavior
from hqp.behaviors.planners import Footstep, Support, WalkPlanner

ROBOTS = ("paper-humanoid", "g1", "talos")


def _standing(name: str) -> tuple[Any, Any]:
    robot = robots.load(name)
    model = robot.model()
    model.update(robot.q_standing, np.zeros(model.nv))
    return robot, model


def write_state(path: Path) -> None:
    """Write each robot's standing feet, centre of mass and sole size, with walk's parameters."""
    out = {}
    params = dict(load_behavior("walk").planner.params)
    for name in ROBOTS:
        robot, model = _standing(name)
        sole = robot.contact(robot.feet[0])
        out[name] = {"urdf": str(robot.urdf_path),
                     "T_left": model.frame_placement(robot.feet[0]).homogeneous.tolist(),
                     "T_right": model.frame_placement(robot.feet[1]).homogeneous.tolist(),
                     "com": model.com.tolist(), "foot_length": 2 * sole.half_length,
                     "foot_width": 2 * sole.half_width, "params": params}
    path.write_text(json.dumps(out, indent=1))


def hqp_plan(name: str) -> WalkPlanner:
    """Return hqp's plan of ``walk`` for a robot standing."""
    robot, model = _standing(name)
    sole = robot.contact(robot.feet[0])
    planner = WalkPlanner(load_behavior("walk").planner.params, feet=robot.feet,
                          foot_length=2 * sole.half_length, foot_width=2 * sole.half_width)
    planner.start(model, 0.0)
    return planner


def compare_plans(recorded: dict) -> dict:
    """Footsteps, durations, and the largest CoM and ZMP differences per robot."""
    out = {}
    for name, placo in recorded.items():
        ours = hqp_plan(name)
        t = np.array(placo["t"])
        com = np.array([ours.com_state(x)[0] for x in t])
        vel = np.array([ours.com_state(x)[1] for x in t])
        acc = np.array([ours.com_state(x)[2] for x in t])
        zmp = com[:, :2] - acc[:, :2] / ours.omega**2
        old_com = np.array(placo["com"])
        out[name] = {
            "footsteps": {"placo": [np.round(f["position"][:2], 4).tolist()
                                    for f in placo["footsteps"]],
                          "hqp": [np.round(f.position[:2], 4).tolist() for f in ours.footsteps]},
            "duration_s": {"placo": placo["t_end"], "hqp": ours.duration},
            "omega": {"placo": placo["omega"], "hqp": ours.omega},
            "com_difference_max_m": np.abs(com - old_com).max(axis=0).round(4).tolist(),
            "com_lateral_sway_m": {"placo": float(np.ptp(old_com[:, 1]).round(4)),
                                   "hqp": float(np.ptp(com[:, 1]).round(4))},
            "com_speed_max_m_s": {"placo": np.abs(placo["com_velocity"]).max(axis=0)[:2]
                                  .round(4).tolist(),
                                  "hqp": np.abs(vel).max(axis=0)[:2].round(4).tolist()},
            "com_acceleration_max_m_s2": {
                "placo": np.abs(placo["com_acceleration"]).max(axis=0)[:2].round(4).tolist(),
                "hqp": np.abs(acc).max(axis=0)[:2].round(4).tolist()},
            "zmp_difference_max_m": np.abs(zmp - np.array(placo["zmp"])).max(axis=0)
            .round(4).tolist(),
            "hqp_zmp_margin_min_m": round(ours.zmp_support_margin()[0], 4),
        }
    return out


class ReplayPlanner(WalkPlanner):
    """The walk planner's interface on PlaCo's recorded plan (``--replay``)."""

    recorded: dict = {}

    def start(self, model: Any, t: float) -> None:
        """Take PlaCo's footsteps, supports and centre of mass; swings as hqp plans them."""
        rec = self.recorded
        R = np.eye(3)
        self.footsteps = [Footstep(f["side"], np.array(f["position"]), R)
                          for f in rec["footsteps"]]
        ends = [s["t_start"] for s in rec["supports"][1:]] + [rec["t_end"]]
        self.supports = [Support(s["t_start"], end,
                                 tuple(Footstep("", np.array(p), R) for p in s["feet"]))
                         for s, end in zip(rec["supports"], ends)]
        self.omega = rec["omega"]
        self._t = np.array(rec["t"])
        self._com = [np.array(rec[k]) for k in ("com", "com_velocity", "com_acceleration")]
        self.t_start = float(t) + float(self.params["start_delay"])
        self.swings = self._plan_swings()
        self._last = None

    def com_state(self, tau: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """PlaCo's centre of mass, interpolated between its samples."""
        tau = min(max(float(tau), 0.0), float(self._t[-1]))
        return tuple(np.array([np.interp(tau, self._t, x[:, a]) for a in range(3)])
                     for x in self._com)


def run_walk(recorded: dict, robot: str, replay: bool) -> dict:
    """``hqp run walk --json`` on ``robot``, with PlaCo's plan if ``replay``."""
    from hqp.app.run import run_behavior

    if replay:
        ReplayPlanner.recorded = recorded[robot]
        setup.WalkPlanner = ReplayPlanner  # type: ignore[misc]
    return run_behavior("walk", robot=robot).as_json()


def main(argv: list[str] | None = None) -> int:
    """Command line (module docstring)."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = p.add_subparsers(dest="command", required=True)
    s = sub.add_parser("state", help="write the standing states for placo_walk_plan.py")
    s.add_argument("out", type=Path)
    c = sub.add_parser("plans", help="compare the two plans (JSON on stdout)")
    c.add_argument("placo", type=Path)
    r = sub.add_parser("run", help="run walk in MuJoCo (JSON on stdout)")
    r.add_argument("placo", type=Path)
    r.add_argument("--robot", default="paper-humanoid", choices=ROBOTS)
    r.add_argument("--replay", action="store_true", help="on PlaCo's recorded plan")
    args = p.parse_args(argv)
    if args.command == "state":
        write_state(args.out)
        return 0
    recorded = json.loads(args.placo.read_text())
    if args.command == "plans":
        json.dump(compare_plans(recorded), sys.stdout, indent=1)
    else:
        json.dump(run_walk(recorded, args.robot, args.replay), sys.stdout)
    print()
    return 0


if __name__ == "__main__":
    sys.exit(main())
