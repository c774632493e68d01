"""PlaCo's ``DynamicsSolver`` on the standing task set, for the controller benchmark.

The same tasks as :func:`hqp.controller.standing_stack` (both soles in contact, centre of
mass over the centre of the feet, trunk upright, the standing posture, torque and joint
limits), expressed with PlaCo's two priorities: the dynamics, the planar contacts (unilateral,
friction, centre of pressure in the soles), the torque limits and the joint limits are PlaCo's
constraints; the centre of mass is a ``hard`` task (PlaCo's strict priority, what hqp's
balance level is above the operational and posture levels); the trunk orientation and the
posture are ``soft`` tasks with weights (1 and :data:`POSTURE_WEIGHT`): PlaCo cannot put one
strictly below the other.

One step (:meth:`PlacoStanding.step`) is the work a control step does: set the state, update
PlaCo's model (``update_kinematics``), build its task rows and solve (``solve``). PlaCo loads
the robot's URDF (:attr:`hqp.robots.Robot.urdf_path`); joint, velocity and torque limits are
set to the controller model's so that both solvers see the same limits.
"""

from __future__ import annotations

import numpy as np

from hqp.robots import Robot

POSTURE_WEIGHT = 1e-2
"""Weight of PlaCo's soft posture task (the trunk orientation has weight 1)."""


class PlacoStanding:
    """PlaCo's ``DynamicsSolver`` holding a humanoid on both feet.

    Args:
        robot: The bundled robot (its URDF is loaded by PlaCo).
        dt: Control period [s].
        com_kp: Stiffness of the centre-of-mass task [1/s^2] (as in ``standing_stack``).
        orientation_kp: Stiffness of the trunk orientation task [1/s^2].
        posture_kp: Stiffness of the posture task [1/s^2].
        friction: Friction coefficient of the contacts (default: 0.8 x the sole's, as hqp).
        sole_margin: Fraction of the sole's length and width given to the centre of pressure.

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
    ) -> None:
        import placo

        self.robot = robot
        model = robot.model()
        self.wrapper = placo.RobotWrapper(str(robot.urdf_path), placo.Flags.ignore_collisions)
        w = self.wrapper
        names = list(model.joint_names)
        lo, hi = model.q_lower, model.q_upper
        for i, name in enumerate(names):
            w.set_joint_limits(name, float(lo[i]), float(hi[i]))
            w.set_velocity_limit(name, float(model.v_max[i]))
            w.set_torque_limit(name, float(model.tau_max[i]))
        q0 = np.asarray(robot.q_standing, dtype=float)
        if q0.shape != w.state.q.shape:
            raise ValueError(
                f"PlacoStanding: PlaCo's model of {robot.name} has nq = {w.state.q.size}, "
                f"hqp's standing configuration {q0.size}"
            )
        w.state.q = q0.copy()
        w.state.qd = np.zeros(w.state.qd.size)
        w.update_kinematics()
        solver = placo.DynamicsSolver(w)
        solver.dt = float(dt)
        solver.mask_fbase(False)
        solver.enable_torque_limits(True)
        solver.enable_joint_limits(True)
        solver.enable_velocity_limits(True)
        self.contacts = []
        for foot in robot.feet:
            surface = robot.contact(foot)
            task = solver.add_frame_task(surface.frame, w.get_T_world_frame(surface.frame))
            task.configure(surface.frame, "hard", 1.0, 1.0)
            contact = solver.add_planar_contact(task)
            contact.length = 2.0 * sole_margin * surface.half_length
            contact.width = 2.0 * sole_margin * surface.half_width
            contact.mu = 0.8 * surface.friction if friction is None else friction
            self.contacts.append(contact)
        # centre of mass over the centre of the feet, at its standing height
        feet = np.mean([w.get_T_world_frame(robot.contact(f).frame)[:3, 3] for f in robot.feet],
                       axis=0)
        com = w.com_world()
        self.com = solver.add_com_task(np.array([feet[0], feet[1], com[2]]))
        self.com.configure("com", "hard", 1.0)
        self.com.kp = com_kp
        self.trunk = solver.add_orientation_task("trunk", w.get_T_world_frame("trunk")[:3, :3])
        self.trunk.configure("trunk", "soft", 1.0)
        self.trunk.kp = orientation_kp
        self.posture = solver.add_joints_task()
        self.posture.set_joints({name: float(w.get_joint(name)) for name in names})
        self.posture.configure("posture", "soft", POSTURE_WEIGHT)
        self.posture.kp = posture_kp
        self.solver = solver
        self.nq = q0.size

    def step(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """One control step at state ``(q, v)``: model update, rows, solve.

        Args:
            q: Configuration ``(nq,)`` (pinocchio convention).
            v: Velocity ``(nv,)``.

        Returns:
            The actuated torques ``(na,)`` [N m] PlaCo computes.

        """
        w = self.wrapper
        w.state.q = q
        w.state.qd = v
        w.update_kinematics()
        result = self.solver.solve(False)
        return np.asarray(result.tau)[6:]

    def last_success(self) -> bool:
        """Whether the last solve succeeded (a fresh solve at the current state)."""
        return bool(self.solver.solve(False).success)
