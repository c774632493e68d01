"""Closed loops whose hierarchy is in conflict: a centre-of-mass move faster than the support
allows and an unreachable hand goal, on every bundled robot (slow: MuJoCo).

What a strict hierarchy owes its user there: no safe-mode step, no joint past its limit, a
command an actuator can follow (per-step torque change under the stated 5 N m at 1 ms).
The controllers are the defaults: the servo's torque-rate level (4 N m per step) is on in
every preset (docs/design/control.md).
"""

import numpy as np
import pytest

import hqp.robots as robots
from hqp.controller import standing_controller
from hqp.sim import Event, simulate
from hqp.tasks.base import Category
from hqp.tasks.position import PositionTask

JUMP_NM = 5.0
"""Stated bound on the per-step torque change [N m per 1 ms step]."""

LIMIT_RAD = 1e-3
"""Stated bound on a joint's excursion past its controller limit [rad]."""

def _load(name):
    try:
        return robots.load(name)
    except (ImportError, FileNotFoundError) as exc:  # robot files not bundled here
        pytest.skip(f"robot {name!r} unavailable: {exc}")


def _excursion(log, model):
    """Largest excursion past a position limit of the controller's model over the run [rad]."""
    q = log.q[:, model.actuated_q]
    return float(max(np.max(q - model.q_upper), np.max(model.q_lower - q), 0.0))


JUMP_SEEN_NM = 6.5
"""Above the largest per-step change measured where ``jump_xfail`` applies (5.98 N m): a step
beyond it is a regression, not the known case."""


def _check(log, model, conflicting, jump_xfail=None):
    """The run's claims; ``jump_xfail``: a known reason the per-step torque bound may fail
    (an xfail of that claim alone, after every other one has passed, and only up to
    :data:`JUMP_SEEN_NM`)."""
    jumps = np.abs(np.diff(log.tau, axis=0)).max(axis=1)
    assert not log.fell, log.fell_at
    assert not log.safe_mode.any(), int(log.safe_mode.sum())
    assert log.clip_count == 0
    assert "conflict" in log.status[conflicting], "the case must be a conflict"
    assert _excursion(log, model) < LIMIT_RAD
    worst = (float(jumps.max()), float(log.t[1:][jumps.argmax()]))
    if jump_xfail is not None and JUMP_NM <= worst[0] < JUMP_SEEN_NM:
        pytest.xfail(f"{worst}: {jump_xfail}")
    assert worst[0] < JUMP_NM, worst


G1_COM_JUMP = (
    "rounding-dependent (measured on an AMD EPYC): at 0.549 s of the unperturbed run the "
    "torque-rate level is in conflict with the contact limits (once): the step is 5.18 N m "
    "(4 N m of rate band and its least-squares violation; 5.98 N m in one of 10 runs with 1e-6 rad "
    "of initial joint noise, the others 4.0-4.01), over the stated 5 N m. Its spread of the "
    "violation also throws the right wrist roll to 20 rad/s, which the joint limits' recovery "
    "deceleration stops at its limit (6e-6 rad, tests/test_tasks_joint_limits.py). Open: "
    "issue 17, tests/test_rate_conflict.py")


@pytest.mark.slow
@pytest.mark.parametrize("name", robots.NAMES)  # talos: a few seconds of CPU
def test_a_centre_of_mass_move_faster_than_the_support_allows(name):
    """The CoM goal 5 cm forward in 0.4 s (a min-jerk peak of 1.8 m/s^2, more than the soles'
    centre of pressure allows): the balance level in conflict."""
    robot = _load(name)
    c = standing_controller(robot, diagnostics="residuals")
    com = c.task("com")

    def move(sim, ctrl, t):
        goal = com.goal_at(t).position + np.array([0.05, 0.0, 0.0])
        com.move_to(ctrl.model, goal, 0.4, t)

    log = simulate(robot, c, 0.8, [Event(0.05, move, "CoM 5 cm forward in 0.4 s")])
    _check(log, c.model, "com", jump_xfail=G1_COM_JUMP if name == "g1" else None)


@pytest.mark.slow
@pytest.mark.parametrize("name", robots.NAMES)
def test_an_unreachable_hand_goal(name):
    """The right hand sent 1.5 m ahead of the pelvis (out of reach) and held there."""
    robot = _load(name)
    c = standing_controller(robot, diagnostics="residuals")
    model = c.model
    hand = PositionTask(model, robot.hands[1], name="hand", kp=30.0)
    model.update(robot.q_standing, np.zeros(model.nv))
    hand.set_goal(model.frame_placement(robot.hands[1]).translation + np.array([1.5, 0.0, 0.0]))
    log = simulate(robot, c, 1.0, [
        Event(0.05, lambda s, k, t: k.add_task(hand, Category.OPERATIONAL, t=t), "hand")])
    _check(log, model, "hand")
