"""The ``walk`` behavior: its plan, the swing trajectories, and the closed-loop walk.

The closed-loop test (slow) runs ``walk`` on paper-humanoid under the HQP controller in
MuJoCo and counts footsteps as the runner defines them (:mod:`hqp.app.run`): a
swing foot out of contact for at least 0.1 s that lands at least 0.10 m ahead of where
it lifted. ``hqp run walk --json`` prints the same figures. The planner itself (footsteps,
supports, the ZMP of the planned centre of mass) is tested in
``tests/test_behaviors_walk_planner.py``.
"""

from __future__ import annotations

import numpy as np
import pytest

from hqp.behaviors.planners import SwingTrajectory, WalkPlanner
from hqp.errors import BehaviorFileError

WALK_DURATION = 13.0
"""Simulated time of the closed-loop test [s]: the behavior's (its plan ends at 12.3 s)."""


def test_swing_trajectory_derivatives_and_boundaries() -> None:
    sw = SwingTrajectory("left", 1.0, 1.6, np.array([0.1, 0.08, 0.0]),
                         np.array([0.32, 0.09, 0.01]), 0.05)
    h = 1e-5
    for t in np.linspace(1.0 + 1e-3, 1.6 - 1e-3, 17):
        p, v, a = sw.sample(t)
        p_plus, v_plus, _ = sw.sample(t + h)
        p_minus, v_minus, _ = sw.sample(t - h)
        np.testing.assert_allclose((p_plus - p_minus) / (2 * h), v, atol=1e-7)  # [m/s]
        np.testing.assert_allclose((v_plus - v_minus) / (2 * h), a, atol=1e-5)  # [m/s^2]
    for t in (1.0, 1.6):  # lift-off and touchdown: at rest
        _, v, a = sw.sample(t)
        np.testing.assert_allclose(v, 0.0, atol=1e-12)
        np.testing.assert_allclose(a, 0.0, atol=1e-12)
    np.testing.assert_allclose(sw.sample(1.0)[0], sw.start, atol=1e-12)
    np.testing.assert_allclose(sw.sample(1.6)[0], sw.end, atol=1e-12)
    # peak of the bump at mid-swing: the height above the mid-point of the footsteps
    np.testing.assert_allclose(sw.sample(1.3)[0], 0.5 * (sw.start + sw.end) + [0, 0, 0.05],
                               atol=1e-12)
    assert sw.progress(0.0) == 0.0 and sw.progress(2.0) == 1.0
    with pytest.raises(BehaviorFileError, match="lands"):
        SwingTrajectory("right", 1.0, 1.0, sw.start, sw.end, 0.05)


@pytest.fixture(scope="module")
def walk_plan():
    from hqp import robots
    from hqp.behaviors.loader import load_behavior

    robot = robots.load("paper-humanoid")
    model = robot.model()
    model.update(robot.q_standing, np.zeros(model.nv))
    spec = load_behavior("walk")
    surface = robot.contact(robot.feet[0])
    planner = WalkPlanner(spec.planner.params, feet=robot.feet,
                          foot_length=2 * surface.half_length,
                          foot_width=2 * surface.half_width)
    planner.start(model, 0.0)
    return planner, model


def test_walk_plan_has_ten_swings_forward_from_the_current_state(walk_plan) -> None:
    planner, model = walk_plan
    out = planner.outputs(0.0)
    np.testing.assert_allclose(out["com"], model.com, atol=1e-6)  # the plan starts here [m]
    for side in ("left", "right"):
        np.testing.assert_allclose(out[f"{side}_foot"],
                                   model.frame_placement(f"{side}_foot").translation, atol=1e-6)
    swings = planner.swings
    assert [s.side for s in swings[:2]] == ["left", "right"]
    assert all(a.side != b.side for a, b in zip(swings, swings[1:]))  # alternating
    assert all(b.t_lift >= a.t_land for a, b in zip(swings, swings[1:]))  # one foot at a time
    forward = [s for s in swings if s.end[0] - s.start[0] >= 0.10 and s.duration >= 0.1]
    assert len(forward) >= 10
    # the outputs follow the swings: unloading before lift-off, in the air between
    sw = swings[1]
    lead = planner.params["unload_lead"]
    t0 = planner.t_start
    assert planner.outputs(t0 + sw.t_lift - 0.5 * lead)["right_unload"]
    mid = planner.outputs(t0 + 0.5 * (sw.t_lift + sw.t_land))
    assert mid["right_swing"] and not mid["left_swing"] and not mid["right_unload"]
    np.testing.assert_allclose(mid["right_swing_progress"], 0.5, atol=1e-9)
    np.testing.assert_allclose(mid["right_foot"], sw.sample(0.5 * (sw.t_lift + sw.t_land))[0])
    after = planner.outputs(t0 + sw.t_land + 1e-3)
    assert not after["right_swing"]
    np.testing.assert_allclose(after["right_foot"], sw.end, atol=1e-6)


