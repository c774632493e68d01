"""TSID's control step on the standing task set, for the controller suite (a worker process).

:class:`TsidStanding` starts :mod:`hqp.bench.tsid_worker` with the interpreter of TSID's own
environment (``python -m hqp.bench.peer_env tsid`` makes it; :func:`hqp.bench.worker.start`),
sends it the robot (URDF, standing configuration, soles, limits, the standing controllers'
gains) and then one request per control step. The worker times its own step (TSID's problem
data, solve, torques), so the suite's ``tsid`` row does not count the pipe; the round trip is
kept apart (``worker.round_trip``).

Same task set as :func:`hqp.control.presets.standing_controller` where TSID can express it:
soles as rigid ``Contact6d`` (friction 0.8 x the sole's, normal force at least 0, corners
within 0.9 x the sole), centre of mass over the centre of the feet (kp 100), trunk
orientation (kp 100), standing posture (kp 50), torque limits and TSID's own viable joint
position/velocity/acceleration bounds (``TaskJointPosVelAccBounds``, the Del Prete bounds hqp's
joint-limit level follows too, with the same acceleration bound). TSID has two levels: the
contacts and bounds are its level 0, the centre of mass, trunk and posture weighted tasks of
its level 1 (weights 1, 1, 1e-2, as PlaCo's row): the centre of mass cannot be strictly above
the posture, and the posture has one weight for all its joints.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from hqp.bench.worker import start_setup
from hqp.robots import Robot
from hqp.tasks.joint_limits import max_acceleration_from_torques

WORKER = Path(__file__).with_name("tsid_worker.py")
"""The worker script (run by TSID's interpreter, imports nothing of hqp)."""

GAINS = {"com": 100.0, "trunk": 100.0, "posture": 50.0, "contact": 0.0}
"""Stiffness of the tasks [1/s^2] (critically damped in the worker), as the standing controllers."""
WEIGHTS = {"com": 1.0, "trunk": 1.0, "posture": 1e-2, "force_regularization": 1e-5}
"""Weights of TSID's level-1 tasks, and of its contact-force regularisation."""


def setup_message(robot: Robot, dt: float = 1e-3) -> dict[str, Any]:
    """Return the ``setup`` request of a robot (protocol of :mod:`hqp.bench.tsid_worker`)."""
    model = robot.model()
    model.update(robot.q_standing, np.zeros(model.nv))
    feet = [model.frame_placement(robot.contact(f).frame).translation for f in robot.feet]
    center = np.mean(feet, axis=0)
    qdd_max = np.clip(max_acceleration_from_torques(model, margin=0.5), 5.0, 50.0)
    return {
        "op": "setup",
        "urdf": str(robot.urdf_path),
        "q": robot.q_standing.tolist(),
        "dt": dt,
        "feet": [{"frame": robot.contact(f).frame,
                  "half_length": 0.9 * robot.contact(f).half_length,
                  "half_width": 0.9 * robot.contact(f).half_width,
                  "mu": 0.8 * robot.contact(f).friction, "f_min": 0.0, "f_max": 1e4}
                 for f in robot.feet],
        "trunk": "trunk",
        "com_goal": [float(center[0]), float(center[1]), float(model.com[2])],
        "tau_max": model.tau_max.tolist(),
        "q_lower": model.q_lower.tolist(),
        "q_upper": model.q_upper.tolist(),
        "v_max": model.v_max.tolist(),
        "a_max": qdd_max.tolist(),
        "gains": GAINS,
        "weights": WEIGHTS,
    }


class TsidStanding:
    """TSID holding a humanoid on both feet, in a worker process (module docstring).

    Args:
        robot: The bundled robot (TSID loads its URDF).
        dt: Control period [s].
        python: TSID's interpreter (default: :func:`hqp.bench.peer_env.env_python`).

    Raises:
        PeerUnavailable: TSID's environment is missing or cannot run the worker.
        WorkerError: The worker could not set the robot up.

    """

    def __init__(self, robot: Robot, dt: float = 1e-3, python: Path | None = None) -> None:
        self.worker, info = start_setup("tsid", WORKER, setup_message(robot, dt), python)
        self.tsid_version: str = info["tsid_version"]
        self.pinocchio_version: str = info["pinocchio_version"]
        self.wall: list[float] = []
        """Wall-clock time of each step in the worker [s]."""
        self.cpu: list[float] = []
        """CPU time of each step in the worker [s]."""
        self.failures = 0
        """Steps whose QP TSID could not solve."""
        self.t = 0.0

    def step(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """One control step at ``(q, v)``; return the actuated torques ``(na,)`` [N m]."""
        reply = self.worker.request({"op": "step", "q": np.asarray(q).tolist(),
                                     "v": np.asarray(v).tolist(), "t": self.t})
        self.t += 1e-3
        self.wall.append(float(reply["wall_s"]))
        self.cpu.append(float(reply["cpu_s"]))
        self.failures += 0 if reply["success"] else 1
        return np.asarray(reply["tau"])

    def close(self) -> None:
        """Stop the worker."""
        self.worker.close()
