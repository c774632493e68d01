import numpy as np
import pytest
from _h5_standins import (
    ComStandIn,
    JointAccelStandIn,
    JointBoundStandIn,
    PostureStandIn,
    sample_humanoid,
)

from hqp.controller import (
    Command,
    Feasibility,
    FeasibilityReport,
    TaskStatus,
    WholeBodyController,
)
from hqp.errors import InvalidInput, SolverFailure, UnknownName
from hqp.model import RobotState
from hqp.stack import Stack
from hqp.tasks.base import Category
from hqp.tasks.contact import Contact
from hqp.tasks.dynamics import FloatingBaseDynamics

DT = 1e-3


BACKENDS = ["proxsuite", "daqp"]


def make(extra=(), posture=True, backend="proxsuite", **kwargs):
    m, q = sample_humanoid()
    m.update(q, np.zeros(m.nv))
    st = Stack(**kwargs)
    st.add(FloatingBaseDynamics())
    st.add(ComStandIn("com", m.com[:2] + np.array([0.01, 0.0])))
    if posture:
        st.add(PostureStandIn("posture", q))
    for task, level in extra:
        st.add(task, level)
    c = WholeBodyController(m, [Contact("right", "right_sole"), Contact("left", "left_sole")], st,
                            dt=DT, backend=backend)
    return c, m, q


def test_report_lookup():
    s = TaskStatus("a", 3, Feasibility.CONFLICT, 0.5, 2, 0.1)
    r = FeasibilityReport(tasks=(s,))
    assert r["a"] is s and "a" in r and "b" not in r
    assert not r.feasible and r.conflicts() == [s] and r.singular() == []
    with pytest.raises(UnknownName, match="valid tasks: a"):
        r["b"]


def test_step_satisfies_equation_of_motion_and_limits():
    c, m, q = make()
    v = np.random.default_rng(1).normal(scale=0.1, size=m.nv)
    cmd = c.step(RobotState(q, v), 0.0)
    assert isinstance(cmd, Command) and not cmd.safe_mode
    assert cmd.tau.shape == (m.na,) and cmd.qdd.shape == (m.nv,)
    assert np.all(np.isfinite(cmd.tau))
    m.update(q, v)
    gen = m.M @ cmd.qdd + m.h
    for name, frame in (("right", "right_sole"), ("left", "left_sole")):
        gen -= m.frame_jacobian(frame).T @ cmd.wrenches[name]
    np.testing.assert_allclose(gen[:6], 0.0, atol=1e-6)  # unactuated rows
    np.testing.assert_allclose(gen[6:], cmd.tau, atol=1e-6)  # torques from x
    for name in ("right", "left"):
        assert cmd.wrenches[name][2] >= -1e-6  # unilateral
    assert cmd.report["dynamics"].status is Feasibility.SATISFIED
    assert cmd.report["com"].status is Feasibility.SATISFIED
    assert cmd.report["posture"].status is Feasibility.CONFLICT
    assert cmd.report["posture"].yields_to == 0  # the feet hold the legs (physics level)
    assert set(cmd.timings) >= {"update", "rows", "solve", "total"}


def test_conflicting_task_is_reported_and_leaves_higher_level_unchanged():
    # Without and with a lower task asking for another centre-of-mass acceleration.
    c0, m, q = make(posture=False)
    state = RobotState(q, np.zeros(m.nv))
    ref = c0.step(state, 0.0)
    rival = ComStandIn("rival", m.com[:2] + np.array([-0.05, 0.02]))
    c1, _, _ = make(extra=[(rival, Category.OPERATIONAL)], posture=False)
    cmd = c1.step(state, 0.0)
    st = cmd.report["rival"]
    assert st.status is Feasibility.CONFLICT
    assert st.yields_to == int(Category.BALANCE)
    assert st.residual > 1.0
    np.testing.assert_allclose(cmd.report["com"].residual, ref.report["com"].residual, atol=1e-6)
    m.update(q, np.zeros(m.nv))
    np.testing.assert_allclose(m.com_jacobian[:2] @ cmd.qdd, m.com_jacobian[:2] @ ref.qdd,
                               atol=1e-6)


def test_conflict_with_an_inequality_level_names_it():
    bound = JointBoundStandIn("bound", 10, -1.0, 1.0)
    push = JointAccelStandIn("push", 10, 5.0)
    c, m, q = make(extra=[(bound, Category.JOINT_LIMITS), (push, Category.OPERATIONAL)])
    cmd = c.step(RobotState(q, np.zeros(m.nv)), 0.0)
    st = cmd.report["push"]
    assert st.status is Feasibility.CONFLICT and st.yields_to == int(Category.JOINT_LIMITS)
    np.testing.assert_allclose(st.residual, 4.0, atol=1e-5)
    np.testing.assert_allclose(cmd.qdd[10], 1.0, atol=1e-6)


