"""PlaCo as a peer: its environment, its worker (``hqp/bench/placo_worker.py``) and its clients.

The live tests run PlaCo's worker in its own environment (``python -m hqp.bench.peer_env
placo``, made by ``.ci/run`` before the tests) and skip, saying so, where it is absent. The
paths without it (what ``hqp compare`` and ``hqp bench`` do then) run everywhere, against an
environment folder that does not exist.
"""

from __future__ import annotations

import io
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from hqp.bench import peer_env
from hqp.bench.placo_step import WORKER, PlacoStanding, standing_setup
from hqp.bench.worker import PeerUnavailable, WorkerError, start
from hqp.errors import UnknownName
from hqp.robots import load

ROOT = Path(__file__).resolve().parents[1]
ABSENT = peer_env.usable("placo")
live = pytest.mark.skipif(ABSENT is not None, reason=f"PlaCo's environment is absent "
                          f"(python -m hqp.bench.peer_env placo): {ABSENT}")
COMMAND = "python -m hqp.bench.peer_env placo"


@pytest.fixture
def no_placo(monkeypatch, tmp_path):
    """PlaCo's environment pointed at a folder that does not exist; no installing."""
    monkeypatch.setenv("HQP_PLACO_ENV", str(tmp_path / "no-placo"))
    monkeypatch.setenv("HQP_NO_PEER_INSTALL", "1")


# -- without PlaCo's environment ---------------------------------------------------------------

def test_the_environment_follows_its_variable_and_says_how_to_make_it(monkeypatch, tmp_path):
    monkeypatch.setenv("HQP_PLACO_ENV", str(tmp_path / "env"))
    assert peer_env.env_dir("placo") == tmp_path / "env"
    assert peer_env.env_python("placo") == tmp_path / "env" / "bin" / "python"
    monkeypatch.delenv("HQP_PLACO_ENV")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    assert peer_env.env_dir("placo") == tmp_path / "cache" / "hqp" / "placo-venv"
    reason = peer_env.usable("placo")
    assert reason is not None and COMMAND in reason
    with pytest.raises(PeerUnavailable, match=COMMAND):
        PlacoStanding(load("g1"))
    assert peer_env.PEERS["placo"].requirements[:3] == (
        "placo==0.10.2", "pin==3.8.0", "cmeel-urdfdom==4.0.1")


def test_an_unknown_peer_lists_the_peers():
    with pytest.raises(UnknownName, match="placo, tsid"):
        peer_env.env_dir("crocoddyl")


def test_ensure_installs_once_with_a_notice_unless_told_not_to(no_placo, monkeypatch):
    made: list[Path] = []

    def fake_create(name, folder=None, *, quiet=False):
        made.append(folder)
        monkeypatch.setattr(peer_env, "usable", lambda *a, **k: None)
        return folder / "bin" / "python"

    monkeypatch.setattr(peer_env, "create", fake_create)
    reason = peer_env.ensure("placo", io.StringIO())  # HQP_NO_PEER_INSTALL=1: not made
    assert reason is not None and "HQP_NO_PEER_INSTALL" in reason and COMMAND in reason
    assert made == []
    monkeypatch.delenv("HQP_NO_PEER_INSTALL")
    notice = io.StringIO()
    assert peer_env.ensure("placo", notice) is None
    assert made == [peer_env.env_dir("placo")]
    lines = notice.getvalue().splitlines()
    assert len(lines) == 1, lines
    assert lines[0].startswith("hqp: making PlaCo's environment once in ")
    assert lines[0].endswith(" s") and "done in" in lines[0]
    assert peer_env.ensure("placo", notice) is None and len(made) == 1  # usable: nothing to do


def test_ensure_reports_a_failed_install_with_the_command(no_placo, monkeypatch):
    def offline(name, folder=None, *, quiet=False):
        raise PeerUnavailable("pip install of PlaCo failed (exit 1): no network")

    monkeypatch.setattr(peer_env, "create", offline)
    monkeypatch.delenv("HQP_NO_PEER_INSTALL")
    notice = io.StringIO()
    reason = peer_env.ensure("placo", notice)
    assert reason is not None and "no network" in reason and COMMAND in reason
    assert "failed after" in notice.getvalue()


