import math

import numpy as np
import pytest
from _h5_standins import (
    ComStandIn,
    JointAccelStandIn,
    JointBoundStandIn,
    PostureStandIn,
    sample_humanoid,
)

from hqp.errors import HQPError, InvalidInput, InvalidLevel, UnknownName
from hqp.model.layout import ContactType, Layout
from hqp.stack import ContactMode, Stack, min_jerk
from hqp.tasks.base import Category
from hqp.tasks.contact import Contact
from hqp.tasks.dynamics import FloatingBaseDynamics


def advance_build(st, m, layout, t, x_prev):
    """One control step's use of the stack: advance to ``t``, then build."""
    st.advance(m, layout, 1e-3, t, x_prev)
    return st.build(m, layout, 1e-3, t)


def same_levels(a, b) -> bool:
    fields = ("A", "b", "C", "lower", "upper")
    return a.level_index == b.level_index and a.spans == b.spans and all(
        (getattr(la, f) is None and getattr(lb, f) is None)
        or np.array_equal(getattr(la, f), getattr(lb, f))
        for la, lb in zip(a.levels, b.levels, strict=True) for f in fields)


@pytest.fixture(scope="module")
def humanoid():
    m, q = sample_humanoid()
    m.update(q, np.zeros(m.nv))
    return m, q


def test_min_jerk_profile():
    assert min_jerk(-1.0) == 0.0 and min_jerk(0.0) == 0.0
    assert min_jerk(1.0) == 1.0 and min_jerk(2.0) == 1.0
    np.testing.assert_allclose(min_jerk(0.5), 0.5, atol=1e-15)


def test_a_ramps_kept_share_stays_in_the_unit_interval():
    """``min_jerk`` rounds above 1 just below a ramp's end (by up to 2e-15); the share of the
    offsets a ramping task keeps, which the native step checks, stays in [0, 1]."""
    fractions = np.linspace(0.999, 1.0, 200001)
    assert max(min_jerk(float(f)) for f in fractions) > 1.0  # the rounding this guards
    stack = Stack()

    class Entry:  # the two fields ramp_keep reads
        added_at, ramp_time = 0.0, 1.0

    keeps = [stack.ramp_keep(Entry(), float(f)) for f in fractions]
    assert min(keeps) >= 0.0 and max(keeps) <= 1.0


def test_default_levels_follow_categories():
    st = Stack()
    assert st.n_levels == len(Category)
    for c in Category:
        assert st.level_of(c) == int(c)
    assert st.level_of("posture") == int(Category.POSTURE)
    with pytest.raises(InvalidLevel, match="out of range"):
        st.level_of(7)
    with pytest.raises(InvalidLevel, match="unknown level"):
        st.level_of("nope")
    custom = Stack(["physics", "shared", Category.POSTURE])
    with pytest.raises(InvalidLevel, match="no level of category BALANCE"):
        custom.level_of(Category.BALANCE)
    with pytest.raises(InvalidInput):
        Stack([])
    with pytest.raises(InvalidInput):
        Stack(["a", "a"])


def test_add_remove_and_errors(humanoid):
    st = Stack()
    st.add(PostureStandIn("posture", humanoid[1]))
    with pytest.raises(InvalidInput, match="already in the stack"):
        st.add(PostureStandIn("posture", humanoid[1]))
    with pytest.raises(InvalidInput, match="expected a Task"):
        st.add("posture")  # type: ignore[arg-type]
    with pytest.raises(UnknownName, match="posture"):
        st.task("missing")
    assert st.level_of_task("posture") == int(Category.POSTURE)
    st.remove("posture", t=0.1)
    assert "posture" not in st
    events = st.pop_events()
    assert len(events) == 1 and "removed" in events[0].note and events[0].t == 0.1
    assert st.pop_events() == []


def test_build_weights_spans_and_skipped_levels(humanoid):
    m, q = humanoid
    layout = Layout.build(m.nv)
    st = Stack()
    com = ComStandIn("com", m.com[:2] + 0.01)
    posture = PostureStandIn("posture", q, weight=4.0)
    other = JointAccelStandIn("joint", 8, 0.5, weight=0.25)
    st.add(com)
    st.add(posture)
    st.add(other, Category.POSTURE)
    st.add(JointBoundStandIn("bound", 9, -1.0, 1.0))
    built = st.build(m, layout, 1e-3, 0.0)
    assert built.level_index == (int(Category.JOINT_LIMITS), int(Category.BALANCE),
                                 int(Category.POSTURE))
    assert [lv.name for lv in built.levels] == ["joint_limits", "balance", "posture"]
    sp = built.span("posture")
    sj = built.span("joint")
    assert sp.built_level == sj.built_level == 2
    assert (sp.eq.start, sp.eq.stop, sj.eq.start, sj.eq.stop) == (0, m.na, m.na, m.na + 1)
    level = built.levels[2]
    rows_p = posture.rows(m, layout, 1e-3, 0.0)
    np.testing.assert_allclose(level.A[sp.eq], 2.0 * rows_p.A, atol=0)
    np.testing.assert_allclose(level.b[sp.eq], 2.0 * rows_p.b, atol=1e-12)
    np.testing.assert_allclose(level.A[sj.eq][0, 8], 0.5, atol=0)
    np.testing.assert_allclose(built.rows["posture"].b, rows_p.b, atol=1e-12)  # unweighted
    bound = built.span("bound")
    assert bound.ineq == slice(0, 1) and bound.eq == slice(0, 0)


