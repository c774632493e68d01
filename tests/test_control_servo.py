"""The servo (hqp.control.servo): one control step, safe command, ramps and blends."""

import numpy as np
import pytest
from _h5_standins import (
    JointAccelStandIn,
    sample_humanoid,
)
from _servo_setup import DT, make

from hqp.controller import (
    Command,
    Feasibility,
    WholeBodyController,
)
from hqp.errors import InvalidInput, SolverFailure
from hqp.model import RobotState
from hqp.tasks.base import Category

BACKENDS = ["proxsuite", "daqp"]


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
    safe_tau = c.safe_command()[0]
    np.testing.assert_allclose(gen[6:] - c.damping * state.v[6:], safe_tau, atol=1e-6)
    assert np.linalg.norm(safe_tau - good.tau) < np.linalg.norm(good.tau)  # same ballpark
    # It is blended in from the torques sent last (no torque step), then sent as it is.
    np.testing.assert_allclose(cmd.tau, backup.tau, atol=1e-9)
    assert cmd.report.strictness_suspended
    t = DT
    while t < DT + c.stack.blend_time:
        t += DT
        cmd = c.step(state, t)
        assert cmd.safe_mode
    assert not cmd.report.strictness_suspended
    np.testing.assert_allclose(cmd.tau, c.safe_command()[0], atol=1e-9)


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


def test_the_torque_rate_level_spreads_a_torque_step():
    """An unramped task (a torque step of several N m) with the servo's torque-rate level:
    every step changes the torques by at most ``max_torque_rate * dt``, the level is reported,
    and the torques reach those of the hierarchy without the level once it is satisfied."""
    rate = 5000.0  # [N m/s]: 5 N m per 1 ms step
    runs = {}
    for limited in (False, True):
        c, m, q = make()
        if limited:
            c.max_torque_rate = np.full(m.na, rate)
        state = RobotState(q, np.zeros(m.nv))
        taus = [c.step(state, i * DT).tau for i in range(3)]
        c.add_task(JointAccelStandIn("new", 10, 50.0), Category.OPERATIONAL, ramp_time=0.0)
        for i in range(3, 100):
            cmd = c.step(state, i * DT)
            taus.append(cmd.tau)
        runs[limited] = (np.array(taus), cmd)
    free, limited = runs[False][0], runs[True][0]
    assert np.abs(np.diff(free, axis=0)).max() > 5 * rate * DT  # the step the level spreads
    assert np.abs(np.diff(limited, axis=0)).max() <= rate * DT * (1 + 1e-6)
    assert "torque_rate" in runs[True][1].report and "torque_rate" not in runs[False][1].report
    assert runs[True][1].report["torque_rate"].status is Feasibility.SATISFIED
    np.testing.assert_allclose(limited[-1], free[-1], atol=1e-6 * np.abs(free[-1]).max())
