"""Mistakes a user makes, each a clear error before anything runs (issue 19).

Library calls raise an :class:`hqp.HQPError` whose message names the file and line, the
level and field, or the argument; the command line prints one line on stderr and exits with
status 2, without a traceback and before any simulation starts.
"""

from __future__ import annotations

import json
import re
import time
from pathlib import Path

import numpy as np
import pytest

from hqp import robots
from hqp.app.cli import main
from hqp.app.run import run_behavior
from hqp.behaviors.expressions import MAX_LENGTH, ExpressionError, parse
from hqp.behaviors.inputs import InputStream
from hqp.behaviors.loader import parse_behavior
from hqp.behaviors.setup import prepare
from hqp.behaviors.spec import InputSpec
from hqp.control.presets import standing_controller
from hqp.errors import BehaviorFileError, HQPError, InvalidInput, InvalidLevel
from hqp.sim.simulator import Simulator
from hqp.solver import Level, solve

STAND = """\
[behavior]
name = "bad"
initial = "stand"
duration = 0.01

[tasks.balance]
type = "com"
axes = "xyz"
goal = "[feet_center.x, feet_center.y, com0.z]"
level = {level}

[tasks.trunk_upright]
type = "orientation"
frame = "trunk"
goal = {goal}

[phases.stand]
tasks = ["balance", "trunk_upright"]
contacts = ["left_foot", "right_foot"]
final = true

[[phases.stand.transitions]]
to = "stand"
when = "{when}"
"""


def _file(tmp_path: Path, level: str = '"balance"', goal: str = "[0.0, 0.0, 0.0]",
          when: str = "phase_time > 1") -> Path:
    path = tmp_path / "bad.toml"
    path.write_text(STAND.format(level=level, goal=goal, when=when))
    return path


def _cli_error(capsys, *argv: str) -> str:
    """Run the CLI; it must exit 2 with one line on stderr and nothing on stdout."""
    assert main(list(argv)) == 2
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("hqp: error: "), captured.err
    assert "Traceback" not in captured.err and captured.out == ""
    return lines[0]


# -- behavior-file expressions: bounded, checked at load ------------------------------------

@pytest.mark.parametrize(("when", "expected"), [
    ("phase_time > 9 ** 9 ** 9", "exponent"),
    ("+".join(["t"] * 1500), f"at most {MAX_LENGTH}"),
    ("+".join(["t"] * 3000), f"at most {MAX_LENGTH}"),
    ("-" * 900 + "t", "nested deeper"),
    ("+".join(["t"] * 300), "nested deeper"),
    ("'abc'", "constant 'abc' is not allowed"),
    ("t > 1 / 0", "division by zero"),
])
def test_an_unbounded_or_meaningless_expression_is_refused_at_load(tmp_path, when, expected):
    path = _file(tmp_path, when=when)
    start = time.perf_counter()
    with pytest.raises(BehaviorFileError, match=expected) as info:
        parse_behavior(path.read_text(), path=path)
    assert time.perf_counter() - start < 1.0
    assert str(info.value).startswith(f"{path}:24: phases.stand.transitions[0].when: ")


def test_an_exponent_read_at_run_time_is_bounded():
    expr = parse("phase_time ** input")
    with pytest.raises(ExpressionError, match="exponent"):
        expr.evaluate({"phase_time": 9.0, "input": 1e9})
    assert expr.evaluate({"phase_time": 2.0, "input": 3}) == 8.0


def test_a_toml_file_nested_too_deeply_is_a_behavior_file_error(tmp_path):
    for text in ("a = " + "[" * 5000 + "]" * 5000, "a = " + "{x = " * 3000 + "1" + "}" * 3000):
        with pytest.raises(BehaviorFileError, match="nested too deeply"):
            parse_behavior(text, path=tmp_path / "deep.toml")


# -- runtime inputs (JSON Lines) -------------------------------------------------------------

