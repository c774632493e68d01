"""The simulator's ``welded`` contact mode (the seed papers' rigid feet) and its wrenches."""

from __future__ import annotations

import numpy as np
import pytest

from hqp.control.presets import standing_controller
from hqp.errors import InvalidInput
from hqp.robots import load
from hqp.sim.run import simulate
from hqp.sim.simulator import CONTACT_MODES, Simulator


def test_unknown_contact_mode_is_refused():
    with pytest.raises(InvalidInput, match="contacts must be one of"):
        Simulator(load("paper-humanoid"), contacts="glued")
    assert CONTACT_MODES[0] == "unilateral"


@pytest.mark.parametrize("mode", CONTACT_MODES)
def test_standing_wrenches_carry_the_weight_in_both_modes(mode):
    robot = load("paper-humanoid")
    sim = Simulator(robot, contacts=mode)
    log = simulate(robot, standing_controller(robot), 0.3, sim=sim)
    assert not log.fell
    w = sim.foot_wrenches()
    weight = float(robot.mujoco_model().body_subtreemass[1]) * 9.81
    np.testing.assert_allclose(w[:, 2].sum(), weight, rtol=1e-3)
    np.testing.assert_allclose(log.normal_force[-1], w[:, 2], rtol=1e-3)
    cop = sim.sole_cops(w)
    assert np.all(np.abs(cop) < 0.01)  # centred under each sole [m]
    assert log.foot_slip(0.05).max() < 1e-6


def test_welded_feet_pull_on_the_floor_where_contacts_would_let_go():
    """Zero torques and the pelvis lifted by twice the weight: the welds hold the soles
    (within 2 mm) by pulling on them; unilateral feet leave the floor."""
    robot = load("paper-humanoid")
    weight = float(robot.mujoco_model().body_subtreemass[1]) * 9.81
    lift = np.array([0.0, 0.0, 2.0 * weight])
    welded, free = Simulator(robot, contacts="welded"), Simulator(robot)
    start = welded.contacts().foot_position.copy()
    for _ in range(100):
        welded.step(np.zeros(welded.na), lift)
        free.step(np.zeros(free.na), lift)
    moved = np.linalg.norm(welded.contacts().foot_position - start, axis=1)
    assert moved.max() < 2e-3
    assert welded.foot_wrenches()[:, 2].sum() < -0.5 * weight  # no floor pulls like that
    assert welded.contacts().foot_contact.all()
    assert np.isnan(welded.sole_cops()).all()  # no centre of pressure of a pull
    assert not free.contacts().foot_contact.any()


def test_unilateral_default_is_unchanged():
    """The default model has no equality and the feet collide with the floor."""
    robot = load("paper-humanoid")
    sim = Simulator(robot)
    assert sim.contact_mode == "unilateral" and sim.mj_model.neq == 0
    welded = Simulator(robot, contacts="welded")
    assert welded.mj_model.neq == len(robot.feet)


def test_welds_hold_rotated_feet_where_they_are():
    """The weld's relative pose is the feet's own (a wrong convention snaps them elsewhere)."""
    import pinocchio as pin

    robot = load("paper-humanoid")
    q = robot.q_standing.copy()
    q[3:7] = pin.Quaternion(pin.utils.rpyToMatrix(0.2, 0.1, 0.7)).coeffs()
    sim = Simulator(robot, contacts="welded")
    sim.reset(q)
    start = sim.sole_corners()
    for _ in range(50):
        sim.step(np.zeros(sim.na))
    moved = np.linalg.norm(sim.sole_corners() - start, axis=2)
    assert moved.max() < 1e-3  # every sole corner within 1 mm while the robot collapses
