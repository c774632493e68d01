"""TSID's worker (``hqp/bench/tsid_worker.py``), the peers' pipe client and their environments.

The protocol is tested with the worker run by hqp's own interpreter, ``tsid`` replaced by an
empty module (TSID's wheel cannot be installed beside hqp): requests, error replies, quitting,
a dead worker. The live TSID step runs only where its environment exists
(``python -m hqp.bench.peer_env tsid``).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from hqp.bench import peer_env
from hqp.bench.tsid_step import WORKER, TsidStanding, setup_message
from hqp.bench.worker import PeerUnavailable, Worker, WorkerError, start
from hqp.robots import load

FAKE_TSID = ("import runpy, sys, types\n"
             "fake = types.ModuleType('tsid'); fake.RobotWrapper = object\n"
             "sys.modules['tsid'] = fake\n"
             f"runpy.run_path({str(WORKER)!r}, run_name='__main__')\n")
"""The worker with an empty ``tsid`` module: its protocol without TSID."""


@pytest.fixture
def fake_worker():
    worker = Worker([sys.executable, "-c", FAKE_TSID])
    yield worker
    worker.close()


def test_worker_protocol_replies_and_errors(fake_worker):
    assert fake_worker.request({"op": "hello"}) == {"ok": True}
    with pytest.raises(WorkerError, match="step before setup"):
        fake_worker.request({"op": "step", "q": [0.0], "v": [0.0]})
    with pytest.raises(WorkerError, match="unknown op 'jump'"):
        fake_worker.request({"op": "jump"})
    with pytest.raises(WorkerError, match="KeyError"):  # a setup without its fields
        fake_worker.request({"op": "setup"})
    assert fake_worker.request({"op": "quit"}) == {"ok": True}
    fake_worker.proc.wait(timeout=10)
    assert fake_worker.proc.returncode == 0
    with pytest.raises(WorkerError, match="worker died"):
        fake_worker.request({"op": "quit"})


def test_a_worker_that_dies_is_reported():
    worker = Worker([sys.executable, "-c", "import sys; sys.exit('no tsid here')"])
    with pytest.raises(WorkerError, match="no tsid here"):
        worker.request({"op": "quit"})
    worker.close()


def test_setup_message_carries_the_standing_task_set():
    robot = load("g1")
    model = robot.model()
    msg = setup_message(robot)
    assert msg["op"] == "setup" and msg["urdf"] == str(robot.urdf_path)
    assert len(msg["q"]) == model.nq and len(msg["tau_max"]) == model.na
    assert len(msg["a_max"]) == model.na and min(msg["a_max"]) >= 5.0
    assert [f["frame"] for f in msg["feet"]] == [robot.contact(f).frame for f in robot.feet]
    for foot, name in zip(msg["feet"], robot.feet):
        assert foot["half_length"] == pytest.approx(0.9 * robot.contact(name).half_length)
        assert foot["mu"] == pytest.approx(0.8 * robot.contact(name).friction)


def test_a_missing_environment_says_how_to_make_it(tmp_path):
    reason = peer_env.usable("tsid", tmp_path / "none")
    assert reason is not None and "python -m hqp.bench.peer_env tsid" in reason
    with pytest.raises(PeerUnavailable, match="python -m hqp.bench.peer_env tsid"):
        TsidStanding(load("g1"), python=tmp_path / "none" / "bin" / "python")


def test_an_environment_that_cannot_run_the_worker_is_unavailable(tmp_path):
    """A worker that dies before answering ``hello`` (its environment lacks the peer): the
    peer is unavailable, and the message says how to re-create the environment."""
    script = tmp_path / "worker.py"
    script.write_text("import sys\nsys.exit('ModuleNotFoundError: no peer here')\n")
    with pytest.raises(PeerUnavailable, match="no peer here.*python -m hqp.bench.peer_env tsid"):
        start("tsid", script, python=Path(sys.executable))


def test_env_dir_follows_the_variable(monkeypatch, tmp_path):
    monkeypatch.setenv("HQP_TSID_ENV", str(tmp_path / "env"))
    assert peer_env.env_dir("tsid") == tmp_path / "env"
    assert peer_env.env_python("tsid") == tmp_path / "env" / "bin" / "python"


@pytest.mark.skipif(peer_env.usable("tsid") is not None,
                    reason="TSID's environment is absent (python -m hqp.bench.peer_env tsid)")
def test_live_tsid_holds_the_standing_configuration():
    """At rest on both feet, TSID's torques make the contact wrenches carry the weight."""
    robot = load("g1")
    model = robot.model()
    tsid = TsidStanding(robot)
    try:
        tau = tsid.step(robot.q_standing, np.zeros(model.nv))
        assert tsid.failures == 0 and tsid.tsid_version
        assert tau.shape == (model.na,) and np.all(np.isfinite(tau))
        assert np.all(np.abs(tau) <= model.tau_max + 1e-6)
        # gravity needs nonzero leg torques; the worker timed its own step
        assert np.abs(tau).max() > 1.0 and 0.0 < tsid.wall[-1] < 0.1
    finally:
        tsid.close()
