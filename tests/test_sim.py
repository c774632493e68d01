"""MuJoCo execution: simulator unit tests, and closed-loop runs of the HQP controller (slow)."""

import numpy as np
import pytest

import hqp.robots as robots
from hqp.control.servo import MAX_TORQUE_RATE
from hqp.controller import Feasibility, WholeBodyController, standing_controller, standing_stack
from hqp.errors import InvalidInput
from hqp.model import RobotModel, RobotState
from hqp.sim import (
    Event,
    Noise,
    Push,
    RenderUnavailable,
    Simulator,
    inside_polygon,
    render_png,
    rendering_available,
    simulate,
)
from hqp.sim.simulator import SEAT_DEPTH
from hqp.tasks.base import Category
from hqp.tasks.pose import PoseTask
from hqp.tasks.position import PositionTask

PAPER = "paper-humanoid"


def load(name):
    try:
        return robots.load(name)
    except (ImportError, FileNotFoundError) as exc:  # robot files not bundled here
        pytest.skip(f"robot {name!r} unavailable: {exc}")


# -- simulator ------------------------------------------------------------------------------


def test_inside_polygon():
    square = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0], [0.5, 0.5]])
    np.testing.assert_allclose(inside_polygon(np.array([0.5, 0.5]), square), 0.5, atol=1e-12)
    np.testing.assert_allclose(inside_polygon(np.array([0.9, 0.3]), square), 0.1, atol=1e-12)
    np.testing.assert_allclose(inside_polygon(np.array([1.2, 0.5]), square), -0.2, atol=1e-12)


def test_simulator_state_round_trip_and_sensing():
    r = robots.load(PAPER)
    sim = Simulator(r)
    assert sim.dt == 1e-3 and sim.mj_model.opt.timestep == 1e-3
    rng = np.random.default_rng(0)
    q = r.q_standing.copy()
    q[7:] += rng.uniform(-0.05, 0.05, q.size - 7)
    v = rng.normal(scale=0.1, size=sim.nv)
    sim.set_state(q, v)
    st = sim.state()
    np.testing.assert_allclose(st.q, q, atol=1e-12)
    np.testing.assert_allclose(st.v, v, atol=1e-12)
    sim.reset()
    # seated: both soles touch the floor from the first step (round-off used to leave one
    # sole 1e-17 m above it, without contact)
    np.testing.assert_allclose(sim.contacts().foot_position[:, 2], -SEAT_DEPTH, atol=1e-6)
    assert sim.contacts().foot_contact.all()
    for _ in range(5):
        sim.step(np.zeros(sim.na))
    reading = sim.contacts()
    assert reading.foot_contact.all() and reading.other_contact == ()
    np.testing.assert_allclose(reading.normal_force.sum(), r.model().mass * 9.81, rtol=0.5)
    assert not sim.fallen()
    corners = sim.sole_corners()
    assert corners.shape == (2, 4, 3)
    assert inside_polygon(sim.com()[:2], corners.reshape(-1, 3)[:, :2]) > 0.02


def test_torques_beyond_limits_are_counted_not_hidden():
    r = robots.load(PAPER)
    sim = Simulator(r)
    tau = np.zeros(sim.na)
    assert sim.apply(tau) == 0 and sim.clip_count == 0
    tau[0] = 2.0 * sim.torque_limits[0]
    tau[3] = -3.0 * sim.torque_limits[3]
    assert sim.apply(tau) == 2 and sim.clip_count == 2
    applied = sim.converter.tau_from_ctrl(sim.mj_data.ctrl)
    np.testing.assert_allclose(applied[[0, 3]], [sim.torque_limits[0], -sim.torque_limits[3]])
    with pytest.raises(InvalidInput):
        sim.apply(np.full(sim.na, np.nan))


def test_passive_robot_falls_and_is_detected():
    r = robots.load(PAPER)

    class Limp:
        dt = 1e-3

        def __init__(self, na):
            self.na = na
            from hqp.stack import Stack

            self.stack = Stack()

        def step(self, state, t):
            from hqp.controller import Command, FeasibilityReport

            return Command(np.zeros(self.na), np.zeros(self.na + 6), {}, FeasibilityReport())

    # limp, the robot folds symmetrically onto MuJoCo's joint stops (pelvis ~0.57 m, above
    # the fall height); a 10 N s push topples it
    log = simulate(r, Limp(r.model().na), 3.0, [Push(0.1, (100.0, 0.0, 0.0), 0.1)])
    assert log.fell and log.fell_at < 3.0
    assert log.t[-1] == pytest.approx(log.fell_at)


