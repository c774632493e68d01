"""Force-level primitives inside a controller step: the solution has the commanded CoP.

The paper humanoid stands on both feet; a CoP task (its own level, under the
constraints) shifts the centre of pressure 2 cm forward and 1 cm left of the
feet's centre; internal forces are driven to zero below it. The CoP of the
returned wrenches must equal the goal, and so must the ZMP computed
independently from the accelerations (Newton-Euler of the whole body from
``A_g qdd + dA_g v`` and gravity), which checks that the rows are consistent
with the physics rows they sit under.
"""

import numpy as np
import pytest

from hqp.controller import WholeBodyController
from hqp.model import RobotState
from hqp.model.layout import ContactType
from hqp.robots import load
from hqp.stack import Stack
from hqp.tasks.base import Category
from hqp.tasks.com import CoMTask, support_center
from hqp.tasks.contact import Contact
from hqp.tasks.cop import CoPTask
from hqp.tasks.dynamics import FloatingBaseDynamics
from hqp.tasks.internal_forces import InternalForcesTask
from hqp.tasks.posture import PostureTask
from hqp.tasks.torque_limits import TorqueLimits


def test_cop_and_internal_forces_in_a_controller_step() -> None:
    robot = load("paper-humanoid")
    model = robot.model()
    model.update(robot.q_standing, np.zeros(model.nv))
    stack = Stack(
        [Category.PHYSICS, Category.CONTACT_LIMITS, "cop", Category.BALANCE,
         Category.OPERATIONAL, Category.POSTURE]
    )
    stack.add(FloatingBaseDynamics())
    contacts = []
    for foot in robot.feet:
        s = robot.contact(foot)
        contacts.append(Contact(foot, s.frame, ContactType.SURFACE, mu=0.8,
                                half_length=s.half_length, half_width=s.half_width, model=model))
    stack.add(TorqueLimits(), Category.CONTACT_LIMITS)
    centre = support_center(model, list(robot.feet))
    goal = centre[:2] + np.array([0.02, 0.01])
    cop = CoPTask(model, list(robot.feet), height=0.0)
    cop.set_goal(goal)
    stack.add(cop, "cop")
    com = CoMTask(model)
    com.set_goal(model.com)
    stack.add(com)
    internal = InternalForcesTask(model, list(robot.feet))
    stack.add(internal)
    posture = PostureTask(model)
    posture.set_configuration(robot.q_standing, model)
    stack.add(posture)
    ctrl = WholeBodyController(model, contacts, stack, dt=1e-3, diagnostics="residuals")
    cmd = ctrl.step(RobotState(robot.q_standing.copy(), np.zeros(model.nv)), 0.0)
    assert not cmd.safe_mode

    layout = ctrl.layout
    # CoP of the returned wrenches (world axes at each sole origin), plane z = 0.
    F = np.zeros(3)
    tau_O = np.zeros(3)
    for foot in robot.feet:
        w = np.asarray(cmd.wrenches[foot])
        p = model.frame_placement(robot.contact(foot).frame).translation
        F += w[:3]
        tau_O += w[3:] + np.cross(p, w[:3])
    cop_wrenches = np.array([-tau_O[1], tau_O[0]]) / F[2]  # plane z = 0
    np.testing.assert_allclose(cop_wrenches, goal, atol=1e-6)
    # ZMP from the whole-body accelerations (independent of the wrench slots).
    model.update(robot.q_standing, np.zeros(model.nv))
    hdot = model.centroidal_matrix @ cmd.qdd + model.centroidal_drift
    g = model.gravity_vector
    f_ext = hdot[:3] - model.mass * g
    tau_ext = hdot[3:] + np.cross(model.com, hdot[:3]) - np.cross(model.com, model.mass * g)
    zmp = np.array([-tau_ext[1], tau_ext[0]]) / f_ext[2]
    np.testing.assert_allclose(zmp, goal, atol=1e-6)
    np.testing.assert_allclose(f_ext, F, atol=1e-6 * model.mass * 9.81)
    # Internal forces vanish (the level below the CoP has room for them).
    x = np.concatenate([cmd.qdd] + [np.asarray(cmd.wrenches[s.name]) for s in layout.contacts])
    np.testing.assert_allclose(internal.measure(model, layout, x), 0.0, atol=1e-6)
    assert cop.measure(model, layout, x) == pytest.approx(goal, abs=1e-6)
