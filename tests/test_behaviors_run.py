"""Behaviors in closed loop with MuJoCo on paper-humanoid (slow).

Thresholds have margins; the measured figures are printed by ``hqp run NAME --json``.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from hqp.app.run import run_behavior
from hqp.behaviors.loader import LIBRARY

pytestmark = pytest.mark.slow


def check_upright(result, *, flight_allowed: bool = False) -> None:
    assert not result.fell, result.fall_reason
    assert result.metrics["sim_clipped_torques"] == 0
    assert result.metrics["max_torque_ratio"] <= 1.0 + 1e-9
    # the controller's safe command replaces a failed solve; the current solver returns
    # non-finite ProxQP solutions at the operational level for a few steps after some goal
    # changes (reported in issue 7): tolerated, bounded
    assert result.metrics["safe_mode_steps"] <= 10
    if not flight_allowed:
        assert result.metrics["flight_time_s"] == 0.0


def test_reach_follows_the_streamed_goal_without_falling() -> None:
    # the seed's points, streamed (the library's default goal is relative to the shoulder)
    result = run_behavior("reach", duration=2.5, inputs=LIBRARY / "reach_inputs.jsonl")
    check_upright(result)
    assert result.phases == ["stand", "reach"]
    hand = result.metrics["task_errors"]["reach"]["hand"]
    assert hand["final"] < 0.03  # [m] from the goal streamed at t = 2 s


FILE_ONLY = """\
# A behavior written only as a file: shift the weight over the left foot, then the
# right one, then back to the middle (sensed centre of gravity triggers the phases).
[behavior]
name = "sway"
initial = "middle"
duration = 1.6

[tasks.balance]
type = "com"
goal = "[feet_center.x, feet_center.y, com0.z]"
kp = 60.0

[tasks.trunk]
type = "orientation"
frame = "trunk"
goal = [0.0, 0.0, 0.0]

[tasks.posture]
type = "posture"
goal = "standing"
kp = 40.0

[actions.sway]
tasks = ["balance", "trunk", "posture"]

[phases.middle]
action = "sway"
contacts = ["left_foot", "right_foot"]
transitions = [{ to = "left", when = "t >= 0.1" }]

[phases.left]
action = "sway"
contacts = ["left_foot", "right_foot"]
goals = { balance = "[feet_center.x, feet_center.y + 0.03, com0.z]" }
transitions = [{ to = "right", when = "com.y > feet_center.y + 0.02" }]

[phases.right]
action = "sway"
contacts = ["left_foot", "right_foot"]
goals = { balance = "[feet_center.x, feet_center.y - 0.03, com0.z]" }
transitions = [{ to = "back", when = "com.y < feet_center.y - 0.02" }]

