"""The per-task feasibility report (hqp.control.diagnostics): conflicts and singularities."""

import numpy as np
from _h5_standins import (
    ComStandIn,
    JointAccelStandIn,
    JointBoundStandIn,
)
from _servo_setup import make

from hqp.controller import (
    Feasibility,
)
from hqp.model import RobotState
from hqp.tasks.base import Category


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
