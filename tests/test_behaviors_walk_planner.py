"""hqp's walk planner: footsteps, supports, and the centre of mass by ZMP preview control.

The checks are the planner's promises, computed here from the plan's outputs and the soles'
geometry: the ZMP of the planned centre of mass, ``p = c - c_ddot / omega^2``, inside every
support polygon by at least ``zmp_margin``; the centre of mass continuous in position,
velocity and acceleration, its derivatives those of its position; the footsteps at the
robot's own foot spacing, at most ``step_length`` ahead of the supporting foot.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import ConvexHull

from hqp import robots
from hqp.behaviors.lipm import GRAVITY, lipm_omega, preview_com, preview_gains
from hqp.behaviors.loader import load_behavior, parse_behavior
from hqp.behaviors.planners import (
    WalkPlanner,
    make_supports,
    plan_footsteps,
)
from hqp.errors import BehaviorFileError, HQPError

ROBOTS = ("paper-humanoid", "g1")


def _standing(name: str):
    robot = robots.load(name)
    model = robot.model()
    model.update(robot.q_standing, np.zeros(model.nv))
    return robot, model


def _planner(robot, params=None) -> WalkPlanner:
    sole = robot.contact(robot.feet[0])
    if params is None:
        params = load_behavior("walk").planner.params
    return WalkPlanner(params, feet=robot.feet, foot_length=2 * sole.half_length,
                       foot_width=2 * sole.half_width)


@pytest.fixture(scope="module", params=ROBOTS)
def plan(request):
    robot, model = _standing(request.param)
    planner = _planner(robot)
    planner.start(model, 0.0)
    return robot, model, planner


# -- the preview controller ------------------------------------------------------------------

def test_preview_gains_first_preview_gain_is_minus_the_integral_gain() -> None:
    # f_1 = H Bt^T P Et and K_e = H Bt^T P At e_1, with At e_1 = e_1 = -Et (module docstring)
    gains = preview_gains(lipm_omega(0.8), 0.005, 320)
    np.testing.assert_allclose(gains.f[0], -gains.K[0], rtol=1e-12)
    # the preview gains fade over the horizon (Kajita et al.'s Figure 6): the last one is
    # below 2 % of the largest
    assert abs(gains.f[-1]) < 0.02 * np.abs(gains.f).max()


def test_preview_control_tracks_a_zmp_step_without_steady_error() -> None:
    omega, dt = lipm_omega(0.8), 0.005
    gains = preview_gains(omega, dt, 320)
    ref = np.zeros((1200, 1))
    ref[400:] = 0.1  # [m] at 2 s
    states, jerks = preview_com(np.zeros((3, 1)), ref, gains)
    zmp = states[:, 0, 0] - states[:, 2, 0] / omega**2
    assert abs(zmp[-1] - 0.1) < 1e-4  # [m]: the integral action leaves no offset
    assert abs(states[-1, 1, 0]) < 1e-3  # [m/s]: at rest again
    assert abs(zmp[:300]).max() < 1e-3  # the CoM starts moving before the step (preview)
    assert abs(states[390, 0, 0]) > 1e-3
    # the states follow the cart-table model exactly from the jerks
    A, B = gains.A, gains.B
    for k in (0, 399, 400, 1100):
        np.testing.assert_allclose(states[k + 1, :, 0], A @ states[k, :, 0] + B * jerks[k, 0],
                                   atol=1e-14)


def test_preview_and_lipm_reject_bad_input() -> None:
    with pytest.raises(HQPError, match="height must be positive"):
        lipm_omega(0.0)
    with pytest.raises(HQPError, match="ZMP preview"):
        preview_gains(3.0, 0.0, 10)
    with pytest.raises(HQPError, match="ZMP preview"):
        preview_gains(3.0, 0.005, 0)


# -- footsteps and supports ------------------------------------------------------------------

def test_footsteps_alternate_at_the_robot_s_spacing_and_step_length(plan) -> None:
    robot, model, planner = plan
    p = planner.params
    steps = planner.footsteps
    left0 = model.frame_placement(robot.feet[0]).translation
    right0 = model.frame_placement(robot.feet[1]).translation
    np.testing.assert_allclose(steps[0].position, left0, atol=1e-12)
    np.testing.assert_allclose(steps[1].position, right0, atol=1e-12)
    # 1.0 m at 0.11 m: nine steps of 0.11 m ahead of the support, then 0.12 - 0.01 to the end
    assert len(steps) == 13
    assert [s.side for s in steps[2:]] == ["left", "right"] * 5 + ["left"]
    last = {"left": steps[0], "right": steps[1]}
    for step in steps[2:]:
        support = last["right" if step.side == "left" else "left"]
        ahead = step.position[0] - support.position[0]
        assert -1e-12 <= ahead <= p["step_length"] + 1e-12
        # lateral: the robot's own spacing, kept
        np.testing.assert_allclose(step.position[1], last[step.side].position[1], atol=1e-12)
        np.testing.assert_allclose(abs(step.position[1] - support.position[1]),
                                   abs(left0[1] - right0[1]), atol=1e-12)
        last[step.side] = step
    for side, start in (("left", left0), ("right", right0)):  # both feet arrive
        np.testing.assert_allclose(last[side].position, start + [p["distance"], 0, 0],
                                   atol=1e-12)


def test_footsteps_follow_the_stance_heading_and_spacing() -> None:
    yaw = np.deg2rad(30.0)
    R = np.array([[np.cos(yaw), -np.sin(yaw), 0], [np.sin(yaw), np.cos(yaw), 0], [0, 0, 1]])
    T_left, T_right = np.eye(4), np.eye(4)
    T_left[:3, :3] = T_right[:3, :3] = R
    T_left[:3, 3] = R @ [0.0, 0.15, 0.0] + [1.0, 2.0, 0.0]
    T_right[:3, 3] = R @ [0.0, -0.15, 0.0] + [1.0, 2.0, 0.0]
    steps = plan_footsteps(T_left, T_right, 0.5, 0.2)
    advance = [float((s.position - T_left[:3, 3]) @ R[:, 0]) for s in steps]
    across = [float((s.position - T_right[:3, 3]) @ R[:, 1]) for s in steps]
    np.testing.assert_allclose(advance, [0, 0, 0.2, 0.4, 0.5, 0.5], atol=1e-12)
    np.testing.assert_allclose(across, [0.3, 0, 0.3, 0, 0.3, 0], atol=1e-12)
    still = plan_footsteps(T_left, T_right, 0.0, 0.2)  # no distance: each foot steps in place
    assert [s.side for s in still] == ["left", "right", "left", "right"]
    for step in still[2:]:
        np.testing.assert_allclose(step.position, still[0 if step.side == "left" else 1].position,
                                   atol=1e-12)
    with pytest.raises(BehaviorFileError, match="step_length must be positive"):
        plan_footsteps(T_left, T_right, 0.5, 0.0)
    with pytest.raises(BehaviorFileError, match="more than 3 footsteps"):
        plan_footsteps(T_left, T_right, 5.0, 0.2, max_steps=3)


def test_supports_start_and_end_double_then_alternate(plan) -> None:
    _, _, planner = plan
    p = planner.params
    single = p["single_support_duration"]
    double = p["double_support_ratio"] * single
    startend = p["startend_double_support_ratio"] * single
    supports = planner.supports
    durations = [s.t_end - s.t_start for s in supports]
    kinds = [s.double for s in supports]
    assert kinds == [True] + [False, True] * 11
    np.testing.assert_allclose(durations, [startend] + [single, double] * 10
                               + [single, startend], atol=1e-12)
    assert all(a.t_end == b.t_start for a, b in zip(supports, supports[1:]))
    np.testing.assert_allclose(planner.duration, 2 * startend + 11 * single + 10 * double)
    # each single support stands on the foot that does not swing
    for support, swing in zip([s for s in supports if not s.double], planner.swings):
        assert support.feet[0].side != swing.side
        assert swing.t_lift == support.t_start and swing.t_land == support.t_end
    assert make_supports(planner.footsteps, single, 0.0, startend)[1].double is False


# -- the centre of mass ----------------------------------------------------------------------

def _sole_polygon(support, robot) -> np.ndarray:
    sole = robot.contact(robot.feet[0])
    corners = []
    for foot in support.feet:
        for sx in (-1, 1):
            for sy in (-1, 1):
                local = np.array([sx * sole.half_length, sy * sole.half_width, 0.0])
                corners.append((foot.position + foot.rotation @ local)[:2])
    return ConvexHull(np.array(corners)).equations


def test_planned_zmp_stays_in_the_support_polygon_with_its_margin(plan) -> None:
    robot, _, planner = plan
    margin = planner.params["zmp_margin"]
    omega = np.sqrt(GRAVITY / planner.com_height)
    np.testing.assert_allclose(planner.omega, omega, rtol=1e-12)
    worst = np.inf
    for support in planner.supports:
        eq = _sole_polygon(support, robot)
        for tau in np.arange(support.t_start, support.t_end, 1e-3):
            c, _, a = planner.com_state(tau)
            p = c[:2] - a[:2] / omega**2
            worst = min(worst, float(-(eq[:, :2] @ p + eq[:, 2]).max()))
    assert worst >= margin, worst  # [m]
    # the planner's own account agrees
    assert planner.zmp_support_margin()[0] == pytest.approx(worst, abs=2e-3)
    assert planner.outputs(planner.t_start + 3.3)["zmp"].shape == (2,)


def test_com_is_continuous_and_its_derivatives_are_its_own(plan) -> None:
    _, model, planner = plan
    dt = planner.params["timestep"]
    # at rest at the measured centre of mass when the plan starts
    c0, v0, a0 = planner.com_state(0.0)
    np.testing.assert_allclose(c0, model.com, atol=1e-12)
    np.testing.assert_allclose(v0, 0.0, atol=1e-12)
    np.testing.assert_allclose(a0, 0.0, atol=1e-12)
    # continuity across the samples where the jerk changes
    for k in range(1, int(planner.duration / dt), 7):
        before = planner.com_state(k * dt - 1e-9)
        after = planner.com_state(k * dt + 1e-9)
        for x, y, tol in zip(before, after, (1e-9, 1e-8, 1e-7)):
            np.testing.assert_allclose(x, y, atol=tol)
    # velocity and acceleration are the derivatives of position and velocity
    rng = np.random.default_rng(0)
    h = 1e-5
    for tau in rng.uniform(0.0, planner.duration, 50):
        c_p, v_p, _ = planner.com_state(tau + h)
        c_m, v_m, _ = planner.com_state(tau - h)
        _, v, a = planner.com_state(tau)
        np.testing.assert_allclose((c_p - c_m) / (2 * h), v, atol=1e-8)  # [m/s]
        np.testing.assert_allclose((v_p - v_m) / (2 * h), a, atol=1e-6)  # [m/s^2]
    # ends over the centre of the final feet, settled once the preview time has passed
    final = 0.5 * (planner.footsteps[-1].position + planner.footsteps[-2].position)
    c, v, _ = planner.com_state(planner.duration + planner.params["preview_time"])
    np.testing.assert_allclose(c[:2], final[:2], atol=1e-3)
    np.testing.assert_allclose(v, 0.0, atol=1e-3)


def _com_state_vectors(planner: WalkPlanner, tau: float):
    """The planned centre of mass at plan time ``tau`` as numpy vector expressions."""
    from hqp.tasks.reference import min_jerk_profile

    dt = float(planner.params["timestep"])
    n = planner._jerks.shape[0]
    tau = min(max(float(tau), 0.0), n * dt)
    k = min(int(tau // dt), n - 1)
    s = tau - k * dt
    c, v, a = planner._states[k]
    j = planner._jerks[k]
    pos, vel, acc = np.empty(3), np.empty(3), np.empty(3)
    pos[:2] = c + v * s + a * s * s / 2 + j * s**3 / 6
    vel[:2] = v + a * s + j * s * s / 2
    acc[:2] = a + j * s
    if tau >= n * dt:
        vel[:2] = 0.0
        acc[:2] = 0.0
    m, dm, ddm = min_jerk_profile(tau, planner.supports[0].t_end)
    dz = planner._z1 - planner._z0
    pos[2], vel[2], acc[2] = planner._z0 + m * dz, dm * dz, ddm * dz
    return pos, vel, acc


def test_com_state_is_the_vector_expression_bit_for_bit(plan) -> None:
    _, _, planner = plan
    dt = planner.params["timestep"]
    rng = np.random.default_rng(1)
    end = planner.duration + planner.params["preview_time"]
    taus = np.concatenate([np.arange(0.0, end + 0.5, dt / 3),
                           rng.uniform(-1.0, end + 1.0, 500)])
    for tau in taus:
        for x, y in zip(planner.com_state(tau), _com_state_vectors(planner, tau)):
            assert x.tobytes() == y.tobytes(), tau


def test_outputs_follow_the_plan_and_its_flags() -> None:
    robot, model = _standing("paper-humanoid")
    planner = _planner(robot, {"start_delay": 0.3})
    with pytest.raises(BehaviorFileError, match="before start"):
        planner.output("com", 0.0)
    planner.start(model, 1.0)
    assert planner.t_start == pytest.approx(1.3)
    out = planner.outputs(1.0)
    assert not out["started"] and not out["done"] and out["double_support"]
    assert out["steps_planned"] == 13 and out["swings"] == 11
    np.testing.assert_allclose(out["trunk_rotation"], np.eye(3), atol=1e-12)
    end = planner.outputs(1.3 + planner.duration)
    assert end["started"] and end["done"]
    sw = planner.swings[0]
    mid = planner.outputs(1.3 + 0.5 * (sw.t_lift + sw.t_land))
    assert mid["left_swing"] and not mid["double_support"]
    np.testing.assert_allclose(mid["left_foot"], sw.sample(0.5 * (sw.t_lift + sw.t_land))[0])
    c, _, a = planner.com_state(0.5 * (sw.t_lift + sw.t_land))
    np.testing.assert_allclose(mid["zmp"], c[:2] - a[:2] / planner.omega**2)
    with pytest.raises(KeyError):
        planner.output("stride", 1.0)


# -- parameters ------------------------------------------------------------------------------

def test_walk_planner_rejects_bad_parameters() -> None:
    kw = {"foot_length": 0.2, "foot_width": 0.1}
    with pytest.raises(BehaviorFileError, match="planner.stride: unknown key"):
        WalkPlanner({"stride": 0.1}, **kw)
    with pytest.raises(BehaviorFileError, match="planner.planned_timesteps: a parameter of "
                       "PlaCo's planner.*set preview_time"):
        WalkPlanner({"planned_timesteps": 100}, **kw)
    with pytest.raises(BehaviorFileError, match="planner.step_length: expected a positive"):
        WalkPlanner({"step_length": 0.0}, **kw)
    with pytest.raises(BehaviorFileError, match="planner.timestep: expected a non-negative"):
        WalkPlanner({"timestep": float("nan")}, **kw)
    with pytest.raises(BehaviorFileError, match="planner.foot_height: expected a non-negative"):
        WalkPlanner({"foot_height": True}, **kw)
    with pytest.raises(BehaviorFileError, match="soles must have a positive size"):
        WalkPlanner({}, foot_length=0.0, foot_width=0.1)


def test_a_plan_the_robot_cannot_balance_is_refused() -> None:
    robot, model = _standing("paper-humanoid")
    # no start double support: the ZMP would have to jump from between the feet to a sole
    planner = _planner(robot, {"startend_double_support_ratio": 0.0})
    with pytest.raises(BehaviorFileError, match="planned ZMP leaves the support polygon"):
        planner.start(model, 0.0)


def test_the_earlier_planner_type_is_an_alias() -> None:
    text = ('[behavior]\ninitial = "a"\n[planner]\ntype = "{}"\ndistance = 0.5\n'
            '[tasks.c]\ntype = "com"\ngoal = "plan.com"\n'
            '[actions.a]\ntasks = ["c"]\n[phases.a]\naction = "a"\n'
            'contacts = ["left_foot", "right_foot"]\nfinal = true\n')
    for name in ("walk", "placo_walk"):
        spec = parse_behavior(text.format(name))
        assert spec.planner.type == name and spec.planner.params == {"distance": 0.5}
    with pytest.raises(BehaviorFileError, match="unknown planner 'placo'"):
        parse_behavior(text.format("placo"))
