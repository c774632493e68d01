"""The behavior state machine on a real stack, without simulation (fast).

A stub controller records what the behavior writes into it (tasks, levels,
contacts, ramps) and hands back feasibility reports that the test chooses, so
the transitions, the safety phase of seed Figure 13 and the smooth switching of
task sets are checked exactly.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from hqp import HQPError, robots
from hqp.behaviors import Behavior, load_behavior
from hqp.behaviors.factory import TaskFactory
from hqp.controller import Controller, Feasibility, FeasibilityReport, TaskStatus
from hqp.model import RobotState
from hqp.stack import Stack

TEXT = """\
[behavior]
name = "machine"
initial = "hold"
ramp_time = 0.25
unload_time = 0.15

[inputs.goal]
default = [0.3, -0.2, 1.0]

[tasks.balance]
type = "com"
axes = "xy"
goal = "[feet_center.x, feet_center.y]"

[tasks.hand]
type = "position"
frame = "right_hand"
goal = "input.goal"

[tasks.hip]
type = "position"
frame = "trunk"
axes = "z"
goal = "initial - 0.1"

[tasks.posture]
type = "posture"
goal = "standing"

[phases.hold]
tasks = ["balance", "posture"]
contacts = ["left_foot", "right_foot"]
transitions = [{ to = "reach", when = "phase_time >= 0.5" }]

[phases.reach]
tasks = ["balance", "hand", "hip", "posture"]
contacts = ["left_foot", "right_foot"]
safety = "safe"
watch = ["hip"]
transitions = [{ to = "lift", when = "error.hand < 0.01" }]

[phases.lift]
tasks = ["balance", "hand", "posture"]
contacts = ["left_foot"]
final = true