def test_a_scenario_lists_placo_as_skipped_without_its_environment(no_placo):
    from comparisons import get_scenario
    from comparisons.report import format_table

    messages: list[str] = []
    result = get_scenario("hand-reach").run(controllers=["placo"], duration=0.01,
                                            progress=messages.append)
    payload = result.to_json()
    assert payload["runs"] == []
    (entry,) = payload["skipped"]
    assert entry["controller"] == "placo" and entry["hierarchies"] == ["shared", "cog-first"]
    assert COMMAND in entry["skipped"]
    assert sum("placo skipped" in m for m in messages) == 1
    assert "skipped (placo, shared, cog-first)" in format_table(result)


def test_hqp_compare_json_lists_placo_as_skipped_and_stdout_is_pure_json(tmp_path):
    env = {**os.environ, "HQP_PLACO_ENV": str(tmp_path / "no-placo"),
           "HQP_NO_PEER_INSTALL": "1", "PYTHONPATH": str(ROOT)}
    proc = subprocess.run([sys.executable, "-m", "hqp.cli", "compare", "hand-reach", "--json",
                           "--duration", "0.01", "--controllers", "hqp", "placo"],
                          capture_output=True, text=True, env=env, timeout=300, cwd=ROOT)
    assert proc.returncode == 0, proc.stderr
    payload = json.loads(proc.stdout)
    assert {r["controller"] for r in payload["runs"]} == {"hqp"}
    assert payload["skipped"][0]["controller"] == "placo"
    assert COMMAND in payload["skipped"][0]["skipped"]
    assert "making PlaCo's environment" not in proc.stderr


def test_the_controller_suite_lists_placo_as_skipped(no_placo):
    from hqp.bench.suite_controller import run_robot

    rows = run_robot("g1", ["placo"], quick=True)
    assert len(rows) == 1 and rows[0]["solver"] == "placo" and rows[0]["median_ms"] is None
    assert COMMAND in rows[0]["skipped"]


# -- the live worker ---------------------------------------------------------------------------

@live
def test_worker_protocol_against_placo():
    worker = start("placo", WORKER)
    try:
        assert worker.request({"op": "hello"}) == {"ok": True}
        with pytest.raises(WorkerError, match="step before setup"):
            worker.request({"op": "step", "q": [0.0], "v": [0.0]})
        with pytest.raises(WorkerError, match="unknown op 'jump'"):
            worker.request({"op": "jump"})
        with pytest.raises(WorkerError, match="KeyError"):
            worker.request({"op": "setup"})
        robot = load("g1")
        setup = standing_setup(robot)
        wrong = {**setup, "joints": list(reversed(setup["joints"]))}
        with pytest.raises(WorkerError, match="same names in the same order"):
            worker.request(wrong)
        bad = {**setup, "tasks": [{**setup["tasks"][0], "kind": "gaze"}]}
        with pytest.raises(WorkerError, match="unknown kind 'gaze'"):
            worker.request(bad)
        info = worker.request(setup)
        assert info["placo_version"] == "0.10.2" and info["pinocchio_version"].startswith("3.8")
        assert info["nq"] == robot.model().nq
        assert worker.request({"op": "quit"}) == {"ok": True}
        worker.proc.wait(timeout=10)
        assert worker.proc.returncode == 0
    finally:
        worker.close()


@live
@pytest.mark.parametrize("name", ["paper-humanoid", "g1", "talos"])
def test_placo_loads_the_urdf(name: str) -> None:
    """PlaCo's model of the robot's URDF (pinocchio 3.8, in the worker) has hqp's kinematics
    and centre of mass (pinocchio 4) at the standing configuration."""
    robot = load(name)
    placo = PlacoStanding(robot)
    try:
        frames = ("trunk", *(robot.contact(f).frame for f in robot.feet))
        reply = placo.worker.request({"op": "placements", "frames": list(frames)})
    finally:
        placo.close()
    model = robot.model()
    model.update(robot.q_standing, np.zeros(model.nv))
    for frame in frames:
        np.testing.assert_allclose(np.array(reply["T"][frame]),
                                   model.frame_placement(frame).homogeneous, atol=1e-9)
    np.testing.assert_allclose(reply["com"], model.com, atol=1e-9)


