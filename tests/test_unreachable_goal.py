"""A hand goal out of reach, held: the robot should come to rest, balanced, the hand stopped at
the nearest point it can reach (slow: MuJoCo).

The standing controller (``hqp.standing_controller``), a :class:`PositionTask` on the right
hand added at 0.05 s in the operational level with the goal 0.8 m ahead of the hand's standing
position. Claims, over the last 0.5 s of a 3.5 s run: every actuated joint slower than
0.05 rad/s, the hand no farther from its goal than where it started, the trunk within
0.35 rad of its standing orientation, every torque under 90 % of its limit, the per-step torque
change under 0.5 N m, and no task above the operational level in conflict. Measurements and
the mechanism: docs/design/control.md, "An unreachable goal".
"""

import numpy as np
import pinocchio as pin
import pytest

import hqp.robots as robots
from hqp.controller import standing_controller
from hqp.sim import Event, simulate
from hqp.tasks.base import Category
from hqp.tasks.position import PositionTask

DURATION = 3.5
"""Simulated time [s]; the claims hold over the last :data:`WINDOW`."""
WINDOW = 0.5
"""Window at the end of the run over which the robot must be at rest [s]."""
SPEED = 0.05
"""Largest actuated joint speed at rest [rad/s]."""
TRUNK = 0.35
"""Largest trunk tilt from its standing orientation [rad]."""
TORQUE_RATIO = 0.9
"""Largest torque as a fraction of its limit."""
JUMP = 0.5
"""Largest per-step torque change at rest [N m]."""
AHEAD = np.array([0.8, 0.0, 0.0])
"""Goal of the hand from its standing position [m] (out of reach of every bundled robot)."""


def _load(name):
    try:
        return robots.load(name)
    except (ImportError, FileNotFoundError) as exc:  # robot files not bundled here
        pytest.skip(f"robot {name!r} unavailable: {exc}")


def _run(name, **gains):
    robot = _load(name)
    c = standing_controller(robot, diagnostics="residuals", **gains)
    model = c.model
    model.update(robot.q_standing, np.zeros(model.nv))
    start = model.frame_placement(robot.hands[1]).translation.copy()
    R0 = model.frame_placement("trunk").rotation.copy()
    hand = PositionTask(model, robot.hands[1], name="hand", kp=30.0)
    goal = start + AHEAD
    hand.set_goal(goal)
    log = simulate(robot, c, DURATION, [
        Event(0.05, lambda s, k, t: k.add_task(hand, Category.OPERATIONAL, t=t), "hand")])
    return robot, c, log, start, goal, R0


def _claims(robot, c, log, start, goal, R0):
    """Measured figures of the last :data:`WINDOW` (a dict) and the failed claims (a list)."""
    model = c.model
    last = log.t >= log.t[-1] - WINDOW
    speed = float(np.abs(log.v[last][:, 6:]).max())
    model.update(log.q[-1], log.v[-1])
    hand = float(np.linalg.norm(model.frame_placement(robot.hands[1]).translation - goal))
    tilt = float(np.linalg.norm(pin.log3(R0.T @ model.frame_placement("trunk").rotation)))
    ratio = float((np.abs(log.tau[last]) / model.tau_max).max())
    jump = float(np.abs(np.diff(log.tau[last], axis=0)).max())
    op = c.stack.level_of(Category.OPERATIONAL)
    below = {t.name for k, t in c.stack.task_levels() if k >= op}
    above = sorted(n for n, s in log.status.items()
                   if n not in below and any(x == "conflict" for x in np.asarray(s)[last]))
    figures = {"speed": speed, "hand": hand, "start": float(np.linalg.norm(goal - start)),
               "tilt": tilt, "ratio": ratio, "jump": jump, "above": above,
               "fell": bool(log.fell), "safe": int(log.safe_mode.sum())}
    failed = [claim for claim, ok in (
        ("at rest", speed < SPEED), ("hand no farther", hand <= figures["start"]),
        ("trunk upright", tilt < TRUNK), ("torque margin", ratio < TORQUE_RATIO),
        ("torque steady", jump < JUMP), ("no conflict above", not above),
        ("standing", not log.fell), ("no safe mode", not log.safe_mode.any())) if not ok]
    return figures, failed


def _xfail(name, reason, strict=True):
    return pytest.param(name, marks=pytest.mark.xfail(strict=strict, reason=reason))


@pytest.mark.slow
@pytest.mark.parametrize("name", [
    # measured (docs/design/control.md, "An unreachable goal"): the hand level's residual, about
    # kp |e| = 12 m/s^2 held, is spent by its least squares along directions it barely
    # controls (the other arm, through the balance level): joints at their velocity bounds
    _xfail("paper-humanoid", "measured: the left shoulder yaw and roll swing at 2.0 rad/s at "
           "the end, the torque steps 2.9 N m; in another process (the whole suite on two "
           "workers) the same run met every bound: the outcome is marginal", strict=False),
    _xfail("g1", "measured: the left wrist and both shoulder yaws at 8-10 rad/s, torque steps "
           "of 4 N m (the rate band)"),
    _xfail("talos", "measured: the left arm at 1.3 rad/s, arm_right_2 at its torque limit"),
])
def test_the_default_standing_controller_with_an_unreachable_hand_goal(name):
    robot, c, log, start, goal, R0 = _run(name)
    figures, failed = _claims(robot, c, log, start, goal, R0)
    assert not failed, (failed, figures)


DAMPED = {"redundancy_damping": 3e-3, "redundancy_damping_gain": 10.0}
"""The operational level's joint damping measured in docs/design/control.md."""


@pytest.mark.slow
@pytest.mark.parametrize("name", [
    "paper-humanoid",
    _xfail("g1", "measured: the right shoulder yaw still creeps at 0.18 rad/s (from 10 rad/s) "
           "along a direction the hand level barely controls; the other claims hold"),
    _xfail("talos", "measured: the arms creep at 0.17 rad/s (from 1.3 rad/s) and arm_right_2 "
           "holds the outstretched arm at 0.96 of its torque limit (the acceleration-level "
           "hierarchy has no bound on the static torque of the pose it moves to)"),
])
def test_the_operational_level_damped_comes_to_rest_with_an_unreachable_hand_goal(name):
    robot, c, log, start, goal, R0 = _run(name, **DAMPED)
    figures, failed = _claims(robot, c, log, start, goal, R0)
    assert not failed, (failed, figures)
