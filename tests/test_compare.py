"""Tests of the paper scenarios (``comparisons/``), their metrics, plots and ``hqp compare``."""

from __future__ import annotations

import numpy as np
import pytest

from comparisons.metrics import Trace, final_window, joint_limit_violation, run_metrics
from hqp.errors import HQPError, InvalidInput


def _trace(n: int = 101, dt: float = 0.01, **kw: object) -> Trace:
    t = np.arange(n) * dt
    names = ("a", "b")
    base = dict(
        t=t,
        q=np.zeros((n, 2)),
        q_lower=np.array([-1.0, -np.inf]),
        q_upper=np.array([1.0, 2.0]),
        joint_names=names,
        com=np.zeros((n, 3)),
        com_goal=np.zeros((n, 2)),
        pelvis_z=np.full(n, 0.9),
        standing_height=0.9,
    )
    base.update(kw)
    return Trace(**base)  # type: ignore[arg-type]


def test_cog_errors_follow_the_contract_definitions() -> None:
    n, dt = 201, 0.01  # 2 s
    t = np.arange(n) * dt
    com = np.zeros((n, 3))
    # x error ramps to 3 mm, y error a constant -4 mm after 1 s: distance 5 mm at the end.
    com[:, 0] = np.minimum(t, 1.0) * 3e-3
    com[t >= 1.0, 1] = -4e-3
    com[50, 0] = 0.02  # a 20 mm spike at t = 0.5 s
    m = run_metrics(_trace(n, dt, com=com, com_goal=np.zeros((n, 2))))
    np.testing.assert_allclose(m["cog_error_max_mm"], 20.0, atol=1e-9)
    np.testing.assert_allclose(m["cog_error_final_mm"], 5.0, atol=1e-9)
    np.testing.assert_allclose(m["cog_error_x_final_mm"], 3.0, atol=1e-9)
    np.testing.assert_allclose(m["cog_error_y_final_mm"], -4.0, atol=1e-9)
    np.testing.assert_allclose(m["cog_error_y_max_mm"], 4.0, atol=1e-9)


def test_final_cog_error_is_a_mean_over_the_last_half_second() -> None:
    n, dt = 301, 0.01  # 3 s
    t = np.arange(n) * dt
    com = np.zeros((n, 3))
    com[:, 0] = t * 1e-3  # 1 mm/s drift
    m = run_metrics(_trace(n, dt, com=com))
    # mean of t over [2.5, 3.0] = 2.75 s -> 2.75 mm
    np.testing.assert_allclose(m["cog_error_final_mm"], 2.75, atol=1e-9)


def test_hand_distance_and_joint_limit_violation() -> None:
    n = 11
    hand = np.zeros((n, 3))
    hand[-1] = [0.0, 0.3, 0.4]
    q = np.zeros((n, 2))
    q[3, 0] = 1.0004  # past the upper limit by 4e-4
    q[5, 1] = -50.0  # no lower limit on joint b
    q[7, 0] = -1.0  # exactly at the lower limit: no violation
    m = run_metrics(_trace(n, hand=hand, hand_goal=np.zeros((n, 3)), q=q))
    np.testing.assert_allclose(m["hand_final_distance_cm"], 50.0, atol=1e-9)
    np.testing.assert_allclose(m["joint_limit_violation_max_rad"], 4e-4, atol=1e-12)
    assert joint_limit_violation(np.zeros((2, 2)), -np.ones(2), np.ones(2)) == 0.0


def test_the_largest_torque_change_per_step_and_its_time() -> None:
    n, dt = 11, 0.001
    tau = np.zeros((n, 2))
    tau[4:, 1] = 3.0  # a 3 N m step at t = 4 ms
    tau[8:, 0] = -7.5  # a 7.5 N m step at t = 8 ms: the largest
    m = run_metrics(_trace(n, dt, tau=tau))
    np.testing.assert_allclose(m["max_torque_jump_nm"], 7.5, atol=1e-12)
    np.testing.assert_allclose(m["max_torque_jump_t"], 0.008, atol=1e-12)
    m = run_metrics(_trace(n, dt))  # no torques recorded
    assert m["max_torque_jump_nm"] is None and m["max_torque_jump_t"] is None