[phases.back]
action = "sway"
contacts = ["left_foot", "right_foot"]
final = true
"""


def test_a_behavior_written_only_as_a_file_runs(tmp_path: Path) -> None:
    path = tmp_path / "sway.toml"
    path.write_text(FILE_ONLY)
    result = run_behavior(path)
    check_upright(result)
    assert result.phases == ["middle", "left", "right", "back"]
    assert result.metrics["task_errors"]["back"]["balance"]["final"] < 0.02


@pytest.mark.parametrize("name", [
    "stand",
    "mimic",
    "screwgun",
])
def test_library_behavior_runs_without_falling(name: str) -> None:
    duration = {"stand": 1.0, "mimic": 2.5, "screwgun": 3.5}[name]
    result = run_behavior(name, duration=duration)
    check_upright(result)
    # the default torque-rate level (4 N m per 1 ms step; mimic's pose switches and
    # screwgun's moves make larger steps without it); no flight, so no impact
    assert result.metrics["max_torque_jump_nm"] < 5.0
    assert result.metrics["impacts"] == []
    if name == "mimic":
        assert result.phases[:3] == ["stand", "arms_forward", "wave"]
    if name == "screwgun":
        # the tool is taken (1 s), then the tool point rises above 1.20 m at t = 2.5 s
        # (screwgun_inputs.jsonl): posture switch
        assert result.phases[:3] == ["ready", "low", "high"]
        # at the end of `high` the tool point moves down at 0.15 m/s (inputs from t = 5 s): the
        # PD law lags by kv v / kp = 0.2 s x 0.15 m/s = 30 mm (the streamed input carries no
        # goal velocity); measured 30.1 mm, and 7 mm while the point is still (t = 3.5-5 s)
        assert result.metrics["task_errors"]["high"]["tool_point"]["final"] < 0.035  # [m]


def test_squat_jump_flies_and_lands_standing(tmp_path: Path) -> None:
    # Measured (hqp run squat-jump --json, repeated: runs differ by ~1e-13 per step from the
    # first (BLAS rounding) and the landing amplifies it): contacts released at 0.30 m/s, both
    # feet out of contact (MuJoCo's contacts) for 0.038-0.046 s with the lower sole 1.2-1.6
    # mm up, landing at -0.2 to -0.3 m/s, pelvis at least 0.840 m (standing 0.863); torque
    # limits reached in the push and at the landing (ratio 1.0, never beyond: the
    # controller's own rows); push 5.5 and 6.5 m/s^2 and a far target also land standing.
    result = run_behavior("squat-jump", plot=tmp_path / "squat-jump.png")
    check_upright(result, flight_allowed=True)
    png = Path(result.metrics["plot"])
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 10_000
    assert result.phases[:5] == ["stand", "down", "up", "flight", "strike"]
    assert result.phases[-2:] == ["land", "recover"]
    assert "abort" not in result.phases
    assert result.metrics["flight_time_s"] >= 0.02  # [s] both feet off the floor
    assert result.metrics["flight_clearance_m"] > 0.0
    assert result.metrics["pelvis_min_m"] > 0.75  # [m]
    assert result.metrics["task_errors"]["recover"]["trunk_upright"]["final"] < 0.05  # [rad]
    # the file's torque-rate level, 20 N m per step, holds over the whole run, the landing
    # included (a landing without the level is a step of a hundred N m or more); the landing
    # is reported apart
    assert result.metrics["max_torque_jump_nm"] <= 20.0 + 1e-6
    impacts = result.metrics["impacts"]
    assert len(impacts) >= 1
    landing = impacts[0]
    assert 0.0 <= landing["max_torque_jump_t"] - landing["t"] <= 0.05 + 1e-9
    assert landing["max_torque_jump_nm"] <= result.metrics["max_torque_jump_nm"]
    assert result.metrics["max_torque_jump_outside_impacts_nm"] <= result.metrics[
        "max_torque_jump_nm"]


def test_squat_jump_infeasible_push_enters_the_safety_phase_on_its_feet() -> None:
    # A take-off height above what straight legs reach (1.2 m > 1.002 m): the hip task cannot
    # be completed. Measured: it becomes infeasible 0.066 s into the push with the knees at
    # -0.46 rad extending at 4.1 rad/s toward their limit (0 rad: the push's acceleration is
    # no longer available there); the seed's
    # Figure 13 state machine: the safety phase. The robot is still on its feet (the push
    # holds both contacts until take-off), so the safety phase keeps them and stands up.
    # (Releasing the contacts there, as an earlier version did, made the controller model a
    # free fall while the feet stood on the floor: it fell on a CI machine, not here.)
    # The velocity trigger off (10 m/s): only the height would release the contacts.
    result = run_behavior("squat-jump", overrides={"takeoff_height": 1.2,
                                                   "takeoff_velocity": 10.0})
    check_upright(result)  # no flight: both feet stay down
    assert result.phases == ["stand", "down", "up", "abort", "recover"]
    assert result.metrics["pelvis_min_m"] > 0.8  # [m] measured 0.840 (standing 0.863)
    safety = [e for e in result.feasibility_events if e["status"] == "safety"]
    assert safety and safety[0]["task"] == "hip" and safety[0]["phase"] == "up"
    assert result.metrics["task_errors"]["recover"]["trunk_upright"]["final"] < 0.05  # [rad]