@pytest.mark.parametrize(("line", "expected"), [
    ('{"t": "soon", "goal": 1.0}', "'t' expected a finite time"),
    ('{"t": null, "goal": 1.0}', "'t' expected a finite time"),
    ('{"t": [1, 2], "goal": 1.0}', "'t' expected a finite time"),
    ('{"t": NaN, "goal": 1.0}', "'t' expected a finite time"),
    ('{"t": 0.0, "goal": [1, 2, 3]}', "goal expected shape"),
    ('{"t": 0.0, "goal": "abc"}', "goal expected shape"),
    ('{"t": 0.0, "goal": NaN}', "goal expected shape"),
    ('{"t": 0.0, "goal": ' + "[" * 5000 + "]" * 5000 + "}", "nested too deeply"),
])
def test_a_malformed_inputs_line_names_file_and_line(tmp_path, line, expected):
    path = tmp_path / "inputs.jsonl"
    path.write_text('{"t": 0.0, "goal": 0.5}\n' + line + "\n")
    specs = {"goal": InputSpec("goal", (), np.array(0.0), False, "")}
    with pytest.raises(InvalidInput, match=expected) as info:
        InputStream(specs, path).values(1.0)
    assert str(path) in str(info.value) and "2" in str(info.value)


def test_a_bad_line_late_in_the_inputs_file_fails_when_the_stream_opens(tmp_path):
    path = tmp_path / "inputs.jsonl"
    path.write_text('{"t": 0.0, "goal": 0.5}\n{"t": 1.0, "goal": 0.6}\n'
                    '{"t": 5.0, "goal": [1, 2]}\n')
    specs = {"goal": InputSpec("goal", (), np.array(0.0), False, "")}
    with pytest.raises(InvalidInput, match=f"{re.escape(str(path))}: line 3: goal expected"):
        InputStream(specs, path)


# -- checks that need the robot and the controller, still at load ---------------------------

@pytest.mark.parametrize(("level", "goal", "key", "expected"), [
    ("99", "[0.0, 0.0, 0.0]", "10: tasks.balance.level", "level 99 out of range"),
    ('"balance"', "[0.0, 0.0]", "15: tasks.trunk_upright.goal", "got shape (2,)"),
    ('"balance"', "[[2.0, 0, 0], [0, 1, 0], [0, 0, 1]]", "15: tasks.trunk_upright.goal",
     "not a rotation matrix"),
])
def test_a_level_or_goal_the_controller_refuses_fails_at_load(tmp_path, capsys, level, goal,
                                                               key, expected):
    path = _file(tmp_path, level=level, goal=goal)
    with pytest.raises(BehaviorFileError, match=re.escape(expected)) as info:
        prepare(path)
    assert str(info.value).startswith(f"{path}:{key}: ")
    assert expected in _cli_error(capsys, "run", str(path))


INPUT_GOAL = """\
[behavior]
initial = "reach"

[inputs.target]
default = [0.3, -0.2]

[tasks.hand]
type = "position"
frame = "right_hand"
goal = "input.target"

[phases.reach]
tasks = ["hand"]
contacts = ["left_foot", "right_foot"]
final = true
"""


def test_a_goal_fed_by_an_input_of_the_wrong_length_fails_at_load(tmp_path):
    path = tmp_path / "reach2.toml"
    path.write_text(INPUT_GOAL)
    with pytest.raises(BehaviorFileError, match=re.escape("tasks.hand.goal")) as info:
        prepare(path)
    assert str(info.value).startswith(f"{path}:10: ") and "(2,)" in str(info.value)
    path.write_text(INPUT_GOAL.replace("[0.3, -0.2]", "[0.3, -0.2, 1.0]"))
    prepare(path)  # the right length loads


@pytest.mark.parametrize("value", ["[1,2,3]", '"abc"', "NaN", "null", "true"])
def test_a_set_value_of_the_wrong_kind_is_refused(capsys, value):
    line = _cli_error(capsys, "run", "squat-jump", "--set", f"takeoff_height={value}")
    assert "input 'takeoff_height': expected finite numbers of shape []" in line
    with pytest.raises(InvalidInput, match="takeoff_height"):
        prepare("squat-jump", overrides={"takeoff_height": json.loads(value)})


@pytest.mark.parametrize("duration", ["nan", "inf", "-1", "0"])
def test_a_duration_that_is_not_positive_is_refused(capsys, duration):
    assert "--duration expects a positive number" in _cli_error(
        capsys, "run", "stand", "--duration", duration)
    with pytest.raises(InvalidInput, match="duration"):
        run_behavior("stand", duration=float(duration))


