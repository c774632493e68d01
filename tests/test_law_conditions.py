"""The papers' law on welded feet (``python -m comparisons.law_conditions``): what it reproduces
of seed 003's Figures 4-5 and where it stops (docs/results/comparison.md)."""

from __future__ import annotations

import pytest

from comparisons.hand_reach import HandReach, HandReachParameters
from comparisons.law_conditions import zone_report


def _law_run(torque_scale: float, duration: float):
    scenario = HandReach(HandReachParameters(torque_scale=torque_scale))
    scenario.hierarchies = ("cog-first",)
    result = scenario.run(controllers=["nullspace"], duration=duration, contacts="welded")
    run = result.runs[0]
    assert run.metrics["contacts"] == "welded"
    return run, zone_report(run, scenario.parameters.zone)


@pytest.mark.slow
def test_without_torque_limits_the_law_is_the_papers_until_the_first_zone():
    """Welded feet, torque limits x10 (none reached): CoG within the paper's 2 mm and the hand
    at the paper's 24 cm (+- 3 cm) when the first joint enters its activation zone."""
    run, report = _law_run(10.0, 1.66)
    assert report["zone_entry_s"] is not None and 1.5 < report["zone_entry_s"] < 1.66
    before = report["before_zone"]
    assert before["cog_x_max_mm"] < 2.0 and before["cog_y_max_mm"] < 2.0
    assert abs(before["hand_distance_cm"] - 24.0) < 3.0
    assert report["saturated"] == {}  # no torque limit reached before the zone


@pytest.mark.slow
def test_with_the_robots_torque_limits_the_torso_saturates_first():
    """Welded feet, paper-humanoid's limits: the torso-pitch motor (78 N m) saturates before
    any joint reaches a zone; the torso then sinks into its zone and the run breaks down."""
    run, report = _law_run(1.0, 0.85)
    assert report["zone_entry_s"] is not None and report["zone_entry_s"] < 0.85
    assert "torso_pitch" in report["zone_joints"]
    assert report["saturated"]["torso_pitch"] < report["zone_entry_s"] - 0.1
    assert report["before_zone"]["cog_x_max_mm"] < 2.0
