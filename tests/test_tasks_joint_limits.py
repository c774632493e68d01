"""Viable joint limits (Del Prete 2018) and the papers' activation zones (seed 003, eq. 25)."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from hqp import HQPError, InvalidGain
from hqp.model import RobotModel
from hqp.model.layout import Layout
from hqp.tasks.base import Category
from hqp.tasks.joint_limit_zone import JointLimitZone
from hqp.tasks.joint_limits import JointLimits, SupportBraking, max_acceleration_from_torques

DT = 1e-3
V_MAX = 1.0
TAU_MAX = 100.0


@pytest.fixture(scope="module")
def arm() -> RobotModel:
    model = pin.buildSampleModelManipulator()
    return RobotModel(model, name="arm", floating_base=False,
                      velocity_limits=np.full(6, V_MAX), torque_limits=np.full(6, TAU_MAX))


@pytest.fixture(scope="module")
def humanoid() -> RobotModel:
    return RobotModel(pin.buildSampleModelHumanoid(), name="sample")


def test_braking_at_maximum_velocity_stays_viable(arm: RobotModel) -> None:
    """Every joint runs at v_max toward its upper limit, taking its upper bound every step."""
    dt = 4e-3  # any period works; a coarse one keeps the test fast
    data = arm.model.createData()
    q, v = arm.neutral(), np.zeros(arm.nv)
    arm.update(q, v)
    A = max_acceleration_from_torques(arm, margin=0.5)
    assert np.all(A > 0) and np.all(np.isfinite(A))
    task = JointLimits(qdd_max=A)
    # Start a little before the last viable position for v_max.
    q = arm.q_upper - V_MAX**2 / (2 * A) - 0.05
    v = np.full(arm.nv, V_MAX)
    worst_torque = 0.0
    closest = np.full(arm.na, np.inf)
    for _ in range(int(1.2 * (V_MAX / A.min() + 0.05 / V_MAX) / dt)):
        arm.update(q, v)
        lb, ub = task.bounds(arm, dt)
        assert np.all(lb <= ub + 1e-12)
        assert np.all(ub >= -A - 1e-9)  # braking never needs more than A
        a = ub
        assert np.all(np.abs(a) <= A + 1e-9)
        tau = pin.rnea(arm.model, data, q, v, a)
        worst_torque = max(worst_torque, float(np.max(np.abs(tau) / TAU_MAX)))
        q = q + dt * v + 0.5 * dt**2 * a
        v = v + dt * a
        assert np.all(q <= arm.q_upper + 1e-12)
        assert np.all(np.abs(v) <= V_MAX + 1e-9)
        closest = np.minimum(closest, arm.q_upper - q)
    # Not conservative: the joints end up at their limits, nearly at rest (taking the
    # upper bound every step leaves a velocity ripple of order A dt at the limit).
    assert np.all(closest < 1e-3)
    assert np.all(np.abs(v) < 2 * A * dt)
    assert 0.05 < worst_torque <= 1.0


def test_any_acceleration_in_the_bounds_keeps_the_state_viable(arm: RobotModel) -> None:
    rng = np.random.default_rng(11)
    A = np.full(arm.na, 3.0)
    task = JointLimits(qdd_max=A)
    for _ in range(200):
        q = arm.random_configuration(rng)
        room_up = arm.q_upper - q
        room_lo = q - arm.q_lower
        v_hi = np.minimum(V_MAX, np.sqrt(2 * A * room_up))
        v_lo = np.minimum(V_MAX, np.sqrt(2 * A * room_lo))
        v = rng.uniform(-v_lo, v_hi)
        arm.update(q, v)
        lb, ub = task.bounds(arm, DT)
        assert np.all(lb <= ub + 1e-9)
        assert np.all(ub >= -A - 1e-9) and np.all(lb <= A + 1e-9)
        for a in (lb, ub, 0.5 * (lb + ub)):
            q1 = q + DT * v + 0.5 * DT**2 * a
            v1 = v + DT * a
            assert np.all(q1 <= arm.q_upper + 1e-12) and np.all(q1 >= arm.q_lower - 1e-12)
            assert np.all(np.abs(v1) <= V_MAX + 1e-9)
            up = np.maximum(v1, 0.0) ** 2 - 2 * A * (arm.q_upper - q1)
            down = np.minimum(v1, 0.0) ** 2 - 2 * A * (q1 - arm.q_lower)
            assert np.all(up <= 1e-9) and np.all(down <= 1e-9)


def test_state_that_is_not_viable_brakes(arm: RobotModel) -> None:
    A = 2.0
    task = JointLimits(qdd_max=A)
    q = arm.neutral()
    q[2] = arm.q_upper[2] - 0.01
    v = np.zeros(arm.nv)
    v[2] = 0.9  # braking distance 0.2 rad > 0.01 rad
    v[4] = -1.5  # above v_max
    arm.update(q, v)
    lb, ub = task.bounds(arm, DT)
    assert lb[2] == ub[2] == -A
    assert lb[4] == ub[4] == A


def test_max_acceleration_estimate_is_within_the_torque_limits(arm: RobotModel) -> None:
    rng = np.random.default_rng(12)
    data = arm.model.createData()
    for _ in range(10):
        q, v = arm.random_configuration(rng), 0.3 * rng.normal(size=arm.nv)
        arm.update(q, v)
        A = max_acceleration_from_torques(arm, margin=1.0)
        ratios = []
        for i in range(arm.na):
            for sign in (1.0, -1.0):
                a = np.zeros(arm.nv)
                a[i] = sign * A[i]
                ratios.append(np.max(np.abs(pin.rnea(arm.model, data, q, v, a)) / TAU_MAX))
        assert max(ratios) <= 1.0 + 1e-9
        assert max(ratios) > 0.99  # tight for some joint


def test_joint_limit_rows_on_a_floating_base(humanoid: RobotModel) -> None:
    rng = np.random.default_rng(13)
    layout = Layout.build(humanoid.nv)
    task = JointLimits(qdd_max=5.0, position_margin=0.01, velocity_scale=0.9)
    assert task.category is Category.JOINT_LIMITS
    q = humanoid.random_configuration(rng, margin=0.1)
    humanoid.update(q, 0.1 * rng.normal(size=humanoid.nv))
    rows = task.rows(humanoid, layout, DT, 0.0)
    assert rows.C.shape == (humanoid.na, layout.n)
    np.testing.assert_array_equal(rows.C[:, :6], 0.0)
    np.testing.assert_array_equal(rows.C[:, 6:], np.eye(humanoid.na))
    lb, ub = task.bounds(humanoid, DT)
    np.testing.assert_array_equal(rows.lower, lb)
    np.testing.assert_array_equal(rows.upper, ub)
    assert np.all(ub <= 5.0) and np.all(lb >= -5.0)
    # No estimate needed when qdd_max is infinite: one-step bounds only.
    inf_task = JointLimits(qdd_max=np.inf)
    lb_inf, ub_inf = inf_task.bounds(humanoid, DT)
    assert np.all(ub_inf >= ub - 1e-9)


def test_joint_limit_errors(humanoid: RobotModel) -> None:
    with pytest.raises(InvalidGain, match="JointLimits 'jl': qdd_max"):
        JointLimits("jl", qdd_max=0.0)
    with pytest.raises(InvalidGain, match="margin"):
        JointLimits(margin=1.5)
    with pytest.raises(InvalidGain, match="position_margin"):
        JointLimits(position_margin=-0.1)
    with pytest.raises(InvalidGain, match="dt"):
        JointLimits(qdd_max=1.0).bounds(humanoid, 0.0)
    with pytest.raises(InvalidGain, match="2 entries"):
        JointLimits(qdd_max=[1.0, 2.0]).bounds(humanoid, DT)


def test_activation_zone_rows(humanoid: RobotModel) -> None:
    layout = Layout.build(humanoid.nv)
    task = JointLimitZone(zone=0.2, depth=0.3, kp=100.0, kv=20.0)
    assert task.category is Category.JOINT_LIMITS
    q = humanoid.neutral()
    v = np.zeros(humanoid.nv)
    humanoid.update(q, v)
    assert task.rows(humanoid, layout, DT, 0.0).n_eq == 0
    assert task.active == ()
    qa = q[humanoid.actuated_q]
    qa[3] = humanoid.q_upper[3] - 0.1
    qa[7] = humanoid.q_lower[7] + 0.05
    qa[9] = humanoid.q_upper[9] - 0.25  # outside the zone
    q[humanoid.actuated_q] = qa
    v[6 + 3], v[6 + 7] = 0.5, -0.2
    humanoid.update(q, v)
    rows = task.rows(humanoid, layout, DT, 0.0)
    assert task.active == (humanoid.joint_names[3], humanoid.joint_names[7])
    idx, q_limit = task.active_indices(humanoid)
    np.testing.assert_array_equal(idx, [3, 7])
    np.testing.assert_allclose(q_limit, [humanoid.q_upper[3] - 0.3, humanoid.q_lower[7] + 0.3])
    expected_A = np.zeros((2, layout.n))
    expected_A[0, 6 + 3] = expected_A[1, 6 + 7] = 1.0
    np.testing.assert_array_equal(rows.A, expected_A)
    e = q_limit - qa[idx]
    np.testing.assert_allclose(task.error(), e)
    np.testing.assert_allclose(rows.b, -20.0 * (np.array([0.5, -0.2]) - 5.0 * e))
    # Velocity saturation (eq. 28): the desired velocity is scaled to max_velocity.
    sat = JointLimitZone(zone=0.2, depth=0.3, kp=100.0, kv=20.0, max_velocity=0.1)
    b = sat.rows(humanoid, layout, DT, 0.0).b
    v_des = 5.0 * e * 0.1 / np.linalg.norm(5.0 * e)
    np.testing.assert_allclose(b, -20.0 * (np.array([0.5, -0.2]) - v_des))


def test_activation_zone_closed_loop_stops_before_the_limit(arm: RobotModel) -> None:
    """A joint entering its zone at 1 rad/s is driven back to the safety position."""
    layout = Layout.build(arm.nv)
    dt = 2e-3
    task = JointLimitZone(zone=0.15, kp=100.0, kv=20.0)
    q, v = arm.neutral(), np.zeros(arm.nv)
    q[1] = arm.q_upper[1] - 0.2
    v[1] = 1.0
    peak = -np.inf
    for _ in range(1000):
        arm.update(q, v)
        rows = task.rows(arm, layout, dt, 0.0)
        a = np.zeros(arm.nv)
        if rows.n_eq:
            a[task.active_indices(arm)[0]] = rows.b
        q = q + dt * v + 0.5 * dt**2 * a
        v = v + dt * a
        peak = max(peak, q[1])
    assert peak < arm.q_upper[1] - 0.05
    np.testing.assert_allclose(q[1], arm.q_upper[1] - 0.15, atol=2e-3)
    assert task.active == (arm.joint_names[1],)


def test_activation_zone_errors() -> None:
    with pytest.raises(InvalidGain, match="JointLimitZone 'z'"):
        JointLimitZone("z", zone=-0.1)
    with pytest.raises(InvalidGain, match="kp"):
        JointLimitZone(kp=0.0)
    with pytest.raises(InvalidGain, match="max_velocity"):
        JointLimitZone(max_velocity=-1.0)


def test_support_estimate_against_kinetic_and_potential_energy(humanoid: RobotModel) -> None:
    """With the right foot held, a right-leg joint moves the rest of the body about its axis.

    Independent check: the generalized velocity that turns the whole robot
    about the joint axis while the joint turns back (so its subtree is still)
    has kinetic energy ``I_rest / 2`` (``v^T M v``) and weight power ``v^T g``.
    """
    rng = np.random.default_rng(14)
    model = humanoid.model
    data = model.createData()
    supports = ["rleg_effector_body"]
    tau = humanoid.tau_max
    for _ in range(5):
        q = humanoid.random_configuration(rng)
        humanoid.update(q, np.zeros(humanoid.nv))
        A = max_acceleration_from_torques(humanoid, margin=1.0, supports=supports)
        pin.forwardKinematics(model, data, q)
        pin.computeJointJacobians(model, data, q)
        M = pin.crba(model, data, q)
        M = np.triu(M) + np.triu(M, 1).T
        g = pin.computeGeneralizedGravity(model, data, q)
        for name in ("rleg_shoulder2_joint", "rleg_elbow_joint", "rleg_wrist1_joint",
                     "rarm_elbow_joint", "lleg_elbow_joint"):
            j = model.getJointId(name)
            i = humanoid.joint_index(name)
            iv = model.joints[j].idx_v
            if name.startswith("rleg"):
                S = pin.getJointJacobian(model, data, j, pin.ReferenceFrame.WORLD)[:, iv]
                v = np.zeros(humanoid.nv)
                v[:6] = data.oMi[1].actInv(pin.Motion(S)).vector
                v[iv] = -1.0
                inertia, weight = v @ M @ v, abs(v @ g)
            else:  # the subtree moves: inertia M_ii, weight torque g_i
                inertia, weight = M[iv, iv], abs(g[iv])
            expected = max(tau[i] - weight, 0.0) / inertia
            np.testing.assert_allclose(A[i], expected, rtol=1e-9)
    # Double support: a leg joint keeps the smaller of its two sides.
    both = max_acceleration_from_torques(humanoid, 1.0, supports=supports + ["lleg_effector_body"])
    one = max_acceleration_from_torques(humanoid, 1.0, supports=supports)
    assert np.all(both <= one + 1e-12)
    with pytest.raises(HQPError, match="unknown frame 'sole'"):
        max_acceleration_from_torques(humanoid, supports=["sole"])


def test_acceleration_bounds_are_optional(arm: RobotModel) -> None:
    A = 0.5
    q, v = arm.neutral(), np.zeros(arm.nv)
    arm.update(q, v)  # far from the limits, at rest
    lb, ub = JointLimits(qdd_max=A).bounds(arm, DT)
    np.testing.assert_allclose(ub, A)
    np.testing.assert_allclose(lb, -A)
    free = JointLimits(qdd_max=A, acceleration_bounds=False)
    lb, ub = free.bounds(arm, DT)
    np.testing.assert_allclose(ub, V_MAX / DT)  # the velocity bounds are what is left
    np.testing.assert_allclose(lb, -V_MAX / DT)
    capped = JointLimits(qdd_max=A, acceleration_bounds=False, inactive_beyond=500.0)
    lb, ub = capped.bounds(arm, DT)
    assert np.all(np.isinf(ub)) and np.all(np.isinf(lb))  # bounds far from binding: inactive
    # Still viable: near the upper limit at speed, braking at -A is what is left.
    q[0] = arm.q_upper[0] - 0.3
    v[0] = np.sqrt(2 * A * 0.3) - 1e-3
    arm.update(q, v)
    lb, ub = free.bounds(arm, DT)
    assert -A - 1e-9 <= ub[0] < -A + 5.0
    q1 = q[0] + DT * v[0] + 0.5 * DT**2 * ub[0]
    v1 = v[0] + DT * ub[0]
    assert v1**2 <= 2 * A * (arm.q_upper[0] - q1) + 1e-9


def test_braking_below_the_acceleration_bound_does_not_lock_and_stops_at_the_limit(
    arm: RobotModel,
) -> None:
    """``braking`` small, ``qdd_max`` large: free far from the limit, stopped exactly at it.

    Closed loop with the semi-implicit Euler step of a simulator (``q+ = q + dt v+``), taking
    the upper bound at every step: the joint ends at its limit without passing it, nearly at
    rest.
    """
    A_max, B = 50.0, 1.0
    task = JointLimits(qdd_max=A_max, braking=B, reserve=2.0)
    q, v = arm.neutral(), np.zeros(arm.nv)
    arm.update(q, v)
    lb, ub = task.bounds(arm, DT)
    np.testing.assert_allclose(ub, A_max)  # far from the limits: not locked by the braking
    np.testing.assert_allclose(lb, -A_max)
    q[0] = arm.q_upper[0] - 0.2
    peak = -np.inf
    for k in range(3000):
        arm.update(q, v)
        lb, ub = task.bounds(arm, DT)
        assert lb[0] <= ub[0]
        if k > 5 and arm.q_upper[0] - q[0] > 1e-4:
            # accelerating at A_max to the braking curve, then braking within 2 B (the last
            # steps may need the one-step stop, -2 v / dt, a few rad/s^2 at mm/s)
            assert ub[0] >= -2.0 * B - 1e-9
        v = v + DT * np.where(np.arange(arm.nv) == 0, ub, 0.0)
        q = q + DT * v
        peak = max(peak, q[0])
        assert abs(v[0]) <= np.sqrt(2 * B * max(arm.q_upper[0] - q[0], 0.0)) + A_max * DT
    assert peak <= arm.q_upper[0] + 1e-12
    np.testing.assert_allclose(q[0], arm.q_upper[0], atol=1e-4)
    assert abs(v[0]) < 2.0 * B * DT


def test_a_state_past_its_limit_is_driven_back_within_the_reserve(arm: RobotModel) -> None:
    A_max, B = 50.0, 1.0
    task = JointLimits(qdd_max=A_max, braking=B, reserve=2.0)
    q, v = arm.neutral(), np.zeros(arm.nv)
    q[1] = arm.q_lower[1] - 0.01  # 10 mrad past the lower limit, at rest
    q[2] = arm.q_upper[2] - 0.01  # not viable for B: 0.5 rad/s at 10 mrad
    v[2] = 0.5
    arm.update(q, v)
    lb, ub = task.bounds(arm, DT)
    np.testing.assert_allclose([lb[1], ub[1]], [2.0 * B, A_max])  # back toward the range
    np.testing.assert_allclose([lb[2], ub[2]], [-A_max, -2.0 * B])  # brake, within 2 B
    for name in ("braking", "reserve"):
        with pytest.raises(InvalidGain, match=name):
            JointLimits(**{name: 0.5 if name == "reserve" else 0.0})


def test_return_from_past_a_limit_uses_the_velocity_time_constant(arm: RobotModel) -> None:
    # 10 mrad past the lower limit, returning at 0.12 rad/s: with T_v = 20 ms the return bound
    # is (v_r - v) / T_v (continuous in v), with T_v = dt it is dead-beat, clipped at 2 B.
    B = 1.0
    q, v = arm.neutral(), np.zeros(arm.nv)
    q[1] = arm.q_lower[1] - 0.01
    v[1] = 0.12
    arm.update(q, v)
    v_r = np.sqrt(2.0 * B * 0.01)  # toward the range
    slow = JointLimits(qdd_max=50.0, braking=B, reserve=2.0, velocity_time=0.02)
    lb, _ = slow.bounds(arm, DT)
    np.testing.assert_allclose(lb[1], (v_r - 0.12) / 0.02, rtol=1e-9)  # 1.07 rad/s^2
    lb, _ = JointLimits(qdd_max=50.0, braking=B, reserve=2.0).bounds(arm, DT)
    np.testing.assert_allclose(lb[1], 2.0 * B)  # (v_r - v) / dt = 21 rad/s^2, clipped


def test_support_braking_follows_the_active_contacts(humanoid: RobotModel) -> None:
    """One braking per set of held frames, each equal to the direct estimate; the task follows
    the frames the stack reports, and ``airborne`` takes the free-limb values."""
    feet = ["rleg_effector_body", "lleg_effector_body"]
    q = humanoid.neutral()
    base = np.full(humanoid.na, 30.0)
    table = SupportBraking(humanoid, feet, base, margin=0.5, q=q)
    assert len(table.table) == 4
    np.testing.assert_array_equal(table(()), base)
    humanoid.update(q, np.zeros(humanoid.nv))
    for held in ([feet[0]], [feet[1]], feet):
        support = max_acceleration_from_torques(humanoid, 0.5, supports=held)
        expected = np.where(support > 0.0, np.minimum(base, support), base)
        np.testing.assert_allclose(table(held), expected, rtol=1e-12)
        np.testing.assert_allclose(table([*held, "some_other_frame"]), expected, rtol=1e-12)
    knee = humanoid.joint_index("rleg_elbow_joint")  # the sample humanoid's right knee
    # held: the knee moves the body about the sole; its foot in the air: the shank alone
    assert table([feet[0]])[knee] < 0.5 * table([feet[1]])[knee]

    coarse = SupportBraking(humanoid, feet, base, margin=0.5, q=q, per_contact=False)
    assert len(coarse.table) == 2
    np.testing.assert_array_equal(coarse([feet[0]]), table(feet))  # any contact: all held
    np.testing.assert_array_equal(coarse(()), base)

    task = JointLimits(qdd_max=60.0, braking=table)
    for held in ((), (feet[0],), tuple(feet)):
        task.set_active_contacts(held)
        np.testing.assert_allclose(task.braking_deceleration(humanoid),
                                   np.minimum(table(held), 60.0))
    task.set_airborne_braking(True)  # a take-off: the supports are ignored
    np.testing.assert_allclose(task.braking_deceleration(humanoid), np.minimum(base, 60.0))
    with pytest.raises(HQPError, match="base must be > 0"):
        SupportBraking(humanoid, feet, 0.0)
    with pytest.raises(HQPError, match="margin must be in"):
        SupportBraking(humanoid, [], 1.0, margin=0.0)
    with pytest.raises(HQPError, match="unknown frame 'sole'"):
        SupportBraking(humanoid, ["sole"], 1.0)


def test_the_braking_curve_is_approached_without_an_acceleration_step(arm: RobotModel) -> None:
    """``approach_time``: a joint taking its upper bound every step (semi-implicit Euler, as
    MuJoCo) reaches its velocity limit (approached over ``T_a``), its braking curve and its
    limit; without the approach its bound falls from
    ``A_max`` to about ``-B`` in one step, with it by at most ``(A_max + B) dt / T_a`` per step
    (plus the curve's own slope), and the joint still stops at the limit, not past it."""
    A_max, B, T_a = 50.0, 12.5, 0.02
    steps = {}
    for approach in (0.0, T_a):
        task = JointLimits(qdd_max=A_max, braking=B, reserve=2.0, velocity_time=T_a,
                           approach_time=approach)
        q, v = arm.neutral(), np.zeros(arm.nv)
        q[0] = arm.q_upper[0] - 0.4
        last, worst, peak = None, 0.0, -np.inf
        for _ in range(1500):
            arm.update(q, v)
            lb, ub = task.bounds(arm, DT)
            assert lb[0] <= ub[0]
            if last is not None:
                worst = max(worst, abs(ub[0] - last))
            last = ub[0]
            v = v + DT * np.where(np.arange(arm.nv) == 0, ub, 0.0)
            q = q + DT * v
            peak = max(peak, q[0])
        assert peak <= arm.q_upper[0] + 1e-12
        np.testing.assert_allclose(q[0], arm.q_upper[0], atol=1e-3)
        steps[approach] = worst
    assert steps[0.0] > 0.9 * (A_max + B)  # the discrete bound: one step from A_max to -B
    assert steps[T_a] < 2.0 * (A_max + B) * DT / T_a, steps


def test_approach_time_is_checked() -> None:
    with pytest.raises(InvalidGain, match="approach_time"):
        JointLimits(qdd_max=10.0, approach_time=-1.0)


def test_an_overspeed_joint_is_braked_at_its_recovery_deceleration(arm: RobotModel) -> None:
    """``recovery``: a joint thrown far past its braking curve (g1's wrist in a conflict:
    20 rad/s on a 50 rad/s^2 bound) stops at its limit, braked at what stops it
    there; a viable state's bounds are those without it, and recovery 0 or ``None`` changes
    nothing."""
    A_max, B, R = 50.0, 25.0, 3e4
    plain = JointLimits(qdd_max=A_max, braking=B, reserve=2.0, velocity_time=0.02)
    task = JointLimits(qdd_max=A_max, braking=B, reserve=2.0, velocity_time=0.02,
                       recovery=np.array([R, R, R, R, R, 0.0]))
    rng = np.random.default_rng(24)
    changed = 0
    for trial in range(200):
        q = arm.random_configuration(rng)
        v = rng.normal(scale=[0.3, 3.0][trial % 2], size=arm.nv)
        arm.update(q, v)
        lb0, ub0 = plain.bounds(arm, DT)
        lb1, ub1 = task.bounds(arm, DT)
        assert lb1[5] == lb0[5] and ub1[5] == ub0[5]
        same = (lb1 == lb0) & (ub1 == ub0)
        # only states that are not viable change: pinned to one braking value within R
        assert np.all(same | ((lb1 == ub1) & (lb0 == ub0) & (np.abs(ub1) <= R)))
        assert np.all(same | (np.sign(ub1) == -np.sign(v)))
        changed += int(np.sum(~same))
    assert changed > 0
    # 20 rad/s at 1.2 rad from the limit (braking curve 7.7 rad/s), closed loop with the
    # simulator's semi-implicit Euler step, taking the lower bound (the hardest braking the
    # level allows): stopped before the limit with the recovery, far past it without.
    for jl, stops in ((task, True), (plain, False)):
        q, v = arm.neutral(), np.zeros(arm.nv)
        q[0], v[0] = arm.q_upper[0] - 1.2, 20.0
        peak = q[0]
        for _ in range(2000):
            arm.update(q, v)
            lb, ub = jl.bounds(arm, DT)
            assert lb[0] <= ub[0] + 1e-12
            v = v + DT * np.where(np.arange(arm.nv) == 0, lb, 0.0)
            q = q + DT * v
            peak = max(peak, q[0])
        assert (peak <= arm.q_upper[0] + 1e-9) == stops, peak - arm.q_upper[0]
    with pytest.raises(InvalidGain, match="recovery"):
        JointLimits(recovery=-1.0)
    with pytest.raises(InvalidGain, match="recovery has 2 entries"):
        JointLimits(qdd_max=1.0, recovery=[1.0, 2.0]).bounds(arm, DT)


def test_the_worst_weight_estimate_against_turning_the_joint() -> None:
    """``worst_weight=True``: the weight torque of a free side (an arm, the other leg) is its
    largest as the joint turns about its axis. Independent check: turn the joint over a full
    revolution on a fine grid (pinocchio's generalized gravity ``g_i`` is the weight torque of
    its subtree) and take the largest ``|g_i|``."""
    sample = pin.buildSampleModelHumanoid()
    humanoid = RobotModel(sample, name="sample", torque_limits=np.full(sample.nv - 6, 200.0))
    rng = np.random.default_rng(24)
    model = humanoid.model
    data = model.createData()
    supports = ["rleg_effector_body"]
    names = ("rarm_shoulder2_joint", "rarm_elbow_joint", "larm_shoulder1_joint",
             "lleg_elbow_joint", "lleg_shoulder2_joint")
    for _ in range(3):
        q = humanoid.random_configuration(rng)
        humanoid.update(q, np.zeros(humanoid.nv))
        A = max_acceleration_from_torques(humanoid, margin=1.0, supports=supports,
                                          worst_weight=True)
        M = pin.crba(model, data, q)
        for name in names:
            i, j = humanoid.joint_index(name), model.getJointId(name)
            iq, iv = model.joints[j].idx_q, model.joints[j].idx_v
            worst = 0.0
            for angle in np.linspace(-np.pi, np.pi, 3601):
                qa = q.copy()
                qa[iq] = angle
                worst = max(worst, abs(pin.computeGeneralizedGravity(model, data, qa)[iv]))
            expected = (humanoid.tau_max[i] - worst) / M[iv, iv]
            assert expected > 0.0
            np.testing.assert_allclose(A[i], expected, rtol=1e-5)
    # never above the estimate at the pose itself
    pose = max_acceleration_from_torques(humanoid, margin=1.0, supports=supports)
    assert np.all(A <= pose + 1e-9)