def test_redundant_task_is_singular():
    first = JointAccelStandIn("first", 10, 0.3)
    again = JointAccelStandIn("again", 10, 0.3)
    c, m, q = make(extra=[(first, Category.OPERATIONAL), (again, Category.POSTURE)],
                   posture=False)
    cmd = c.step(RobotState(q, np.zeros(m.nv)), 0.0)
    assert cmd.report["first"].status is Feasibility.SATISFIED
    assert cmd.report["first"].sigma_min > 0.1
    assert cmd.report["again"].status is Feasibility.SINGULAR
    assert cmd.report["again"].sigma_min < 1e-8


@pytest.mark.parametrize("failure", ["raise", "nan"])
def test_safe_mode_when_the_solve_fails(failure, monkeypatch):
    c, m, q = make()
    state = RobotState(q, np.full(m.nv, 0.1))
    good = c.step(state, 0.0)
    real = c.solver.solve

    def broken(levels, **kwargs):
        if failure == "raise":
            raise SolverFailure("backend diverged")
        sol = real(levels, **kwargs)
        sol.x[:] = np.nan
        return sol

    monkeypatch.setattr(c.solver, "solve", broken)
    # First the fallback backend takes over: same command as the primary's, reported.
    backup = c.step(state, DT)
    assert not backup.safe_mode
    assert any("solved again with backend" in n for n in backup.report.notes)
    np.testing.assert_allclose(backup.tau, good.tau, atol=1e-5 * np.abs(good.tau).max())
    # With the fallback failing too, the safe command is sent.
    monkeypatch.setattr(c.resolver.fallback(), "solve", broken)
    cmd = c.step(state, DT)
    assert cmd.safe_mode and cmd.report.safe_mode and not cmd.report.feasible
    assert np.all(np.isfinite(cmd.tau)) and np.all(np.abs(cmd.tau) <= m.tau_max)
    assert any("safe mode" in n for n in cmd.report.notes)
    # The safe command balances gravity through the contacts (quasi-static), with damping.
    m.update(q, state.v)
    gen = m.gravity.copy()
    for name, frame in (("right", "right_sole"), ("left", "left_sole")):
        gen -= m.frame_jacobian(frame).T @ cmd.wrenches[name]
    np.testing.assert_allclose(gen[:6], 0.0, atol=1e-6)
    np.testing.assert_allclose(gen[6:] - c.damping * state.v[6:], cmd.tau, atol=1e-6)
    assert np.linalg.norm(cmd.tau - good.tau) < np.linalg.norm(good.tau)  # same ballpark


def test_non_finite_task_rows_give_the_safe_command():
    # Stack-built levels skip the solver's input validation (validate=False); the controller
    # still checks their finiteness, so a task whose goal went NaN never reaches the QP.
    bad = JointAccelStandIn("bad", 10, np.nan)
    c, m, q = make(extra=[(bad, Category.OPERATIONAL)])
    cmd = c.step(RobotState(q, np.zeros(m.nv)), 0.0)
    assert cmd.safe_mode and np.all(np.isfinite(cmd.tau))
    assert any("non-finite task rows" in n for n in cmd.report.notes)


@pytest.mark.parametrize("backend", BACKENDS)
def test_added_task_is_ramped_in(backend):
    jumps = {}
    for ramp in (0.0, 0.2):
        c, m, q = make(backend=backend)
        state = RobotState(q, np.zeros(m.nv))
        for i in range(3):
            before = c.step(state, i * DT)
        c.add_task(JointAccelStandIn("new", 10, 50.0), Category.OPERATIONAL, ramp_time=ramp)
        after = c.step(state, 3 * DT)
        jumps[ramp] = np.abs(after.tau - before.tau).max()
    assert jumps[0.0] > 1.0  # the unramped task jumps
    assert jumps[0.2] < 1e-2  # the ramped one starts at the previous solution


def test_removed_task_is_blended_and_flagged():
    c, m, q = make(blend_time=0.05)
    state = RobotState(q, np.zeros(m.nv))
    for i in range(3):
        before = c.step(state, i * DT)
    c.remove_task("com")
    after = c.step(state, 3 * DT)
    assert after.report.strictness_suspended
    assert any("removed" in n for n in after.report.notes)
    assert np.abs(after.tau - before.tau).max() < 1e-9
    t = 3 * DT
    while True:
        t += DT
        cmd = c.step(state, t)
        if not cmd.report.strictness_suspended:
            break
    assert t == pytest.approx(3 * DT + 0.05, abs=1.5 * DT)


