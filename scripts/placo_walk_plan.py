"""Record PlaCo's walking plan for the ``walk`` behavior, to compare with hqp's own planner.

Runs in PlaCo's environment (``placo==0.10.2``, pinocchio 3.8), not in hqp's: it imports
neither hqp nor its core. Its input is a JSON object per robot written from hqp's
environment (the standing feet ``T_left``, ``T_right`` ``(4, 4)``, the centre of mass
``com`` ``(3,)``, ``urdf``, ``foot_length``, ``foot_width`` and the walk file's planner
``params``; ``scripts/walk_plan_compare.py state`` writes it); its output is PlaCo's
footsteps, supports and the centre-of-mass / ZMP trajectory sampled every ``--dt`` seconds,
configured the way hqp's walk configured PlaCo before it planned on its own
(``FootstepsPlannerNaive``, ``make_supports`` with start, middle and end double supports,
``WalkPatternGenerator``)::

    /path/to/placo-env/bin/python scripts/placo_walk_plan.py state.json placo_plan.json
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
import placo


def plan(state: dict, dt: float) -> dict:
    """PlaCo's plan for one robot's standing state (see the module docstring)."""
    p = state["params"]
    get = {
        "single_support_duration": 0.6, "double_support_ratio": 0.5,
        "startend_double_support_ratio": 2.0, "foot_height": 0.05, "foot_rise_ratio": 0.2,
        "zmp_margin": 0.02, "com_height_offset": 0.0, "planned_timesteps": 100,
        "single_support_timesteps": 10, "distance": 1.0, "step_length": 0.11,
    }
    get.update({k: v for k, v in p.items() if k in get})
    robot = placo.HumanoidRobot("", 0, Path(state["urdf"]).read_text())
    T_left = np.array(state["T_left"])
    T_right = np.array(state["T_right"])
    com = np.array(state["com"])
    hp = placo.HumanoidParameters()
    hp.single_support_duration = float(get["single_support_duration"])
    hp.single_support_timesteps = int(get["single_support_timesteps"])
    hp.double_support_ratio = float(get["double_support_ratio"])
    hp.startend_double_support_ratio = float(get["startend_double_support_ratio"])
    hp.planned_timesteps = int(get["planned_timesteps"])
    hp.walk_com_height = float(com[2] + get["com_height_offset"])
    hp.walk_foot_height = float(get["foot_height"])
    hp.walk_foot_rise_ratio = float(get["foot_rise_ratio"])
    hp.walk_trunk_pitch = 0.0
    hp.foot_length = float(state["foot_length"])
    hp.foot_width = float(state["foot_width"])
    hp.feet_spacing = float(np.linalg.norm(T_left[:2, 3] - T_right[:2, 3]))
    hp.zmp_margin = float(get["zmp_margin"])
    hp.walk_max_dx_forward = float(get["step_length"])
    planner = placo.FootstepsPlannerNaive(hp)
    target_left, target_right = T_left.copy(), T_right.copy()
    target_left[0, 3] += float(get["distance"])
    target_right[0, 3] += float(get["distance"])
    planner.configure(target_left, target_right)
    footsteps = planner.plan(placo.HumanoidRobot_Side.left, T_left, T_right)
    supports = placo.FootstepsPlanner.make_supports(footsteps, 0.0, True, True, True)
    traj = placo.WalkPatternGenerator(robot, hp).plan(supports, com, 0.0)
    omega = float(placo.LIPM.compute_omega(hp.walk_com_height))
    t = np.arange(0.0, float(traj.t_end), dt)
    left = placo.HumanoidRobot_Side.left
    return {
        "omega": omega,
        "t_end": float(traj.t_end),
        "footsteps": [{"side": "left" if f.side == left else "right",
                       "position": np.array(f.frame)[:3, 3].tolist()} for f in footsteps],
        "supports": [{"t_start": float(s.t_start), "both": bool(s.is_both()),
                      "feet": [np.array(f.frame)[:3, 3].tolist() for f in s.footsteps]}
                     for s in supports],
        "t": t.tolist(),
        "com": [np.array(traj.get_p_world_CoM(x)).tolist() for x in t],
        "com_velocity": [np.array(traj.get_v_world_CoM(x)).tolist() for x in t],
        "com_acceleration": [np.array(traj.get_a_world_CoM(x)).tolist() for x in t],
        "zmp": [np.array(traj.get_p_world_ZMP(x, omega)).tolist() for x in t],
        "double_support": [bool(traj.support_is_both(x)) for x in t],
        "left_foot": [np.array(traj.get_T_world_left(x))[:3, 3].tolist() for x in t],
        "right_foot": [np.array(traj.get_T_world_right(x))[:3, 3].tolist() for x in t],
    }


def main() -> None:
    """Command line: state file in, plan file out (one plan per robot of the state file)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("state", type=Path, help="JSON written by walk_plan_compare.py state")
    parser.add_argument("out", type=Path, help="JSON plan per robot")
    parser.add_argument("--dt", type=float, default=1e-3, help="sampling period [s]")
    args = parser.parse_args()
    states = json.loads(args.state.read_text())
    args.out.write_text(json.dumps({name: plan(s, args.dt) for name, s in states.items()}))


if __name__ == "__main__":
    main()
