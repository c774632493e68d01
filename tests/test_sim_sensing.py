"""The simulator's cheap reads agree with its full contact reading and with MuJoCo's own calls."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

import hqp.robots as robots
from hqp.controller import standing_controller
from hqp.sim import Push, Simulator


@pytest.mark.parametrize("contacts", ["unilateral", "welded"])
def test_feet_touching_and_normal_forces_along_a_pushed_run(contacts: str) -> None:
    """Over a pushed standing run (a foot may lift): ``state()``'s sensed contacts are the
    reading's, and the normal forces are ``mj_contactForce``'s to the last bit."""
    robot = robots.load("paper-humanoid")
    sim = Simulator(robot, contacts=contacts)
    ctrl = standing_controller(robot)
    push = Push(0.05, (0.0, 120.0, 0.0), 0.1)
    wrench = np.zeros(6)
    lifted = False
    for k in range(250):
        reading = sim.contacts()
        state = sim.state()
        assert state.contacts == dict(zip(robot.feet, reading.foot_contact.tolist()))
        np.testing.assert_array_equal(sim.feet_touching(), reading.foot_contact)
        lifted |= not reading.foot_contact.all()
        if contacts == "unilateral":
            d = sim.mj_data
            for i in range(d.ncon):
                mujoco.mj_contactForce(sim.mj_model, d, i, wrench)
                assert sim._normal_forces(d.contact, [i])[0] == wrench[0]
        force = np.asarray(push.force) if push.t <= sim.time < push.t + push.duration else None
        sim.step(ctrl.step(state, sim.time).tau, force)
    assert sim.time == pytest.approx(0.25)
    if contacts == "unilateral":
        assert lifted  # the push lifted a foot: both branches of the reading were met