def test_render_png(tmp_path):
    ok, message = rendering_available()
    if not ok:
        with pytest.raises(RenderUnavailable):
            render_png(Simulator(robots.load(PAPER)), tmp_path / "x.png")
        pytest.skip(message)
    path = render_png(Simulator(robots.load(PAPER)), tmp_path / "stand.png", width=160,
                      height=120)
    import matplotlib.pyplot as plt

    image = plt.imread(path)
    assert image.shape[:2] == (120, 160) and image.std() > 0.01


# -- controller on the real robot, one step ------------------------------------------------


def test_conflicting_task_is_reported_and_leaves_the_higher_one_unchanged():
    # A second centre-of-mass task at the operational level asks for another horizontal
    # acceleration than the balance level's: it yields to the balance level, whose residual and
    # centre-of-mass acceleration do not change (1e-6).
    from hqp.tasks.com import CoMTask

    r = robots.load(PAPER)
    state = RobotState(r.q_standing, np.zeros(r.model().nv))
    ref = standing_controller(r).step(state, 0.0)
    c = standing_controller(r)
    rival = CoMTask(c.model, horizontal=True, name="rival")
    rival.set_goal(c.task("com").goal_at(0.0).position[:2] + np.array([0.05, -0.03]))
    c.add_task(rival, Category.OPERATIONAL, ramp_time=0.0)  # no ramp: the full conflict now
    cmd = c.step(state, 0.0)
    st = cmd.report["rival"]
    assert st.status is Feasibility.CONFLICT and st.residual > 1.0
    assert st.yields_to == int(Category.BALANCE)
    assert cmd.report["com"].status is Feasibility.SATISFIED
    np.testing.assert_allclose(cmd.report["com"].residual, ref.report["com"].residual, atol=1e-6)
    c.model.update(state.q, state.v)
    np.testing.assert_allclose(c.model.com_jacobian @ cmd.qdd, c.model.com_jacobian @ ref.qdd,
                               atol=1e-6)


# -- closed loop (slow) ---------------------------------------------------------------------


def standing_checks(log, slip=1e-3, settle=0.05):
    # The robot starts exactly on the floor: the soft contacts engage during the first
    # milliseconds (a sole sinks about 1 mm and may shift by under 1 mm while it lands), so
    # contact, slip, lift and support figures are taken from `settle` on.
    summary = log.summary(settle)
    assert not log.fell, summary
    assert log.clip_count == 0, summary
    assert summary["safe_mode_steps"] == 0, summary
    assert summary["feet_always_in_contact"], summary
    assert summary["min_support_margin_m"] > 0.0, summary  # CoM inside the support polygon
    assert summary["max_foot_slip_m"] < slip, summary
    assert summary["max_foot_lift_m"] < 1e-3, summary
    return summary


@pytest.mark.slow
def test_paper_humanoid_stands_10s():
    r = robots.load(PAPER)
    log = simulate(r, standing_controller(r, diagnostics="residuals"), 10.0)
    s = standing_checks(log)
    assert s["duration_s"] > 9.9


@pytest.mark.slow
@pytest.mark.parametrize("name", ["g1", "talos"])
def test_real_robots_stand(name):
    r = load(name)
    log = simulate(r, standing_controller(r, diagnostics="residuals"), 1.0)
    standing_checks(log)


@pytest.mark.slow
def test_unreachable_hand_goal_never_drives_a_joint_past_its_limit():
    # The viable joint limits of standing_stack brake the leg joints with what the support
    # allows (about 1 rad/s^2 at the ankles, not the fixed-base 50 rad/s^2), so the ankles and
    # the torso start braking early enough; measured excess about 1e-4 rad (threshold 1e-3).
    r = robots.load(PAPER)
    full = r.model()
    lo, hi = full.q_lower.copy(), full.q_upper.copy()
    # Narrow the controller's elbow and shoulder ranges so the reach hits them; MuJoCo keeps
    # the robot's own (wider) ranges.
    arm = [full.joint_index(n) for n in full.joint_names if n.startswith("right_")
           and ("elbow" in n or "shoulder" in n)]
    q0 = r.q_standing[7:][arm]
    lo[arm] = np.maximum(lo[arm], q0 - 0.3)
    hi[arm] = np.minimum(hi[arm], q0 + 0.3)
    assert np.all((lo[arm] < q0) & (q0 < hi[arm]))  # the robot starts inside the narrowed ranges
    model = RobotModel(r.pinocchio_model(), name=r.name, position_limits=(lo, hi),
                       velocity_limits=full.v_max, torque_limits=full.tau_max)
    stack, contacts = standing_stack(r, model)
    c = WholeBodyController(model, contacts, stack, diagnostics="residuals")
    hand = PositionTask(model, r.hands[1], name="hand", kp=50.0, max_velocity=1.0)
    hand.set_goal(np.array([0.8, -1.2, 0.1]))
    c.add_task(hand, Category.OPERATIONAL)
    sim = Simulator(r)
    jid = [sim.mj_model.joint(n).id for n in model.joint_names]
    mj_lo, mj_hi = sim.mj_model.jnt_range[jid].T
    limited = sim.mj_model.jnt_limited[jid].astype(bool)
    assert np.all(~limited[arm] | ((mj_lo[arm] < lo[arm] - 0.1) & (mj_hi[arm] > hi[arm] + 0.1)))
    log = simulate(r, c, 1.5, sim=sim)
    qa = log.q[:, 7:]
    excess = np.maximum(qa - hi, 0.0) + np.maximum(lo - qa, 0.0)
    assert excess.max() < 1e-3, (excess.max(), np.array(model.joint_names)[excess.max(0) > 0])
    assert not log.fell and log.clip_count == 0
    reached = np.isclose(qa[-1, arm], lo[arm], atol=0.02) | np.isclose(qa[-1, arm], hi[arm],
                                                                        atol=0.02)
    assert reached.any()  # the test does push the arm to its limits
    assert "conflict" in log.status["hand"][-100:]