def test_an_actuator_held_at_its_limit_at_the_end() -> None:
    n, dt = 1001, 0.001  # 1 s: the final window is the last 0.5 s
    tau = np.zeros((n, 2))
    tau[:, 0] = 5.0  # half of its limit throughout
    tau[-300:, 1] = -20.0  # at its limit over the last 0.3 s of the window
    m = run_metrics(_trace(n, dt, tau=tau, tau_max=np.array([10.0, 20.0])))
    window = int(final_window(np.arange(n) * dt).sum())  # 500 or 501 samples
    assert 500 <= window <= 501
    np.testing.assert_allclose(m["torque_ratio_final_max"], 300 / window, atol=1e-12)
    assert m["torque_ratio_final_joint"] == "b"
    m = run_metrics(_trace(n, dt, tau=tau))  # no limits recorded
    assert m["torque_ratio_final_max"] is None and m["torque_ratio_final_joint"] is None


def test_fall_detection() -> None:
    n = 11
    z = np.full(n, 0.9)
    assert run_metrics(_trace(n, pelvis_z=z))["fell"] is False
    z[6] = 0.53  # below 0.6 x 0.9 = 0.54
    assert run_metrics(_trace(n, pelvis_z=z))["fell"] is True
    touch = np.zeros(n, dtype=bool)
    touch[4] = True
    assert run_metrics(_trace(n, non_foot_floor_contact=touch))["fell"] is True
    assert run_metrics(_trace(n, fell_at=0.05))["fell"] is True


def test_trace_rejects_bad_shapes() -> None:
    with pytest.raises(InvalidInput, match="com"):
        _trace(11, com=np.zeros((10, 3)))
    with pytest.raises(HQPError, match="unknown joint 'c'; joints: a, b"):
        _trace(11).joint("c")


def test_plot_panels_writes_a_png(tmp_path) -> None:
    from hqp.plots import Line, Panel, plot_panels

    t = np.linspace(0.0, 1.0, 50)
    panels = [
        Panel("Balancing Error", "error [cm]", t, (Line("X", t), Line("Y", -t))),
        Panel("Right Elbow Angle", "angle [rad]", t, (Line("limit", 0 * t, "dashed"),)),
        Panel("Right Knee Flexion", "angle [rad]", t, (Line("angle", t**2),)),
    ]
    out = plot_panels(panels, tmp_path / "sub" / "fig.png", "title")
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    with pytest.raises(InvalidInput, match="curve 'bad'"):
        plot_panels([Panel("p", "y", t, (Line("bad", t[:-1]),))], tmp_path / "x.png")


def test_hand_reach_limit_metrics() -> None:
    """Closest approach to the flexion (lower) limit, first time within 0.02 rad, hand speed."""
    from comparisons.hand_reach import limit_metrics

    n, dt = 201, 0.01  # 2 s
    t = np.arange(n) * dt
    names = ("right_elbow", "right_knee", "other")
    lower, upper = np.array([-1.3, -1.5, -1.0]), np.array([0.0, 0.0, 1.0])
    q = np.zeros((n, 3))
    q[:, 0] = -1.305 * np.minimum(t, 1.0)  # elbow to its -1.3 flexion limit at about 1 s
    q[:, 1] = -0.3 - 0.5 * t  # knee to -1.3, limit -1.5: 0.2 rad short (0 upper: ignored)
    hand = np.zeros((n, 3))
    hand[:, 0] = 0.5 * t  # 0.5 m/s throughout
    trace = _trace(n, dt, q=q, joint_names=names, q_lower=lower, q_upper=upper, hand=hand,
                   hand_goal=np.ones((n, 3)))
    m = limit_metrics(trace)
    np.testing.assert_allclose(m["right_elbow_flexion_gap_rad"], -0.005, atol=1e-12)
    np.testing.assert_allclose(m["right_elbow_flexion_limit_s"], 0.99, atol=1e-9)  # t >= 0.9808
    np.testing.assert_allclose(m["right_knee_flexion_gap_rad"], 0.2, atol=1e-9)
    assert m["right_knee_flexion_limit_s"] is None
    assert "other_flexion_gap_rad" not in m and "right_hip_pitch_flexion_gap_rad" not in m
    np.testing.assert_allclose(m["hand_speed_final_mps"], 0.5, rtol=1e-9)
    q[150:, 1] = -1.51  # 0.01 rad past the limit from 1.5 s
    m = limit_metrics(_trace(n, dt, q=q, joint_names=names, q_lower=lower, q_upper=upper))
    np.testing.assert_allclose(m["right_knee_flexion_gap_rad"], -0.01, atol=1e-9)
    np.testing.assert_allclose(m["right_knee_flexion_limit_s"], 1.5, atol=1e-9)
    assert m["hand_speed_final_mps"] is None