[phases.safe]
tasks = ["balance", "posture"]
contacts = ["left_foot", "right_foot"]
final = true
"""


class StubController(Controller):
    """Records the active task set; its ``step`` is never called here."""

    def __init__(self, model):
        self.model = model
        self.stack = Stack()
        self.dt = 1e-3
        self.contacts = {"left_foot": True, "right_foot": True}
        self.log: list[tuple] = []

    def step(self, state, t):  # pragma: no cover - not used
        raise NotImplementedError

    def add_task(self, task, level=None, *, t=None, ramp_time=None):
        self.log.append(("add", task.name, t, ramp_time))
        super().add_task(task, level, t=t, ramp_time=ramp_time)

    def remove_task(self, name, *, t=None):
        self.log.append(("remove", name, t))
        super().remove_task(name, t=t)

    def activate_contact(self, name, *, t=None):
        self.log.append(("make", name, t))
        self.contacts[name] = True

    def deactivate_contact(self, name, *, t=None, unload_time=None):
        self.log.append(("release", name, t, unload_time))
        self.contacts[name] = False

    @property
    def active_contacts(self):
        return tuple(c for c, on in self.contacts.items() if on)


def report(statuses: dict[str, tuple[Feasibility, float, int | None]], levels) -> FeasibilityReport:
    return FeasibilityReport(tasks=tuple(
        TaskStatus(name, levels[name], status, residual, yields_to)
        for name, (status, residual, yields_to) in statuses.items()))


def build(tmp_path: Path, text: str = TEXT, stack_tasks=()):
    """The behavior of ``text`` on a stub controller holding ``stack_tasks``, and a state."""
    robot = robots.load("paper-humanoid")
    model = robot.model()
    path = tmp_path / "machine.toml"
    path.write_text(text)
    spec = load_behavior(path, frames=model.frame_names, joints=model.joint_names,
                         contacts=["left_foot", "right_foot"])
    ctrl = StubController(model)
    for task in stack_tasks:
        ctrl.stack.add(task)
    factory = TaskFactory(model, {"left_foot": "left_foot", "right_foot": "right_foot"},
                          robot.q_standing)
    behavior = Behavior(spec, ctrl, factory, standing=robot.q_standing, safety_steps=3)
    state = RobotState(q=robot.q_standing.copy(), v=np.zeros(model.nv), t=0.0,
                       contacts={"left_foot": True, "right_foot": True})
    return behavior, ctrl, state


@pytest.fixture()
def setup(tmp_path: Path):
    return build(tmp_path)


def test_phases_are_an_enum_and_time_is_simulated(setup):
    behavior, ctrl, state = setup
    assert [p.value for p in behavior.Phase] == ["hold", "reach", "lift", "safe"]
    behavior.start(state, 10.0)
    assert behavior.phase is behavior.Phase.HOLD
    # transitions read simulated time only: 0.49 s after the start nothing happens
    behavior.update(state, 10.49, None)
    assert behavior.phase is behavior.Phase.HOLD
    behavior.update(state, 10.5, None)
    assert behavior.phase is behavior.Phase.REACH
    # new tasks are ramped in with the behavior's ramp, kept tasks are not touched
    adds = [e for e in ctrl.log if e[0] == "add" and e[2] == 10.5]
    assert sorted(e[1] for e in adds) == ["hand", "hip"]
    assert all(e[3] == 0.25 for e in adds)
    assert not [e for e in ctrl.log if e[0] == "remove"]
    assert behavior.visited == ["hold", "reach"]


def test_goals_from_inputs_and_initial_values(setup):
    behavior, ctrl, state = setup
    behavior.start(state, 0.0)
    behavior.update(state, 0.5, None)
    hand = behavior.tasks["hand"]
    np.testing.assert_allclose(hand.goal_at(0.5).position, [0.3, -0.2, 1.0])
    trunk_z = ctrl.model.frame_placement("trunk").translation[2]
    np.testing.assert_allclose(behavior.tasks["hip"].goal_at(0.5).position, [trunk_z - 0.1],
                               atol=1e-12)


def test_safety_phase_on_infeasible_watched_task(setup):
    behavior, ctrl, state = setup
    behavior.start(state, 0.0)
    behavior.update(state, 0.5, None)
    levels = {n: ctrl.stack.level_of_task(n) for n in ("balance", "hand", "hip", "posture")}
    # the posture is in conflict (not watched): nothing happens
    rep = report({"posture": (Feasibility.CONFLICT, 5.0, 4),
                  "hip": (Feasibility.SATISFIED, 0, None)}, levels)
    for k in range(5):
        behavior.update(state, 0.6 + 1e-3 * k, rep)
    assert behavior.phase is behavior.Phase.REACH
    # the hip yields to the joint-limit level (2) for 3 steps: safety
    rep = report({"hip": (Feasibility.CONFLICT, 3.0, 2)}, levels)
    for k in range(2):
        behavior.update(state, 0.7 + 1e-3 * k, rep)
    assert behavior.phase is behavior.Phase.REACH
    behavior.update(state, 0.702, rep)
    assert behavior.phase is behavior.Phase.SAFE
    kinds = [(e.task, e.status) for e in behavior.events]
    assert ("hip", "conflict") in kinds and ("hip", "safety") in kinds
    # leaving the phase removes the hand and the hip (blended out by the stack)
    assert {e[1] for e in ctrl.log if e[0] == "remove"} == {"hand", "hip"}


def test_contacts_are_unloaded_when_a_phase_releases_them(setup):
    behavior, ctrl, state = setup
    behavior.start(state, 0.0)
    behavior.update(state, 0.5, None)
    # put the hand on its goal: error.hand < 0.01 after the next rows
    goal = ctrl.model.frame_placement("right_hand").translation.copy()
    behavior.inputs.specs["goal"] = type(behavior.inputs.specs["goal"])(
        "goal", (3,), goal)
    behavior.update(state, 0.501, None)
    hand = behavior.tasks["hand"]
    from hqp.model.layout import Layout

    hand.rows(ctrl.model, Layout.build(ctrl.model.nv), 1e-3, 0.502)
    behavior.update(state, 0.502, None)
    assert behavior.phase is behavior.Phase.LIFT
    assert ("release", "right_foot", 0.502, 0.15) in ctrl.log
    assert "hip" not in ctrl.stack


def test_phase_sets_the_blend_time_and_the_joint_limit_braking(tmp_path: Path) -> None:
    """A phase's ``blend_time`` and ``joint_braking = "airborne"`` reach the controller while
    it is active; the next phase restores the controller's blend time and contact braking."""
    from hqp.tasks.joint_limits import JointLimits, SupportBraking

    text = TEXT.replace('when = "error.hand < 0.01"', 'when = "phase_time >= 0.05"', 1).replace(
        'contacts = ["left_foot"]\nfinal = true',
        'contacts = ["left_foot"]\nblend_time = 0.0\njoint_braking = "airborne"'
        '\ntransitions = [{ to = "safe", when = "phase_time >= 0.1" }]')
    robot = robots.load("paper-humanoid")
    model = robot.model()
    limits = JointLimits(qdd_max=50.0, braking=SupportBraking(model, ["left_foot"], 25.0,
                                                              q=robot.q_standing))
    behavior, ctrl, state = build(tmp_path, text, [limits])
    default_blend = ctrl.stack.blend_time
    assert default_blend > 0.0
    behavior.start(state, 0.0)
    assert not limits.airborne_braking
    behavior.update(state, 0.5, None)
    assert behavior.phase is behavior.Phase.REACH
    assert ctrl.stack.blend_time == default_blend and not limits.airborne_braking
    behavior.update(state, 0.56, None)
    assert behavior.phase is behavior.Phase.LIFT
    assert ctrl.stack.blend_time == 0.0 and limits.airborne_braking
    behavior.update(state, 0.7, None)
    assert behavior.phase is behavior.Phase.SAFE
    assert ctrl.stack.blend_time == default_blend and not limits.airborne_braking