def test_task_ramp_starts_at_previous_solution(humanoid):
    m, q = humanoid
    layout = Layout.build(m.nv)
    st = Stack(ramp_time=0.2)
    task = ComStandIn("com", m.com[:2] + 0.05)
    bound = JointBoundStandIn("bound", 9, 2.0, 3.0)
    st.add(task, t=1.0)
    st.add(bound, t=1.0)
    rng = np.random.default_rng(0)
    x_prev = rng.normal(size=layout.n)
    x_prev[9] = 0.0  # outside [2, 3]
    full = task.rows(m, layout, 1e-3, 1.0)
    b0 = advance_build(st, m, layout, 1.0, x_prev)
    np.testing.assert_allclose(b0.rows["com"].A @ x_prev, b0.rows["com"].b, atol=1e-12)
    assert b0.span("com").ramp == 0.0
    lo, hi = b0.rows["bound"].lower[0], b0.rows["bound"].upper[0]
    assert lo <= x_prev[9] <= hi
    mid = advance_build(st, m, layout, 1.1, x_prev)
    np.testing.assert_allclose(
        mid.rows["com"].b, 0.5 * full.b + 0.5 * (full.A @ x_prev), atol=1e-12
    )
    end = advance_build(st, m, layout, 1.2, x_prev)
    np.testing.assert_allclose(end.rows["com"].b, full.b, atol=1e-12)
    assert end.rows["bound"].lower[0] == 2.0 and end.span("com").ramp == 1.0


def test_task_ramp_offset_is_frozen_so_the_task_feedback_acts(humanoid):
    # The offset A x_prev - b is taken once, at the addition: later steps use the task's own
    # target at the new state plus (1 - s) times that offset, whatever the previous solution.
    # (Pinning the target to the previous step's A x_prev would hold the task's acceleration
    # constant through the ramp and let its velocity run away.)
    m, q = humanoid
    layout = Layout.build(m.nv)
    st = Stack(ramp_time=0.2)
    task = ComStandIn("com", m.com[:2] + 0.05)
    st.add(task, t=1.0)
    rng = np.random.default_rng(1)
    x_add = rng.normal(size=layout.n)
    full0 = task.rows(m, layout, 1e-3, 1.0)
    advance_build(st, m, layout, 1.0, x_add)
    offset = full0.A @ x_add - full0.b
    v = 0.3 * rng.normal(size=m.nv)  # the robot moved: the task's damping changes its target
    m.update(q, v)
    try:
        full = task.rows(m, layout, 1e-3, 1.1)
        assert np.linalg.norm(full.b - full0.b) > 1e-2
        mid = advance_build(st, m, layout, 1.1, rng.normal(size=layout.n))  # any x_prev
        np.testing.assert_allclose(mid.rows["com"].b, full.b + 0.5 * offset, atol=1e-12)
    finally:
        m.update(q, np.zeros(m.nv))


def test_contact_unloading_then_release(humanoid):
    m, q = humanoid
    st = Stack(unload_time=0.1)
    st.add(FloatingBaseDynamics())
    right = Contact("right", "right_sole")
    left = Contact("left", "left_sole")
    st.add_contact(right)
    st.add_contact(left)
    layout = Layout.build(m.nv, st.layout_contacts())
    assert [c.name for c in layout.contacts] == ["right", "left"]
    x = np.zeros(layout.n)
    x[layout.contact("left").start + 2] = 300.0
    st.deactivate_contact("left", t=0.0)
    assert st.contact_mode("left") is ContactMode.UNLOADING
    advance_build(st, m, layout, 0.0, x)
    assert left.max_normal_force == pytest.approx(300.0)
    advance_build(st, m, layout, 0.05, x)
    assert left.max_normal_force == pytest.approx(150.0)
    assert st.active_contacts == ("right", "left")
    built = advance_build(st, m, layout, 0.1, x)
    assert st.contact_mode("left") is ContactMode.INACTIVE
    assert math.isinf(left.max_normal_force) and not left.active  # nominal bound restored
    rows = built.rows["left"]
    np.testing.assert_allclose(rows.A[:, layout.contact("left").slice], np.eye(6))
    assert [e.note for e in st.pop_events()] == ["contact 'left' released"]
    st.activate_contact("left", t=0.2)
    assert left.active and st.contact_mode("left") is ContactMode.ACTIVE
    event = st.pop_events()[0]
    assert "made" in event.note and event.contact == "left"
    # The hierarchy before the contact was made: its slot held at zero, then restored.
    with st.contact_released("left"):
        assert not left.active and st.active_contacts == ("right",)
        before = st.build(m, layout, 1e-3, 0.2)  # pure: nothing advanced inside
    assert left.active and st.contact_mode("left") is ContactMode.ACTIVE
    np.testing.assert_allclose(before.rows["left"].A[:, layout.contact("left").slice], np.eye(6))
    after = advance_build(st, m, layout, 0.2, x)
    assert np.abs(after.rows["left"].A[:, : m.nv]).max() > 0.0  # the contact condition again
    with pytest.raises(UnknownName):
        st.deactivate_contact("hand")