def test_walk_plan_rejects_unknown_and_negative_parameters() -> None:
    with pytest.raises(BehaviorFileError, match="planner.stride: unknown key"):
        WalkPlanner({"stride": 0.1}, foot_length=0.2, foot_width=0.1)
    with pytest.raises(BehaviorFileError, match="planner.unload_lead: expected a non-negative"):
        WalkPlanner({"unload_lead": -0.1}, foot_length=0.2, foot_width=0.1)


def test_behavior_backend_key_is_checked() -> None:
    from hqp.behaviors.loader import load_behavior, parse_behavior

    assert load_behavior("walk").backend is None  # the default (the native step)
    good = ('[behavior]\ninitial = "a"\nbackend = "daqp"\n'
            '[tasks.p]\ntype = "posture"\ngoal = "standing"\n'
            '[actions.a]\ntasks = ["p"]\n[phases.a]\naction = "a"\n'
            'contacts = ["left_foot", "right_foot"]\nfinal = true\n')
    assert parse_behavior(good).backend == "daqp"
    text = ('[behavior]\ninitial = "a"\nbackend = "cplex"\n'
            '[tasks.p]\ntype = "posture"\ngoal = "standing"\n'
            '[actions.a]\ntasks = ["p"]\n[phases.a]\naction = "a"\nfinal = true\n')
    with pytest.raises(BehaviorFileError, match=r":3: behavior.backend: unknown QP backend"):
        parse_behavior(text)


_WALK: list = []


def _walk():
    """The walk of ``hqp run walk`` (run once per session, shared by the tests below)."""
    if not _WALK:
        from hqp.app.run import run_behavior

        _WALK.append(run_behavior("walk", duration=WALK_DURATION))
    return _WALK[0]


@pytest.mark.slow
def test_walk_makes_ten_footsteps_forward() -> None:
    result = _walk()
    out = result.as_json()
    summary = {k: out[k] for k in ("steps", "fell", "fall_reason", "max_torque_ratio",
                                   "controller_clipped_steps", "safe_mode_steps",
                                   "flight_time_s", "mean_speed_m_s",
                                   "com_tracking_error_max_m")}
    print(summary, out["footsteps"])
    assert not result.fell, result.fall_reason
    assert out["steps"] >= 10, out["footsteps"]
    for step in result.steps:  # the runner's definition of a footstep, checked again
        assert step["air_time_s"] >= 0.1 and step["advance_m"] >= 0.10
    assert result.metrics["flight_time_s"] == 0.0  # never both feet in the air
    # torque limits of the model: none clipped in MuJoCo (the solver's own clip: below)
    assert result.metrics["max_torque_ratio"] <= 1.0 + 1e-9
    assert result.metrics["sim_clipped_torques"] == 0
    assert result.metrics["safe_mode_steps"] <= 10
    assert result.metrics["mean_speed_m_s"] > 0.05  # [m/s]
    assert result.metrics["com_tracking_error_max_m"] < 0.02  # [m], horizontal


@pytest.mark.slow
# formerly a strict xfail: one step 0.000548 N m past a torque limit, clipped by the servo;
# gone since the hierarchy's first pass tries DAQP's cheap attempts only (a level
# they cannot solve goes to the absorbing pass instead of the relaxed-bound and ProxQP retries)
def test_walk_meets_the_torque_limits_without_the_servo_clipping() -> None:
    assert _walk().metrics["controller_clipped_steps"] == 0


@pytest.mark.slow
def test_walk_changes_its_torques_by_less_than_5_nm_per_step() -> None:
    # the servo's torque-rate level, on by default (4 N m per 1 ms step;
    # measured 4.1 N m: the level yields a little to the contact limits above it at a
    # touchdown); 52 N m without it, when a single-support swing drove the arms to their
    # acceleration bounds
    metrics = _walk().metrics
    assert metrics["max_torque_jump_nm"] < 5.0, metrics["max_torque_jump_t"]
    assert metrics["impacts"] == []  # a walk has no flight


@pytest.mark.slow
def test_walk_on_g1_makes_ten_footsteps_forward() -> None:
    # the robot's own foot spacing and centre-of-mass height (Unitree G1, 29 DoF); the servo
    # clips a few steps at a torque limit on this robot (with PlaCo's plan too:
    # docs/results/behaviors.md)
    from hqp.app.run import run_behavior

    result = run_behavior("walk", robot="g1", duration=WALK_DURATION)
    out = result.as_json()
    assert not result.fell, result.fall_reason
    assert out["steps"] >= 10, out["footsteps"]
    assert result.metrics["flight_time_s"] == 0.0
    assert result.metrics["sim_clipped_torques"] == 0
    assert result.metrics["safe_mode_steps"] == 0
    assert result.metrics["max_torque_jump_nm"] < 5.0, result.metrics["max_torque_jump_t"]
    assert result.metrics["com_tracking_error_max_m"] < 0.02  # [m], horizontal