# -- registry and names ----------------------------------------------------------------------


def test_unknown_names_list_the_valid_ones() -> None:
    from comparisons import SCENARIOS, get_scenario
    from hqp.errors import UnknownName

    assert SCENARIOS == ("hand-reach", "obstacle", "box-grab", "screwgun")
    with pytest.raises(UnknownName, match="valid scenarios: box-grab, hand-reach, obstacle"):
        get_scenario("hand_reach")
    scenario = get_scenario("hand-reach")
    with pytest.raises(UnknownName, match="valid controllers: hqp, nullspace, placo"):
        scenario.run(controllers=["tsid"])
    with pytest.raises(UnknownName, match="paper-humanoid"):
        scenario.run(robot="g1")
    with pytest.raises(InvalidInput, match="duration"):
        scenario.run(duration=0.0)


def test_contract_json_shape_and_table() -> None:
    from comparisons.base import RunResult, RunSpec, ScenarioResult
    from comparisons.report import format_table

    n = 11
    trace = _trace(n, hand=np.zeros((n, 3)), hand_goal=np.ones((n, 3)), step_ms=np.ones(n))
    runs = []
    for c in ("hqp", "nullspace"):
        for h in ("shared", "cog-first"):
            r = RunResult(RunSpec(c, h), {}, trace, [])
            r.metrics = run_metrics(trace)
            runs.append(r)
    result = ScenarioResult("hand-reach", "paper-humanoid", runs)
    payload = result.to_json()
    assert list(payload) == ["scenario", "robot", "runs"]
    keys = {"controller", "hierarchy", "cog_error_max_mm", "cog_error_final_mm",
            "hand_final_distance_cm", "joint_limit_violation_max_rad", "step_time_median_ms",
            "fell"}
    for row in payload["runs"]:
        assert keys <= set(row)
        assert isinstance(row["fell"], bool)
        assert all(isinstance(row[k], float) for k in keys - {"controller", "hierarchy", "fell"})
    assert {(r["controller"], r["hierarchy"]) for r in payload["runs"]} == {
        ("hqp", "shared"), ("hqp", "cog-first"), ("nullspace", "shared"),
        ("nullspace", "cog-first")}
    table = format_table(result, wide=True)
    assert "x max [mm]" in table and "y final [mm]" in table
    assert len(table.splitlines()) == 3 + 4
    narrow = format_table(result).splitlines()
    assert max(len(line) for line in narrow) <= 100 and "CoG max [mm]" in narrow[1]


def test_scenario_metric_headers_are_short() -> None:
    from comparisons.report import header

    assert header("right_elbow_flexion_gap_rad") == "elbow from limit [rad]"
    assert header("right_knee_flexion_limit_s") == "knee at limit [s]"
    assert header("hand_speed_final_mps") == "hand speed final [m/s]"
    assert header("obstacle_distance_min_cm") == "obstacle distance min [cm]"
    assert header("trunk_tilt_max_deg") == "trunk tilt max [deg]"
    assert header("plain") == "plain"


# -- closed-loop runs in MuJoCo (slow) -------------------------------------------------------

TIMING = {"step_time_median_ms", "realtime_factor"}  # wall-clock figures: not repeatable


@pytest.mark.slow
@pytest.mark.parametrize("name", ["hand-reach", "obstacle", "box-grab", "screwgun"])
def test_every_scenario_runs_end_to_end(name: str, tmp_path) -> None:
    """Every controller on every hierarchy, shortened to 0.15 s; table, JSON and plots."""
    import json

    from comparisons import get_scenario
    from comparisons.report import format_table, write_plots

    scenario = get_scenario(name)
    result = scenario.run(duration=0.15)
    payload = json.loads(json.dumps(result.to_json()))
    assert payload["scenario"] == name and payload["robot"] == "paper-humanoid"
    pairs = {(r["controller"], r["hierarchy"]) for r in payload["runs"]}
    skipped = {(s["controller"], h) for s in payload.get("skipped", []) for h in s["hierarchies"]}
    for s in payload.get("skipped", []):  # a peer without its environment (tests never make it)
        assert s["controller"] == "placo" and "python -m hqp.bench.peer_env placo" in s["skipped"]
    assert pairs | skipped == {(c, h) for c in scenario.controllers for h in scenario.hierarchies}
    assert not pairs & skipped
    for row in payload["runs"]:
        assert isinstance(row["fell"], bool)
        assert np.isfinite(row["cog_error_max_mm"]) and np.isfinite(row["cog_error_final_mm"])
        if row["controller"] == "hqp":  # the others are measured, not required to stand
            assert row["fell"] is False, row
            assert row["cog_error_max_mm"] < 5.0, row
            assert row["torque_clipping_count"] == 0, row
    assert name in format_table(result)
    paths = write_plots(result, tmp_path)
    assert len(paths) == len(payload["runs"]) and all(p.stat().st_size > 10_000 for p in paths)