def test_behavior_file_sets_the_joint_acceleration_clip() -> None:
    from hqp.behaviors.setup import build_controller
    from hqp.tasks.joint_limits import JointLimits

    robot = robots.load("paper-humanoid")
    for clip in (None, 200.0):
        ctrl = build_controller(robot, "hqp", max_joint_acceleration=clip)
        limits = next(t for t in ctrl.stack.tasks if isinstance(t, JointLimits))
        top = limits.max_acceleration(ctrl.model).max()
        assert top == (50.0 if clip is None else 200.0)


def test_behavior_controllers_hold_only_the_constraint_levels() -> None:
    # The standing stack's own tasks (CoM, trunk, posture and the angular-momentum damping of
    # its balance level) are removed: left in, the damping sat strictly above the walk's
    # swing-foot tasks and cut its steps short (6 of 8 in tests/test_walk.py).
    from hqp.behaviors.setup import build_controller
    from hqp.robots import load

    ctrl = build_controller(load("paper-humanoid"), "hqp")
    names = {t.name for t in ctrl.stack.tasks}
    assert "angular_momentum" not in names and "com" not in names, names


def test_an_unchanged_goal_is_not_set_again_so_the_goal_ramp_of_a_new_task_survives(setup):
    # A task added at a phase switch starts at its current value and ramps to its goal (see
    # hqp.stack); setting the same goal again at the next steps would replace that ramp by a
    # step (measured before the fix on `reach`: a 12.9 N m torque jump 2 ms after the switch).
    behavior, ctrl, state = setup
    behavior.start(state, 0.0)
    behavior.update(state, 0.5, None)  # -> reach: hand added, goal set
    hand = behavior.tasks["hand"]
    ctrl.stack.advance(ctrl.model, _layout(ctrl), 1e-3, 0.5, None)  # the stack starts the ramp
    ramp = hand.trajectory
    assert ramp is not None
    behavior.update(state, 0.501, None)
    behavior.update(state, 0.502, None)
    assert hand.trajectory is ramp
    start = ctrl.model.frame_placement("right_hand").translation
    np.testing.assert_allclose(hand.goal_at(0.5).position, start, atol=1e-12)
    # a changed goal (a streamed input) is set at once
    behavior.inputs._add({"t": 0.6, "goal": [0.35, -0.2, 1.0]}, "test")
    behavior.update(state, 0.6, None)
    assert hand.trajectory is None
    np.testing.assert_allclose(hand.goal_at(0.6).position, [0.35, -0.2, 1.0])


def _layout(ctrl):
    from hqp.model.layout import Layout

    return Layout.build(ctrl.model.nv)


def test_momentum_and_forces_tasks_build_from_a_file(tmp_path: Path) -> None:
    from hqp.tasks.centroidal import CentroidalMomentumTask
    from hqp.tasks.effort import ForceRegularization

    robot = robots.load("paper-humanoid")
    model = robot.model()
    text = TEXT.replace("[tasks.posture]", """[tasks.spin]
type = "momentum"
part = "angular"
kv = 5.0
goal = [0.0, 0.0, 0.0]

[tasks.share]
type = "forces"
weight = 100.0

[tasks.posture]""")
    hold = 'tasks = ["balance", "posture"]\ncontacts = ["left_foot", "right_foot"]\ntransitions'
    text = text.replace(hold, hold.replace('"balance", ', '"balance", "spin", "share", '))
    path = tmp_path / "m.toml"
    path.write_text(text)
    spec = load_behavior(path, frames=model.frame_names, joints=model.joint_names,
                         contacts=["left_foot", "right_foot"])
    factory = TaskFactory(model, {"left_foot": "left_foot", "right_foot": "right_foot"},
                          robot.q_standing)
    spin = factory.build(spec.tasks["spin"])
    share = factory.build(spec.tasks["share"])
    assert isinstance(spin, CentroidalMomentumTask) and spin.reference.kv == 5.0
    assert isinstance(share, ForceRegularization) and share.weight == 100.0
    factory.set_goals(spin, spec.tasks["spin"], {"goal": np.zeros(3)})
    ctrl = StubController(model)
    behavior = Behavior(spec, ctrl, factory, standing=robot.q_standing)
    state = RobotState(q=robot.q_standing.copy(), v=np.zeros(model.nv), t=0.0,
                       contacts={"left_foot": True, "right_foot": True})
    behavior.start(state, 0.0)
    assert {"spin", "share"} <= {task.name for task in ctrl.stack.tasks}
    bad = path.with_name("bad.toml")
    bad.write_text(text.replace('part = "angular"', 'part = "sideways"'))
    spec = load_behavior(bad, frames=model.frame_names, joints=model.joint_names,
                         contacts=["left_foot", "right_foot"])
    with pytest.raises(HQPError, match="momentum part must be"):
        factory.build(spec.tasks["spin"])