@pytest.mark.parametrize(("argv", "expected"), [
    (["--controller", "nullspace", "--backend", "gurobi"], "--backend applies to the HQP"),
    (["--backend", "gurobi"], "unknown backend 'gurobi'"),
    (["--set", "takeoff_height"], "--set expects INPUT=JSON"),
    (["--set", "takeoff_height=[1,"], "not JSON"),
])
def test_bad_run_options_are_one_line(capsys, argv, expected):
    assert expected in _cli_error(capsys, "run", "squat-jump", *argv)


def test_an_output_path_that_cannot_be_written_is_refused_before_the_run(tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("")
    for option in ("--plot", "--video"):
        assert "is not a folder" in _cli_error(capsys, "run", "stand", option,
                                               str(blocker / "run.png"))
        assert "is a folder" in _cli_error(capsys, "run", "stand", option, str(tmp_path))
    with pytest.raises(InvalidInput, match="is not a folder"):
        run_behavior("stand", plot=blocker / "run.png")


# -- the servo's entry ------------------------------------------------------------------------

@pytest.fixture(scope="module")
def standing():
    robot = robots.load("paper-humanoid")
    return robot, Simulator(robot).state()


def test_a_step_at_a_time_that_is_not_finite_is_refused(standing):
    robot, state = standing
    ctrl = standing_controller(robot)
    for t in (np.nan, np.inf):
        with pytest.raises(InvalidInput, match="finite time"):
            ctrl.step(state, t)


def test_the_base_quaternion_is_normalised_within_a_tolerance_and_refused_beyond(standing):
    robot, state = standing
    reference = standing_controller(robot).step(state, 0.0).tau
    near = state.q.copy()
    near[3:7] *= 1.0 + 5e-4
    tau = standing_controller(robot).step(type(state)(near, state.v), 0.0).tau
    np.testing.assert_allclose(tau, reference, atol=1e-9)
    ctrl = standing_controller(robot)
    for scale in (2.0, 0.0, 1.01):
        q = state.q.copy()
        q[3:7] *= scale
        with pytest.raises(InvalidInput, match="base quaternion"):
            ctrl.step(type(state)(q, state.v), 0.0)


# -- the solver's entry ------------------------------------------------------------------------

BACKENDS = ("proxsuite", "daqp", "native")


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_complex_level_is_refused(backend):
    rng = np.random.default_rng(1)
    A = rng.normal(size=(3, 5))
    with pytest.raises(InvalidLevel, match="level 0, field A: complex"):
        solve([Level(A=A + 1j * A, b=np.ones(3))], backend=backend)
    with pytest.raises(InvalidLevel, match="level 1, field b: complex"):
        solve([Level(A=A, b=np.ones(3)), Level(A=A, b=[1j, 0, 0])], backend=backend)


@pytest.mark.parametrize("backend", BACKENDS)
def test_bounds_beyond_1e20_are_absent_and_the_level_is_satisfied(backend):
    rng = np.random.default_rng(2)
    A, C = rng.normal(size=(3, 5)), rng.normal(size=(2, 5))
    huge = Level(C=C, lower=np.full(2, -1e300), upper=np.full(2, 1e300))
    solution = solve([huge, Level(A=A, b=np.ones(3))], backend=backend)
    assert solution.levels[0].satisfied and solution.levels[0].cost == 0.0
    assert solution.levels[1].cost < 1e-12
    with pytest.raises(InvalidLevel, match="lower bound above 1e\\+20"):
        solve([Level(C=C, lower=np.full(2, 1e300))], backend=backend)
    with pytest.raises(HQPError, match="beyond"):
        solve([Level(A=1e200 * A, b=np.ones(3))], backend=backend)


# -- terminal output: 100 columns, one number format per column -----------------------------

FIGURES = Path(__file__).resolve().parents[1] / "docs" / "figures"


@pytest.mark.parametrize("scenario", ["hand-reach", "obstacle", "box-grab", "screwgun"])
def test_the_compare_table_fits_100_columns_and_wide_shows_every_field(scenario):
    from comparisons.report import format_rows

    data = json.loads((FIGURES / f"{scenario}.json").read_text())
    narrow = format_rows(data["scenario"], data["robot"], data["runs"])
    assert max(len(line) for line in narrow.splitlines()) <= 100
    assert "more columns: --wide" in narrow
    wide = format_rows(data["scenario"], data["robot"], data["runs"], wide=True)
    header = wide.splitlines()[1]
    assert "x max [mm]" in header and len(header) > 100


def test_a_column_has_one_number_format():
    from hqp.tables import column_format, format_columns

    fmt = column_format([0.01, 5.37e-3, 2.0, 0.0])
    assert [fmt(v) for v in (0.01, 5.37e-3, 2.0, 0.0)] == ["0.01000", "0.00537", "2.00000", "0"]
    fmt = column_format([17.4, 0.0589, 439.0])
    assert [fmt(v) for v in (17.4, 0.0589)] == ["1.74e+01", "5.89e-02"]
    lines, left_out = format_columns(["name", "a", "b"], [["x", 1.0, 2.0]], width=10)
    assert left_out == ["b"] and all(len(line) <= 10 for line in lines)


def test_the_bench_table_fits_100_columns(capsys):
    from hqp.app.bench import format_narrow

    rows = [{"robot": "g1", "solver": "hqp/basis/daqp", "levels": 7, "n": 47, "rows": 148,
             "median_ms": 4.06, "p95_ms": 4.82, "cpu_median_ms": 4.07, "cost_excess": 4e-7,
             "over_nullspace": 1.08, "over_placo": 11.2, "over_placo_cpu": 11.2,
             "speedup_vs_cascade": 1.5, "ratio_to_basis_proxsuite": 0.75, "source": "stand",
             "suite": "controller"}]
    table = format_narrow({"suite": "controller", "rows": rows})
    assert max(len(line) for line in table.splitlines()) <= 100
    assert "--wide" in table.splitlines()[-1] and "hqp/basis/daqp" in table


# -- what a newcomer sees: no library noise ---------------------------------------------------

def test_hqp_run_walk_on_g1_prints_no_warning(capfd):
    assert main(["run", "walk", "--robot", "g1", "--duration", "0.01"]) == 0
    captured = capfd.readouterr()
    assert "WARNING" not in captured.err and "behavior walk on g1" in captured.out
    assert max(len(line) for line in captured.out.splitlines()) <= 100


def test_a_mujoco_gl_backend_that_cannot_load_is_one_line():
    import os
    import subprocess
    import sys

    env = {**os.environ, "MUJOCO_GL": "no-such-backend", "OMP_NUM_THREADS": "1"}
    proc = subprocess.run([sys.executable, "-m", "hqp.cli", "behaviors"], capture_output=True,
                          text=True, env=env, timeout=120)
    assert proc.returncode == 2 and proc.stdout == ""
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("hqp: error: MUJOCO_GL=no-such-backend")


def test_mp4_writing_is_a_dependency(tmp_path):
    import imageio.v2 as imageio

    frames = [np.full((32, 32, 3), 40 * k, dtype=np.uint8) for k in range(5)]
    path = tmp_path / "run.mp4"
    imageio.mimwrite(path, frames, fps=10)
    assert path.stat().st_size > 100


# -- figures ------------------------------------------------------------------------------------

def test_figures_show_values_without_an_offset_and_task_errors_on_a_log_axis(tmp_path,
                                                                           monkeypatch):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from hqp.plots import Line, Panel, plot_panels

    figures = []
    monkeypatch.setattr(plt, "close", figures.append)
    t = np.linspace(0.0, 1.0, 50)
    plot_panels([Panel("CoG height", "z [m]", t, (Line("CoG", 0.9211 + 1e-6 * t),)),
                 Panel("errors", "error", t, (Line("hand", np.exp(-5 * t)),), log=True)],
                tmp_path / "f.png")
    height, errors = figures[0].axes[:2]
    height.figure.canvas.draw()
    assert height.yaxis.get_major_formatter().get_offset() == ""
    assert errors.get_yscale() == "log"


@pytest.mark.slow
def test_hqp_run_reach_plots_the_hand_task(tmp_path, monkeypatch):
    from hqp.app import run as run_module

    drawn = {}

    def capture(panels, path, title=""):
        drawn["panels"] = panels
        return Path(path)

    monkeypatch.setattr(run_module, "plot_panels", capture)
    run_behavior("reach", duration=0.6, plot=tmp_path / "reach.png")
    errors = next(p for p in drawn["panels"] if p.title.startswith("Task errors"))
    assert {"hand", "balance", "posture"} <= {line.label for line in errors.lines}


@pytest.mark.slow
def test_hqp_compare_fits_100_columns_unless_wide(capsys):
    argv = ["compare", "hand-reach", "--duration", "0.01", "--controllers", "hqp"]
    assert main(argv) == 0
    narrow = capsys.readouterr().out.splitlines()
    assert max(len(line) for line in narrow) <= 100 and "--wide" in "\n".join(narrow)
    assert main([*argv, "--wide"]) == 0
    wide = capsys.readouterr().out.splitlines()
    assert max(len(line) for line in wide) > 100 and "x max [mm]" in wide[1]


def test_the_recorder_refuses_an_unknown_robot_and_an_unwritable_folder(tmp_path, capsys):
    from hqp.app import record

    blocker = tmp_path / "file"
    blocker.write_text("")
    for argv, expected in ((["--robot", "nope"], "unknown robot 'nope'"),
                           (["--out", str(blocker / "data")], "is not a folder")):
        assert record.main(argv) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and expected in err[0]


def test_the_progress_bar_draws_on_a_terminal_and_stays_off_elsewhere(monkeypatch):
    import io
    import sys

    from hqp.app.console import progress_bar

    class Terminal(io.StringIO):
        def isatty(self):
            return True

    for stream, drawn in ((Terminal(), True), (io.StringIO(), False)):
        monkeypatch.setattr(sys, "stderr", stream)
        with progress_bar("stand", "s", delay=0.0) as progress:
            for k in range(11):
                progress(0.3 * k, 3.0)
        assert ("stand:" in stream.getvalue() and "/3.0 s" in stream.getvalue()) is drawn


def test_hqp_behaviors_fits_100_columns(capsys):
    assert main(["behaviors"]) == 0
    out = capsys.readouterr().out
    assert "squat-jump" in out and max(len(line) for line in out.splitlines()) <= 100


@pytest.mark.slow
def test_the_figures_give_the_cog_error_in_mm_like_the_tables():
    from comparisons import get_scenario

    result = get_scenario("hand-reach").run(duration=0.2, controllers=["hqp"])
    run = next(r for r in result.runs if r.spec.hierarchy == "shared")
    panel = next(p for p in run.panels if p.title == "Balancing Error")
    assert panel.ylabel == "error [mm]"
    largest = np.hypot(panel.lines[0].y, panel.lines[1].y).max()
    assert largest > 0.1  # [mm]: the shared hierarchy lets the hand drag the CoG
    np.testing.assert_allclose(largest, run.row()["cog_error_max_mm"], rtol=1e-6)


def test_quadprog_fallbacks_are_counted_for_the_summary():
    from hqp.app.run import _summary
    from hqp.solver.backends import QPBackend
    from hqp.solver.qp import last_resort_count, solve_qp

    class Broken(QPBackend):
        name = "broken-for-count"

        def solve(self, slot, H, g, E, e, C, lo, up):
            return np.full(H.shape[0], np.nan), False

    before = last_resort_count()
    for _ in range(3):
        solve_qp(Broken(), ("count", 0), np.eye(2), np.zeros(2), None, None, np.eye(2),
                 -np.ones(2), np.ones(2))
    assert last_resort_count() - before == 3
    data = {"behavior": "b", "robot": "r", "controller": "hqp", "duration_s": 1.0,
            "fell": False, "fall_reason": None, "phases": ["p"], "steps": 0,
            "flight_time_s": 0.0, "max_torque_ratio": 0.1, "max_torque_jump_nm": 0.0,
            "feasibility_events": [], "qp_fallbacks": 3}
    summary = _summary(data)
    assert "QP fallbacks: quadprog solved 3 level QP(s)" in summary
    assert max(len(line) for line in summary.splitlines()) <= 100