@live
def test_placo_standing_holds_the_robot_and_times_its_own_step():
    robot = load("g1")
    model = robot.model()
    placo = PlacoStanding(robot)
    try:
        for _ in range(3):
            tau = placo.step(robot.q_standing, np.zeros(model.nv))
        assert placo.failures == 0 and placo.last_success()
        assert placo.placo_version == "0.10.2"
        assert tau.shape == (model.na,) and np.all(np.isfinite(tau))
        assert np.all(np.abs(tau) <= model.tau_max + 1e-6)
        assert np.abs(tau).max() > 1.0  # gravity needs leg torques
        # the worker timed its own step; the round trip (pipe included) is longer
        assert len(placo.wall) == 3 and 0.0 < placo.wall[-1] < 0.1
        assert placo.worker.round_trip[-1] > placo.wall[-1]
    finally:
        placo.close()
    assert placo.worker.proc.poll() == 0


@live
def test_placo_controller_meets_its_hard_task_with_hqps_reference():
    """cog-first: the centre of gravity is PlaCo's hard task, its acceleration hqp's PD
    reference; at rest PlaCo's accelerations give exactly that acceleration (pinocchio 4's
    centre-of-mass Jacobian of the same robot)."""
    from comparisons import get_scenario
    from comparisons.placo_runner import PlacoController
    from hqp.model import RobotState

    scenario = get_scenario("hand-reach")
    spec = next(s for s in scenario.specs(["placo"]) if s.hierarchy == "cog-first")
    robot, model, hierarchy, _ = scenario.build("paper-humanoid", spec)
    controller = PlacoController(robot, hierarchy)
    try:
        q = robot.q_standing.copy()
        q[7:] += 0.05  # off the goal: a nonzero reference
        q[7:] = np.clip(q[7:], model.q_lower, model.q_upper)
        state = RobotState(q, np.zeros(model.nv), 0.0)
        refs = controller.references(state, 0.0)
        cmd = controller.step(state, 0.0)
    finally:
        controller.close()
    assert controller.hard_levels == ["cog"]
    assert not cmd.safe_mode and cmd.tau.shape == (model.na,)
    cog = next(t for t, kind in controller._tracked if kind == "com")
    acc = np.asarray(refs[cog.name]["acceleration"])[:2]
    assert np.linalg.norm(acc) > 1e-3
    pm = model.model
    J = pin.jacobianCenterOfMass(pm, pm.createData(), q)
    np.testing.assert_allclose(J[:2] @ cmd.qdd, acc, atol=1e-6)
    assert cmd.timings["placo"] > 0.0 and cmd.timings["total"] >= cmd.timings["placo"]


@live
def test_a_posture_goal_change_reaches_placo_once():
    """``screwgun`` switches the posture's goal mid-run: PlaCo's joints task follows it (sent
    once, at the step it changed) and PlaCo's accelerations change with it."""
    from comparisons import get_scenario
    from comparisons.placo_runner import PlacoController
    from hqp.model import RobotState

    scenario = get_scenario("hand-reach")
    spec = next(s for s in scenario.specs(["placo"]) if s.hierarchy == "cog-first")
    robot, model, hierarchy, _ = scenario.build("paper-humanoid", spec)
    posture = hierarchy.levels[-1][1][0]
    controller = PlacoController(robot, hierarchy)
    try:
        state = RobotState(robot.q_standing.copy(), np.zeros(model.nv), 0.0)
        assert posture.name not in controller.references(state, 0.0)
        before = controller.step(state, 0.0).qdd
        goal = np.array(posture.goal_at(0.0).position) + 0.2
        posture.set_goal(goal)
        refs = controller.references(state, 0.0)
        assert list(refs[posture.name]["joints"].values()) == pytest.approx(goal.tolist())
        assert posture.name not in controller.references(state, 0.0)  # sent once
        posture.set_goal(goal - 0.1)
        after = controller.step(state, 0.0)
    finally:
        controller.close()
    assert not after.safe_mode
    assert np.abs(after.qdd - before).max() > 1e-6