def test_layout_contact_must_be_declared(humanoid):
    m, _ = humanoid
    layout = Layout.build(m.nv, [("hand", "right_sole", ContactType.POINT)])
    with pytest.raises(HQPError, match="not declared"):
        Stack().build(m, layout, 1e-3, 0.0)


def test_goal_ramp_of_an_added_task_stays_within_its_pd_law():
    # An added task's goal starts at its current value and follows a minimum-jerk move; the
    # move takes at least as long as the task's own saturated PD law would (peak velocity
    # 1.875 d / T <= min(max_velocity, kp d / kv), peak acceleration 5.77 d / T^2 <=
    # min(max_acceleration, kp d)), not just the stack's ramp_time (0.1 s here).
    from hqp import robots
    from hqp.tasks.orientation import OrientationTask
    from hqp.tasks.position import PositionTask

    r = robots.load("paper-humanoid")
    m = r.model()
    m.update(r.q_standing, np.zeros(m.nv))
    layout = Layout.build(m.nv)
    p0 = m.frame_placement(r.hands[1]).translation.copy()
    hand = PositionTask(m, r.hands[1], name="hand", kp=100.0, max_velocity=0.5,
                        max_acceleration=3.0)
    hand.set_goal(p0 + np.array([0.4, 0.0, 0.0]))
    trunk = OrientationTask(m, "trunk", kp=100.0)  # critical damping kv = 20, no saturation
    R0 = m.frame_placement("trunk").rotation.copy()
    trunk.set_goal(R0 @ np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]]))
    st = Stack(ramp_time=0.1)
    st.add(hand, t=1.0)
    st.add(trunk, t=1.0)
    advance_build(st, m, layout, 1.0, None)
    ts = 1.0 + np.linspace(0.0, 2.0, 2001)
    samples = [hand.goal_at(t) for t in ts]
    np.testing.assert_allclose(samples[0].position, p0, atol=1e-12)
    speed = np.array([np.linalg.norm(s.velocity) for s in samples])
    accel = np.array([np.linalg.norm(s.acceleration) for s in samples])
    assert speed.max() <= 0.5 + 1e-9 and speed.max() > 0.49  # velocity-limited: T = 1.5 s
    assert accel.max() <= 3.0 + 1e-9
    np.testing.assert_allclose(hand.goal_at(2.5).position, p0 + [0.4, 0.0, 0.0], atol=1e-12)
    assert np.linalg.norm(hand.goal_at(2.49).position - p0 - [0.4, 0.0, 0.0]) > 0.0
    # unsaturated: T = max(1.875 kv / kp, sqrt(5.77 / kp)) = 0.375 s for a 90-degree turn
    w = [np.linalg.norm(trunk.goal_at(t).velocity) for t in ts]
    assert max(w) == pytest.approx(1.875 * (np.pi / 2) / 0.375, rel=1e-3)


def test_build_is_pure_and_idempotent(humanoid):
    # Building changes nothing: twice at the same state gives the same levels, a contact whose
    # unloading is over is only released by advance, and a ramp's offsets are only recorded
    # by advance (without them the task ramps from zero).
    m, q = humanoid
    st = Stack(unload_time=0.1, ramp_time=0.2)
    st.add(FloatingBaseDynamics())
    left = Contact("left", "left_sole")
    st.add_contact(left)
    st.add_contact(Contact("right", "right_sole"))
    layout = Layout.build(m.nv, st.layout_contacts())
    task = ComStandIn("com", m.com[:2] + 0.05)
    st.add(task, t=0.0)
    x = np.random.default_rng(2).normal(size=layout.n)
    full = task.rows(m, layout, 1e-3, 0.1)
    unramped = st.build(m, layout, 1e-3, 0.1)  # no advance: ramps from zero
    np.testing.assert_allclose(unramped.rows["com"].b, 0.5 * full.b, atol=1e-12)
    st.deactivate_contact("left", t=0.0)
    st.advance(m, layout, 1e-3, 0.0, x)
    first = st.build(m, layout, 1e-3, 0.2)
    assert same_levels(first, st.build(m, layout, 1e-3, 0.2))
    assert st.contact_mode("left") is ContactMode.UNLOADING and not st.pop_events()
    st.advance(m, layout, 1e-3, 0.2, x)
    assert st.contact_mode("left") is ContactMode.INACTIVE
    assert [e.note for e in st.pop_events()] == ["contact 'left' released"]
    built = st.build(m, layout, 1e-3, 0.2)
    assert same_levels(built, st.build(m, layout, 1e-3, 0.2)) and not st.pop_events()
