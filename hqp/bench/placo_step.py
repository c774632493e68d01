"""PlaCo's ``DynamicsSolver`` on the standing task set, for the controller benchmark.

PlaCo runs in a worker process of its own environment (:mod:`hqp.bench.placo_worker`;
``python -m hqp.bench.peer_env placo`` makes it): :class:`PlacoStanding` sends it the robot
and the task set once, then one request per control step. The worker times its own step, so
the suite's ``placo`` row does not count the pipe; the round trip is kept apart
(``worker.round_trip``).

The same tasks as :func:`hqp.control.presets.standing_controller` (both soles in contact,
centre of mass over the centre of the feet, trunk upright, the standing posture, torque and
joint limits), expressed with PlaCo's two priorities: the dynamics, the planar contacts
(unilateral, friction, centre of pressure in the soles), the torque limits and the joint
limits are PlaCo's constraints; the centre of mass is a ``hard`` task (PlaCo's strict
priority, what hqp's balance level is above the operational and posture levels); the trunk
orientation and the posture are ``soft`` tasks with weights (1 and :data:`POSTURE_WEIGHT`):
PlaCo cannot put one strictly below the other.

One step (:meth:`PlacoStanding.step`) is the work a control step does: set the state, update
PlaCo's model (``update_kinematics``), build its task rows and solve (``solve``). PlaCo loads
the robot's URDF (:attr:`hqp.robots.Robot.urdf_path`); joint, velocity and torque limits are
set to the controller model's so that both solvers see the same limits.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from hqp.bench.worker import start_setup
from hqp.robots import Robot

WORKER = Path(__file__).with_name("placo_worker.py")
"""PlaCo's worker script (run by PlaCo's interpreter, imports nothing of hqp)."""

POSTURE_WEIGHT = 1e-2
"""Weight of PlaCo's soft posture task (the trunk orientation has weight 1)."""


def standing_setup(robot: Robot, dt: float = 0.001, *, com_kp: float = 100.0,
                   orientation_kp: float = 100.0, posture_kp: float = 50.0,
                   friction: float | None = None, sole_margin: float = 0.9) -> dict[str, Any]:
    """Return the worker's ``setup`` request of the standing task set (:class:`PlacoStanding`).

    The centre of mass's goal is the centre of the feet at the standing configuration, at
    PlaCo's own centre-of-mass height (``null``: the worker fills it in).
    """
    model = robot.model()
    q0 = np.asarray(robot.q_standing, dtype=float)
    model.update(q0, np.zeros(model.nv))
    feet = np.mean([model.frame_placement(robot.contact(f).frame).translation
                    for f in robot.feet], axis=0)
    contacts = []
    for foot in robot.feet:
        surface = robot.contact(foot)
        contacts.append({
            "frame": surface.frame, "name": surface.frame,
            "length": 2.0 * sole_margin * surface.half_length,
            "width": 2.0 * sole_margin * surface.half_width,
            "mu": 0.8 * surface.friction if friction is None else float(friction),
            "weight_moments": None,
        })
    task = {"frame": None, "kd": None, "target": None, "mask": None}
    return {
        "op": "setup", "urdf": str(robot.urdf_path), "ignore_collisions": True,
        "dt": float(dt), "q": q0.tolist(), "joints": list(model.joint_names),
        "q_lower": model.q_lower.tolist(), "q_upper": model.q_upper.tolist(),
        "v_max": model.v_max.tolist(), "tau_max": model.tau_max.tolist(), "qdd_safe": None,
        "joint_limits": True, "velocity_limits": True, "torque_limits": True,
        "contacts": contacts,
        "tasks": [
            {**task, "name": "com", "kind": "com", "priority": "hard", "weight": 1.0,
             "kp": float(com_kp), "target": [float(feet[0]), float(feet[1]), None]},
            {**task, "name": "trunk", "kind": "orientation", "frame": "trunk",
             "priority": "soft", "weight": 1.0, "kp": float(orientation_kp)},
            {**task, "name": "posture", "kind": "joints", "priority": "soft",
             "weight": POSTURE_WEIGHT, "kp": float(posture_kp)},
        ],
    }


class PlacoStanding:
    """PlaCo's ``DynamicsSolver`` holding a humanoid on both feet, in a worker process.

    Args:
        robot: The bundled robot (its URDF is loaded by PlaCo).
        dt: Control period [s].
        com_kp: Stiffness of the centre-of-mass task [1/s^2] (as in ``standing_stack``).
        orientation_kp: Stiffness of the trunk orientation task [1/s^2].
        posture_kp: Stiffness of the posture task [1/s^2].
        friction: Friction coefficient of the contacts (default: 0.8 x the sole's, as hqp).
        sole_margin: Fraction of the sole's length and width given to the centre of pressure.
        python: PlaCo's interpreter (default: :func:`hqp.bench.peer_env.env_python`).

    Raises:
        PeerUnavailable: PlaCo's environment is missing or cannot run the worker.
        WorkerError: The worker could not set the robot up.

    """

    def __init__(
        self,
        robot: Robot,
        dt: float = 0.001,
        *,
        com_kp: float = 100.0,
        orientation_kp: float = 100.0,
        posture_kp: float = 50.0,
        friction: float | None = None,
        sole_margin: float = 0.9,
        python: Path | None = None,
    ) -> None:
        setup = standing_setup(robot, dt, com_kp=com_kp, orientation_kp=orientation_kp,
                               posture_kp=posture_kp, friction=friction,
                               sole_margin=sole_margin)
        self.robot = robot
        self.worker, info = start_setup("placo", WORKER, setup, python)
        self.placo_version: str = info["placo_version"]
        self.pinocchio_version: str = info["pinocchio_version"]
        self.nq: int = info["nq"]
        self.wall: list[float] = []
        """Wall-clock time of each step in the worker [s]."""
        self.cpu: list[float] = []
        """CPU time of each step in the worker [s]."""
        self.failures = 0
        """Steps whose QP PlaCo could not solve."""
        self.success = True
        """Whether the last step's solve succeeded."""

    def step(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """One control step at state ``(q, v)``: model update, rows, solve.

        Args:
            q: Configuration ``(nq,)`` (pinocchio convention).
            v: Velocity ``(nv,)``.

        Returns:
            The actuated torques ``(na,)`` [N m] PlaCo computes (zero if its solve failed).

        """
        reply = self.worker.request({"op": "step", "q": np.asarray(q, dtype=float).tolist(),
                                     "v": np.asarray(v, dtype=float).tolist()})
        self.wall.append(float(reply["wall_s"]))
        self.cpu.append(float(reply["cpu_s"]))
        self.success = bool(reply["success"])
        self.failures += 0 if self.success else 1
        return np.asarray(reply["tau"])

    def last_success(self) -> bool:
        """Whether the last step's solve succeeded."""
        return self.success

    def close(self) -> None:
        """Stop the worker."""
        self.worker.close()
