"""Behavior description files: parsing, the expression language, inputs, and clear errors."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from hqp import BehaviorFileError, HQPError
from hqp.behaviors import InputStream, library_names, load_behavior
from hqp.behaviors.expressions import ExpressionError, Namespace, parse
from hqp.errors import InvalidInput, UnknownName

FRAMES = ["left_foot", "right_foot", "left_hand", "right_hand", "trunk", "head", "universe"]
CONTACTS = ["left_foot", "right_foot"]

GOOD = """\
[behavior]
name = "tiny"
initial = "a"

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

[phases.a]
tasks = ["balance"]
contacts = ["left_foot", "right_foot"]

  [[phases.a.transitions]]
  to = "b"
  when = "phase_time > 0.5"

[phases.b]
tasks = ["balance", "hand"]
contacts = ["left_foot", "right_foot"]
final = true
"""


def write(tmp_path: Path, text: str, name: str = "b.toml") -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p


def load(tmp_path: Path, text: str) -> object:
    return load_behavior(write(tmp_path, text), frames=FRAMES, contacts=CONTACTS)


def test_good_file_parses(tmp_path: Path) -> None:
    spec = load(tmp_path, GOOD)
    assert spec.name == "tiny" and spec.initial == "a"
    assert list(spec.phases) == ["a", "b"]
    assert spec.phases["b"].action.runtime_inputs == ("goal",)
    phase = spec.phase_enum()
    assert [p.value for p in phase] == ["a", "b"]
    np.testing.assert_allclose(spec.inputs["goal"].default, [0.3, -0.2, 1.0])


@pytest.mark.parametrize("name", ["stand", "reach", "mimic", "screwgun", "squat-jump", "walk"])
def test_library_files_parse(name: str) -> None:
    assert name in library_names()
    spec = load_behavior(name, frames=None, contacts=CONTACTS)
    assert spec.initial in spec.phases
    for phase in spec.phases.values():
        assert phase.final or phase.transitions


@pytest.mark.parametrize(
    ("old", "new", "fragments"),
    [
        ('type = "position"', 'type = "positon"',
         ["tasks.hand.type", "unknown task type 'positon'", "expected one of", ":14:"]),
        ('frame = "right_hand"', 'frame = "rigth_hand"',
         ["tasks.hand.frame", "unknown frame 'rigth_hand'", "right_hand", ":15:"]),
        ('to = "b"', 'to = "c"',
         ["phases.a.transitions[0].to", "missing phase 'c'", ":23:"]),
        ('  [[phases.a.transitions]]\n  to = "b"\n  when = "phase_time > 0.5"\n', "",
         ["phases.a", "no exit", "final = true"]),
        ('when = "phase_time > 0.5"', 'when = "phase_tim > 0.5"',
         ["phases.a.transitions[0].when", "unknown name 'phase_tim'"]),
        ('when = "phase_time > 0.5"', 'when = "__import__(1)"',
         ["phases.a.transitions[0].when", "only these functions"]),
        ('goal = "input.goal"', 'goal = "input.gaol"',
         ["tasks.hand.goal", "unknown input 'gaol'"]),
        ('initial = "a"', 'initial = "z"', ["behavior.initial", "'z' is not a phase"]),
        ('axes = "xy"', 'axes = "xw"', ["tasks.balance.axes", "subset of 'xyz'"]),
        ('axes = "xy"', 'kp = -1.0', ["tasks.balance.kp", "non-negative"]),
        ('axes = "xy"', 'gain = 3', ["tasks.balance.gain", "unknown key", "kp"]),
        ('tasks = ["balance"]', 'tasks = ["balanse"]',
         ["phases.a.tasks[0]", "unknown task 'balanse'"]),
        ('contacts = ["left_foot", "right_foot"]\n\n  [[', 'contacts = ["left_hoof"]\n\n  [[',
         ["phases.a.contacts[0]", "unknown contact 'left_hoof'"]),
        ("[phases.b]", "[phases.b]\nsafety = \"nowhere\"",
         ["phases.b.safety", "missing phase 'nowhere'"]),
        ('name = "tiny"', 'name = "tiny', ["not valid TOML", "line 2"]),
        ("[phases.b]", "[phases.b]\njoint_braking = \"flying\"",
         ["phases.b.joint_braking", "expected \"contacts\" or \"airborne\"", "'flying'"]),
        ("[phases.b]", "[phases.b]\nblend_time = -0.1", ["phases.b.blend_time", "non-negative"]),
        ('initial = "a"', 'initial = "a"\nmax_joint_acceleration = 2.0',
         ["behavior.max_joint_acceleration", "at least 5 rad/s^2"]),
        ('initial = "a"', 'initial = "a"\nmax_torque_rate = -1.0',
         ["behavior.max_torque_rate", "non-negative"]),
        ('initial = "a"', 'initial = "a"\nmax_torque_rate = "fast"',
         ["behavior.max_torque_rate"]),
        ('initial = "a"', 'initial = "a"\nmax_torque_rate = nan',
         ["behavior.max_torque_rate", "non-negative"]),
    ],
)
def test_bad_files_name_file_key_and_expectation(
    tmp_path: Path, old: str, new: str, fragments: list[str]
) -> None:
    assert old in GOOD
    path = write(tmp_path, GOOD.replace(old, new, 1))
    with pytest.raises(BehaviorFileError) as info:
        load_behavior(path, frames=FRAMES, contacts=CONTACTS)
    message = str(info.value)
    assert str(path) in message
    for fragment in fragments:
        assert fragment in message, message
    assert isinstance(info.value, HQPError) and isinstance(info.value, ValueError)


def test_phase_controller_options_parse(tmp_path: Path) -> None:
    text = GOOD.replace('initial = "a"', 'initial = "a"\nmax_joint_acceleration = 150.0', 1)
    text = text.replace("[phases.b]", '[phases.b]\njoint_braking = "airborne"\nblend_time = 0.0')
    spec = load(tmp_path, text)
    assert spec.max_joint_acceleration == 150.0
    assert spec.phases["a"].joint_braking == "contacts" and spec.phases["a"].blend_time is None
    assert spec.phases["b"].joint_braking == "airborne" and spec.phases["b"].blend_time == 0.0


@pytest.mark.parametrize(("line", "parsed", "controller_rate"), [
    ("", None, 4000.0),  # the default level (hqp.control.servo.MAX_TORQUE_RATE)
    ("max_torque_rate = 12000.0", 12000.0, 12000.0),
    ("max_torque_rate = 0", 0.0, None),  # 0: no torque-rate level
])
def test_the_torque_rate_level_of_a_behavior_file(tmp_path: Path, line: str, parsed,
                                                 controller_rate) -> None:
    from hqp.behaviors.setup import prepare

    text = GOOD.replace('initial = "a"', f'initial = "a"\n{line}', 1)
    spec = load(tmp_path, text)
    assert spec.max_torque_rate == parsed
    _behavior, ctrl, _robot = prepare(spec, robot="paper-humanoid")
    rate = ctrl.max_torque_rate
    if controller_rate is None:
        assert rate is None
    else:
        np.testing.assert_array_equal(rate, controller_rate)


def test_unreachable_phase_is_an_error(tmp_path: Path) -> None:
    text = GOOD + '\n[phases.orphan]\ntasks = ["balance"]\ncontacts = []\nfinal = true\n'
    with pytest.raises(BehaviorFileError, match="phases.orphan.*cannot be reached"):
        load(tmp_path, text)


def test_unknown_behavior_name_lists_the_library() -> None:
    with pytest.raises(UnknownName, match="walk"):
        load_behavior("wlak")


def test_expressions_evaluate_and_reject() -> None:
    env = {"t": 1.5, "com": np.array([0.1, 0.0, 0.9]),
           "contact": Namespace({"left_foot": True, "right_foot": False}, "contact")}
    assert parse("t > 1 and contact.left_foot and not contact.right_foot").evaluate(env) is True
    np.testing.assert_allclose(parse("com + [0, 0, -0.1]").evaluate(env), [0.1, 0.0, 0.8])
    assert parse("com.z < 0.95").evaluate(env) is True
    assert parse("norm([3, 4]) == 5").evaluate(env) is True
    # min_jerk(u) = 10 u^3 - 15 u^4 + 6 u^5 of u clipped to [0, 1]
    for u in (-0.5, 0.0, 0.25, 0.5, 0.75, 1.0, 3.0):
        c = min(max(u, 0.0), 1.0)
        expected = 10 * c**3 - 15 * c**4 + 6 * c**5
        assert parse(f"min_jerk({u})").evaluate(env) == pytest.approx(expected, abs=1e-15)
    assert parse("min_jerk(t / 3)").evaluate(env) == pytest.approx(0.5)
    for bad in ["open('x')", "t.__class__", "lambda: 1", "[x for x in t]", "a if"]:
        with pytest.raises(ExpressionError):
            parse(bad)
    with pytest.raises(ExpressionError, match="contact.left_hoof"):
        parse("contact.left_hoof").evaluate(env)


def test_input_stream_hold_interpolate_and_growth(tmp_path: Path) -> None:
    spec = load(tmp_path, GOOD)
    path = tmp_path / "in.jsonl"
    path.write_text(json.dumps({"t": 1.0, "goal": [1, 2, 3]}) + "\n")
    stream = InputStream(spec.inputs, path)
    np.testing.assert_allclose(stream.value("goal", 0.5), [0.3, -0.2, 1.0])  # default
    np.testing.assert_allclose(stream.value("goal", 1.2), [1, 2, 3])
    with path.open("a") as f:  # streamed: appended while running
        f.write(json.dumps({"t": 2.0, "goal": [2, 2, 2]}) + "\n")
    np.testing.assert_allclose(stream.value("goal", 1.9), [1, 2, 3])
    np.testing.assert_allclose(stream.value("goal", 2.0), [2, 2, 2])
    stream.close()
    bad = tmp_path / "bad.jsonl"
    bad.write_text('{"t": 0.0, "goal": [1, 2]}\n')
    with pytest.raises(InvalidInput, match=r"bad.jsonl.*goal expected shape \[3\]"):
        InputStream(spec.inputs, bad).value("goal", 0.1)
