"""The standing presets and the controller registry (hqp.control.presets)."""

import numpy as np
from _servo_setup import DT

from hqp.model import RobotState


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


def test_the_registry_and_the_constraint_controllers():
    """One registry of controllers by name; the behaviors' controllers hold only constraints."""
    import pytest

    import comparisons
    import hqp.controller
    import hqp.nullspace
    from hqp import control, robots
    from hqp.control.presets import (
        CONTROLLER_NAMES,
        STANDING_TASKS,
        constraint_controller,
        make_controller,
        standing_nullspace_controller,
    )
    from hqp.errors import UnknownName
    from hqp.tasks.joint_limit_zone import JointLimitZone
    from hqp.tasks.joint_limits import JointLimits

    assert CONTROLLER_NAMES == ("hqp", "nullspace")
    assert comparisons.CONTROLLERS == (*CONTROLLER_NAMES, "placo")
    robot = robots.load("paper-humanoid")
    model = robot.model()
    with pytest.raises(UnknownName, match="hqp, nullspace"):
        make_controller("osc", model, (), None)
    hqp_c = constraint_controller("hqp", robot, max_joint_acceleration=20.0)
    law_c = constraint_controller("nullspace", robot)
    assert isinstance(law_c, control.NullSpaceController)
    for c, limits in ((hqp_c, JointLimits), (law_c, JointLimitZone)):
        tasks = c.stack.tasks
        assert not [t for t in tasks if isinstance(t, STANDING_TASKS)]
        assert [t for t in tasks if isinstance(t, limits)]
        assert c.stack.contacts == robot.feet and c.stack.ramp_time == 0.6
    jl = next(t for t in hqp_c.stack.tasks if isinstance(t, JointLimits))
    assert float(np.max(jl.qdd_max)) <= 20.0
    # the standing law: the standing stack with the zones in place of the viable limits
    law = standing_nullspace_controller(robot)
    ctrl = control.standing_controller(robot)
    names = [(ctrl.stack.level_of_task(t.name), t.name) for t in ctrl.stack.tasks]
    law_names = [(law.stack.level_of_task(t.name), t.name) for t in law.stack.tasks]
    assert [n for n in names if n[1] != "joint_limits"] == [
        n for n in law_names if n[1] != "joint_limit_zone"]
    # the names users import from the old modules are the control layer's
    for module in (hqp.controller, hqp.nullspace):
        for name in module.__all__:
            assert getattr(module, name) is getattr(control, name, getattr(
                control.presets, name, getattr(control.nullspace, name, None))), name