@pytest.mark.slow
@pytest.mark.parametrize("name", ["box-grab", "screwgun"])
def test_the_hqp_rows_of_box_grab_and_screwgun_at_full_length(name: str) -> None:
    """docs/results/experiments.md's HQP rows (the servo's torque-rate level on by default): no
    fall, no safe-mode step, at most issue 17's 5 N m of torque change per step (the level's
    own 4 N m holds except where it yields to a level above it: box-grab cog-first 4.38 N m at
    2.306 s, the rate level in conflict beside the joint-limit level), box-grab's hands within
    0.05 cm of their goals. Joints past a limit: box-grab within the measured 1.5e-3 rad
    (ankles); screwgun within the measured 1.3e-2 rad, issue 17's 1e-3 NOT met: from 3.399 s
    the left shoulder pitch's torque sits at its limit (19.9 N m) while its viability bound
    asks to brake: the joint-limit level in conflict with the torque limits from 3.405 s, the
    joint 0.0125 rad past its limit at 3.448 s."""
    from comparisons import get_scenario

    result = get_scenario(name).run(controllers=["hqp"])
    for run in result.runs:
        m = run.metrics
        assert not m["fell"] and m["safe_mode_steps"] == 0, (run.spec, m)
        assert m["max_torque_jump_nm"] < 5.0, (run.spec, m["max_torque_jump_t"])
        bound = 1.3e-2 if name == "screwgun" else 2.5e-3
        assert m["joint_limit_violation_max_rad"] < bound, run.spec
        if name == "box-grab":  # measured 2e-8 cm (shared), 0.023 cm (cog-first: the hands'
            # level in conflict at moments from 2.3 s, beside the upright and symmetry levels)
            assert m["hand_final_distance_cm"] < 0.05, run.spec
            assert m["left_hand_final_distance_cm"] < 0.05, run.spec


@pytest.mark.slow
def test_simulation_metrics_are_deterministic() -> None:
    from comparisons import get_scenario

    runs = [get_scenario("hand-reach").run(controllers=["hqp"], duration=0.2) for _ in range(2)]
    for a, b in zip(runs[0].runs, runs[1].runs):
        ma = {k: v for k, v in a.metrics.items() if k not in TIMING}
        mb = {k: v for k, v in b.metrics.items() if k not in TIMING}
        assert ma == mb
        np.testing.assert_array_equal(a.trace.q, b.trace.q)


@pytest.mark.slow
def test_hand_reach_hqp_shows_what_the_paper_shows() -> None:
    """Seed 003 Figures 4-5 with the HQP controller, at full length.

    cog-first keeps the centre of gravity within 2 mm while shared lets it
    drift at least 3 times as far; the hand stops short of its (unreachable)
    target in both; joint limits hold (< 1e-3 rad), no torque is clipped,
    nobody falls.
    """
    from comparisons import get_scenario

    scenario = get_scenario("hand-reach")
    result = scenario.run(controllers=["hqp"])
    m = {r.spec.hierarchy: r.metrics for r in result.runs}
    assert m["cog-first"]["cog_error_max_mm"] <= 2.0, m
    assert m["shared"]["cog_error_max_mm"] >= 3.0 * m["cog-first"]["cog_error_max_mm"], m
    for h in ("shared", "cog-first"):
        assert m[h]["hand_final_distance_cm"] > 10.0, m  # stops short of the target
        assert m[h]["joint_limit_violation_max_rad"] < 1e-3, m
        assert m[h]["torque_clipping_count"] == 0, m
        assert m[h]["fell"] is False, m
        # The knee-flexion limit is not reached (module docstring: no target makes it on this
        # robot); measured: 0.87 rad from its -1.5 rad limit at the end.
        assert m[h]["right_knee_flexion_gap_rad"] > 0.5, m
    # cog-first reaches the right elbow's flexion limit at 1.52 s and the right hip's at
    # 1.80 s (within 0.02 rad, comparisons.hand_reach.LIMIT_TOLERANCE; both gaps < 1e-4 rad);
    # shared reaches neither by 2 s (0.08 and 0.13 rad short).
    for joint in ("right_elbow", "right_hip_pitch"):
        assert m["cog-first"][f"{joint}_flexion_gap_rad"] <= 0.02, m
        assert m["cog-first"][f"{joint}_flexion_limit_s"] < 1.95, m