def _weight_shift_setup(**options):
    """Standing controller, a hand task to add, the CoM goal over the right foot."""
    r = robots.load(PAPER)
    c = standing_controller(r, diagnostics="residuals", **options)
    model = c.model
    hand = PositionTask(model, r.hands[1], name="hand", kp=30.0)
    model.update(r.q_standing, np.zeros(model.nv))
    hand.set_goal(model.frame_placement(r.hands[1]).translation + np.array([0.1, 0.0, 0.15]))
    right = model.frame_placement(r.feet[1]).translation
    com = c.task("com")

    def shift(duration):
        def action(sim, ctrl, t):
            goal = np.array([right[0], right[1] * 0.7, com.goal_at(t).position[2]])
            com.move_to(ctrl.model, goal, duration, t)
        return action

    return r, c, hand, shift


def _jumps(log, bounds):
    """Largest per-step torque change [N m] in each interval between consecutive bounds."""
    jumps = np.abs(np.diff(log.tau, axis=0)).max(axis=1)
    t = log.t[1:]
    return [float(jumps[(t >= a) & (t < b)].max()) for a, b in zip(bounds[:-1], bounds[1:])]


@pytest.mark.slow
def test_adding_removing_a_task_and_a_contact_keeps_torques_continuous():
    # A task added then removed; the weight shifted onto the right foot (5.5 cm in 0.8 s:
    # a centre of pressure the support allows); the left foot unloaded (0.2 s), released,
    # lifted 5 mm and put down by a foot pose task added when unloading starts, and the
    # contact made again. Measured per-step jumps [N m] (1 ms steps): add hand 0.09, remove
    # hand 0.17, shift 0.41, unload 0.54, lift/lower 0.14, re-contact 1.74; the released foot
    # bears at most 0.4 N.
    r, c, hand, shift = _weight_shift_setup()
    model = c.model
    left0 = model.frame_placement(r.feet[0]).copy()
    lifted = left0.copy()
    lifted.translation = left0.translation + np.array([0.0, 0.0, 0.005])
    foot = PoseTask(model, r.feet[0], name="left_foot_pose", kp=100.0)

    def unload(sim, ctrl, t):
        foot.set_goal(ctrl.model.frame_placement(r.feet[0]))
        ctrl.add_task(foot, Category.OPERATIONAL, t=t)
        ctrl.deactivate_contact(r.feet[0], t=t, unload_time=0.2)

    def contact_again(sim, ctrl, t):
        ctrl.activate_contact(r.feet[0], t=t)
        ctrl.remove_task("left_foot_pose", t=t)

    events = [
        Event(0.05, lambda s, k, t: k.add_task(hand, Category.OPERATIONAL, t=t), "add hand"),
        Event(0.35, lambda s, k, t: k.remove_task("hand", t=t), "remove hand"),
        Event(0.40, shift(0.8), "CoM over the right foot"),
        Event(1.20, unload, "unload left foot"),
        Event(1.45, lambda s, k, t: foot.move_to(k.model, lifted, 0.2, t), "lift"),
        Event(1.70, lambda s, k, t: foot.move_to(k.model, left0, 0.2, t), "put down"),
        Event(1.95, contact_again, "left foot again"),
    ]
    log = simulate(r, c, 2.1, events)
    assert [name for _, name in log.events] == [e.name for e in events]
    assert not log.fell and log.clip_count == 0 and not log.safe_mode.any()
    assert log.strictness_suspended.any()  # the removals and the new contact were blended
    jumps = _jumps(log, [0.0, 0.05, 0.35, 0.40, 1.20, 1.45, 1.95, 2.1])
    assert max(jumps) < 5.0, jumps  # stated bound: 5 N m per 1 ms step
    released = (log.t > 1.41) & (log.t < 1.95)
    assert np.all(log.normal_force[released, 0] < 1.0)  # [N] the left foot is off the floor
    assert np.all(log.normal_force[log.t > 2.05, 0] > 100.0)  # and bears weight again