@pytest.mark.parametrize("backend", BACKENDS)
def test_contact_unloading_and_release(backend):
    # Static state: the left sole's normal force follows the min-jerk ramp to zero over 20 ms,
    # torques move by less than 5 N m per 1 ms step, and the release is blended over 10 ms.
    c, m, q = make(unload_time=0.02, blend_time=0.01, backend=backend)
    state = RobotState(q, np.zeros(m.nv))
    f0 = c.step(state, 0.0).wrenches["left"][2]
    assert f0 > 50.0
    c.deactivate_contact("left", t=0.0)
    t, prev = 0.0, None
    normals = []
    while t < 0.04:
        t += DT
        cmd = c.step(state, t)
        normals.append(cmd.wrenches["left"][2])
        if prev is not None:
            assert np.abs(cmd.tau - prev).max() < 5.0
        prev = cmd.tau
    assert normals[10] < 0.6 * f0  # half-way through the unloading ramp
    np.testing.assert_allclose(normals[-1], 0.0, atol=1e-8)
    assert c.active_contacts == ("right",)


@pytest.mark.parametrize("backend", BACKENDS)
def test_contact_made_is_blended_between_the_two_hierarchies(backend):
    # Static state, left sole released: making it again starts from the torques of the
    # hierarchy without it (continuous), ends on the one with it, and the torques in between
    # are (1 - s) tau_without + s tau_with, flagged as strictness suspended, over 20 ms.
    c, m, q = make(unload_time=0.0, blend_time=0.02, backend=backend)
    state = RobotState(q, np.zeros(m.nv))
    c.deactivate_contact("left", t=0.0, unload_time=0.0)
    t = 0.0
    for _ in range(30):  # past the release blend
        t += DT
        before = c.step(state, t)
    assert not before.report.strictness_suspended and c.active_contacts == ("right",)
    ref, mr, _ = make(backend=backend)  # the same stack with both contacts made throughout
    ref_tau = ref.step(state, 0.0).tau
    c.activate_contact("left", t=t + DT)
    taus, flags = [], []
    for _ in range(25):
        t += DT
        cmd = c.step(state, t)
        taus.append(cmd.tau)
        flags.append(cmd.report.strictness_suspended)
    np.testing.assert_allclose(taus[0], before.tau, atol=1e-6)  # s = 0: no jump
    assert flags[:20] == [True] * 20 and not any(flags[21:])
    np.testing.assert_allclose(taus[-1], ref_tau, atol=1e-5)  # the hierarchy with the contact
    s = 0.5  # min-jerk at half the blend time
    np.testing.assert_allclose(taus[10], (1 - s) * before.tau + s * ref_tau, atol=1e-5)
    assert np.abs(np.diff(taus, axis=0)).max() < 0.1 * np.abs(ref_tau - before.tau).max()


def test_bad_arguments():
    m, q = sample_humanoid()
    with pytest.raises(InvalidInput, match="dt"):
        WholeBodyController(m, dt=0.0)
    with pytest.raises(InvalidInput, match="diagnostics"):
        WholeBodyController(m, diagnostics="all")
    c = WholeBodyController(m)
    with pytest.raises(InvalidInput):
        c.step(RobotState(q[:-1], np.zeros(m.nv)), 0.0)


def test_joint_limit_braking_follows_the_contacts_of_the_standing_stack():
    """paper-humanoid: the knees brake the body about the soles while a foot holds (a few
    rad/s^2, in single support too: all-or-none), the shanks alone with no contact (half the
    acceleration bound)."""
    from hqp import robots
    from hqp.controller import standing_controller
    from hqp.tasks.joint_limits import JointLimits

    robot = robots.load("paper-humanoid")
    c = standing_controller(robot, diagnostics="residuals")
    limits = next(t for t in c.stack.tasks if isinstance(t, JointLimits))
    m = c.model
    left, right = m.joint_index("left_knee"), m.joint_index("right_knee")
    state = RobotState(robot.q_standing, np.zeros(m.nv))
    c.step(state, 0.0)
    both = limits.braking_deceleration(m)
    assert both[left] < 10.0 and both[right] < 10.0
    c.deactivate_contact("left_foot", t=0.0, unload_time=0.0)
    c.step(state, DT)
    np.testing.assert_allclose(limits.braking_deceleration(m), both)  # single support
    c.deactivate_contact("right_foot", t=DT, unload_time=0.0)
    c.step(state, 1.5 * DT)
    none = limits.braking_deceleration(m)
    np.testing.assert_allclose(none[[left, right]],
                               0.5 * limits.max_acceleration(m)[[left, right]])
    assert none[left] > 2.0 * both[left]
    c.activate_contact("left_foot", t=2 * DT)
    c.step(state, 2 * DT)  # starts the torque blend, which also builds without the contact
    c.step(state, 3 * DT + c.stack.blend_time)  # ends the blend
    c.step(state, 4 * DT + c.stack.blend_time)
    np.testing.assert_allclose(limits.braking_deceleration(m), both)
