"""``hqp compare --contacts welded``: the scenarios on the seed papers' rigid feet."""

from __future__ import annotations

import json

import numpy as np
import pytest

from comparisons import get_scenario
from hqp.errors import UnknownName


def test_unknown_contact_mode_is_refused_before_any_run():
    with pytest.raises(UnknownName, match="valid contact modes: unilateral, welded"):
        get_scenario("hand-reach").run(contacts="glued")


def test_cli_refuses_an_unknown_contact_mode(capsys):
    from hqp.app.cli import main

    with pytest.raises(SystemExit) as exc:
        main(["compare", "hand-reach", "--contacts", "glued"])
    assert exc.value.code != 0
    assert "--contacts" in capsys.readouterr().err


def test_commanded_margin_of_a_support():
    """Centre of pressure of commanded wrenches against the hull of two 0.2 x 0.1 m soles."""
    from comparisons.common import commanded_margin
    from hqp.robots import load

    robot = load("paper-humanoid")
    sole = np.array([[0.1, 0.05, 0.0], [-0.1, 0.05, 0.0], [-0.1, -0.05, 0.0], [0.1, -0.05, 0.0]])
    corners = np.stack([sole + [0.0, 0.1, 0.0], sole - [0.0, 0.1, 0.0]])  # hull: y in +-0.15
    push = np.array([0.0, 0.0, 300.0, 0.0, 0.0, 0.0])
    left, right = robot.feet
    assert commanded_margin(robot, corners, {left: push, right: push}, 700.0) == pytest.approx(0.1)
    behind = push + [0, 0, 0, 0, 300.0 * 0.15, 0]  # tau_y > 0: CoP 0.15 m behind each sole
    assert commanded_margin(robot, corners, {left: behind, right: behind}, 700.0) == \
        pytest.approx(-0.05)
    assert np.isnan(commanded_margin(robot, corners, {left: -push, right: push}, 700.0))
    assert commanded_margin(robot, corners, {left: push}, 700.0) is None
    assert commanded_margin(robot, corners, {}, 700.0) is None


@pytest.mark.slow
def test_welded_runs_carry_their_mode_and_support_wrenches():
    """The law, 0.2 s, welded: every run says its mode and has the support metrics."""
    rows = {}
    for mode in ("welded",):
        result = get_scenario("hand-reach").run(controllers=["nullspace"], duration=0.2,
                                               contacts=mode)
        payload = json.loads(json.dumps(result.to_json()))
        for row in payload["runs"]:
            assert row["contacts"] == mode
            rows[mode, row["hierarchy"]] = row
    for (mode, _), row in rows.items():
        assert row["fell"] is False
        assert {"cop_outside_sole_max_mm", "cop_outside_sole_s", "normal_force_min_n"} <= set(row)
        if mode == "welded":  # the welds push on both soles, centres of pressure inside
            assert row["cop_outside_sole_max_mm"] == 0.0 and row["cop_outside_sole_s"] is None
            assert row["normal_force_min_n"] > 100.0
            assert row["commanded_cop_outside_support_s"] is None