@pytest.mark.slow
def test_torques_stay_continuous_while_the_balance_level_is_in_conflict():
    # The shift asks 5.5 cm in 0.4 s (min-jerk peak 2.0 m/s^2, a centre of pressure 19 cm
    # beside the CoM where the support polygon reaches 12 cm): the balance level is in
    # conflict, the arms and the trunk reach their acceleration bounds and the bounds switch
    # from step to step. Before the torque-rate level and the approach to the braking curve
    # the torques jumped by up to 45 N m per step (24 N m with the rate level alone: the left
    # shoulder reaching its braking curve at 25 rad/s^2; 105 N m with the approach alone).
    r, c, hand, shift = _weight_shift_setup(max_torque_rate=MAX_TORQUE_RATE,
                                            braking_approach_time=0.02)
    log = simulate(r, c, 0.9, [Event(0.10, shift(0.4), "CoM over the right foot, too fast")])
    assert not log.fell and log.clip_count == 0 and not log.safe_mode.any()
    assert "conflict" in log.status["com"]  # the shift is infeasible: balance in conflict
    assert max(_jumps(log, [0.0, 0.9])) < 5.0


@pytest.mark.slow
def test_standing_survives_noise_delay_and_a_push():
    r = robots.load(PAPER)
    c = standing_controller(r, diagnostics="residuals")
    noise = Noise(q_std=2e-4, v_std=5e-3, seed=1)
    log = simulate(r, c, 1.5, [Push(0.5, (60.0, 0.0, 0.0), 0.1)], noise=noise, delay_steps=1)
    summary = log.summary()
    assert not log.fell and log.clip_count == 0 and not log.safe_mode.any(), summary
    assert summary["min_support_margin_m"] > 0.0, summary


def _pushed(force, angle_deg):
    # one simulation of the push-recovery study, its defaults (5 s runs, a 0.1 s push at 0.3 s)
    from hqp.study.simulation import run_simulation

    return run_simulation({"controller": "hqp", "push_force": force,
                           "push_angle_deg": angle_deg})["metrics"]


@pytest.mark.slow
@pytest.mark.parametrize("force,angle", [(275.0, 0.0), (325.0, 90.0)],
                         ids=["forward-275N", "lateral-325N"])
def test_standing_survives_pushes_below_the_band_where_survival_is_chaotic(force, angle):
    # Between about 287 N and 375 N forward (350 N and 375 N lateral) survival is not a
    # function of the force: it flips with rounding (5 s runs, 0.1 s pushes at 0.3 s; the same
    # code and packages on another CPU, or an extra module imported before the run, turn a
    # survival into a slow fall and back; forward 312.5 N falls at 3.65 s where 325 N and
    # 337.5 N survive; 1e-4 rad of initial joint noise, seeds 0-3, makes 287.5 N, 325 N forward
    # and 350 N, 362.5 N lateral fall in one or two runs of four), so a bisection's "largest
    # survived" is one sample of that band (docs/results/push-recovery.md). Below it every run
    # survived: 275 N forward and 325 N lateral, unperturbed and in 4 seeds each.
    m = _pushed(force, angle)
    assert not m["fell"] and m["clip_count"] == 0 and m["safe_mode_steps"] == 0, m


@pytest.mark.slow
def test_a_two_second_window_misses_a_slow_fall():
    # Why the push-recovery study's runs last 5 s: inside the chaotic band (above) a pushed
    # robot can stand for seconds and then fall (312.5 N forward fell at 3.65 s on one machine,
    # 337.5 N at 2.17 s on another). Which force of the band does so depends on
    # rounding, so this looks for one among four and stops at the first.
    falls = []
    for force in (312.5, 325.0, 337.5, 350.0):
        m = _pushed(force, 0.0)
        falls.append((force, m["fell_at_s"]))
        if m["fell"] and 2.0 < m["fell_at_s"] < 5.0:
            return
    pytest.fail(f"no push of the band fell after 2 s: {falls}")