def _static_reach(knee_fixed: bool):
    """Closest static reach of the hand-reach target (feet fixed, CoG over the feet, limits)."""
    import pinocchio as pin
    from scipy.optimize import minimize

    import hqp.robots as robots
    from comparisons.hand_reach import HandReachParameters

    rob = robots.load("paper-humanoid")
    m = rob.pinocchio_model()
    d = m.createData()
    rm = rob.model()
    lo, hi = rm.q_lower.copy(), rm.q_upper.copy()
    qs = rob.q_standing.copy()
    names = [m.names[i] for i in range(2, m.njoints)]
    knee = names.index("right_knee")
    if knee_fixed:
        hi[knee] = lo[knee] + 1e-9  # held at its flexion limit
    feet = [m.getFrameId(f) for f in rob.feet]
    hand = m.getFrameId(rob.hands[1])
    pin.framesForwardKinematics(m, d, qs)
    soles = [d.oMf[f].copy() for f in feet]
    centre = 0.5 * (soles[0].translation + soles[1].translation)
    target = np.array([centre[0], centre[1], 0.0]) + np.array(HandReachParameters().target_offset)

    def q_of(x):
        q = qs.copy()
        q[:7] = pin.integrate(m, qs, np.r_[x[:6], np.zeros(m.nv - 6)])[:7]
        q[7:] = qs[7:] + x[6:]
        return q

    def balance(x):
        q = q_of(x)
        pin.framesForwardKinematics(m, d, q)
        c = pin.centerOfMass(m, d, q)
        slips = [pin.log6(sole.actInv(d.oMf[f])).vector for sole, f in zip(soles, feet)]
        return np.concatenate([*slips, c[:2] - centre[:2]])

    def distance2(x):
        q = q_of(x)
        pin.framesForwardKinematics(m, d, q)
        e = d.oMf[hand].translation - target
        return float(e @ e)

    x0 = np.zeros(m.nv)
    bounds = [(None, None)] * 6 + [(lo[i] - qs[7 + i], hi[i] - qs[7 + i]) for i in range(m.nv - 6)]
    x0[6:] = np.clip(x0[6:], [b[0] for b in bounds[6:]], [b[1] for b in bounds[6:]])
    r = minimize(distance2, x0, method="SLSQP", bounds=bounds,
                 constraints=[{"type": "eq", "fun": balance}],
                 options={"maxiter": 500, "ftol": 1e-12})
    assert r.success, r.message
    assert np.abs(balance(r.x)).max() < 1e-6
    return float(np.sqrt(r.fun)), float(q_of(r.x)[7 + knee]), float(lo[knee])


@pytest.mark.slow
def test_hand_reach_knee_flexion_limit_does_not_help_the_hand_on_paper_humanoid():
    # Evidence for the scenario's one difference from the text: on paper-humanoid
    # (sourced segment lengths and ranges) the closest static reach of the target bends the
    # trunk (hip flexion and torso pitch), not the knees; holding the right knee at its
    # flexion limit leaves the hand further away (the deep squat turns the trunk upright).
    free, knee_free, limit = _static_reach(knee_fixed=False)
    fixed, knee_fixed, _ = _static_reach(knee_fixed=True)
    print(f"static reach: knee free {free:.4f} m (knee {knee_free:.3f} rad), "
          f"knee at its limit {fixed:.4f} m")
    # measured: 0.148 m from the target with the right knee straight (0 rad); 0.202 m with it
    # held at -1.5 rad (torque limits not imposed here; the closed loop ends 25-28 cm short)
    assert knee_free > limit + 0.3  # [rad]
    assert abs(knee_fixed - limit) < 1e-6
    assert fixed > free + 0.01  # [m] the knee at its limit costs the hand centimetres
