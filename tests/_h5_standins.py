"""Stand-in tasks and a sample floating-base humanoid for the stack and controller tests."""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from hqp.model import RobotModel
from hqp.tasks.base import Category, Rows, Task


class PostureStandIn(Task):
    """``qdd_a = kp (q0 - q) - kd v`` over the actuated joints."""

    category = Category.POSTURE

    def __init__(self, name: str, q0: np.ndarray, kp: float = 100.0, kd: float = 20.0,
                 weight: float = 1.0) -> None:
        super().__init__(name, weight)
        self.q0, self.kp, self.kd = np.array(q0), kp, kd

    def rows(self, m, layout, dt, t):
        A = np.zeros((m.na, layout.n))
        A[:, m.actuated] = np.eye(m.na)
        b = self.kp * (self.q0[m.actuated_q] - m.q[m.actuated_q]) - self.kd * m.v[m.actuated]
        return Rows(A=A, b=b)


class ComStandIn(Task):
    """Horizontal centre of mass: ``J_xy qdd + drift = kp (c0 - c) - kd dc``."""

    category = Category.BALANCE

    def __init__(self, name: str, goal, kp: float = 100.0, kd: float = 20.0,
                 axes: slice = slice(0, 2), weight: float = 1.0) -> None:
        super().__init__(name, weight)
        self.goal, self.kp, self.kd, self.axes = np.array(goal, dtype=float), kp, kd, axes

    def rows(self, m, layout, dt, t):
        J = m.com_jacobian[self.axes]
        A = np.zeros((J.shape[0], layout.n))
        A[:, : m.nv] = J
        b = (self.kp * (self.goal - m.com[self.axes]) - self.kd * m.com_velocity[self.axes]
             - m.com_drift[self.axes])
        return Rows(A=A, b=b)


class JointAccelStandIn(Task):
    """One joint's acceleration set to a constant: ``qdd_j = value``."""

    category = Category.OPERATIONAL

    def __init__(self, name: str, index: int, value: float, weight: float = 1.0) -> None:
        super().__init__(name, weight)
        self.index, self.value = index, value

    def rows(self, m, layout, dt, t):
        A = np.zeros((1, layout.n))
        A[0, self.index] = 1.0
        return Rows(A=A, b=np.array([self.value]))


class JointBoundStandIn(Task):
    """Bounds on one joint's acceleration: ``lo <= qdd_j <= hi``."""

    category = Category.JOINT_LIMITS

    def __init__(self, name: str, index: int, lo: float, hi: float) -> None:
        super().__init__(name)
        self.index, self.lo, self.hi = index, lo, hi

    def rows(self, m, layout, dt, t):
        C = np.zeros((1, layout.n))
        C[0, self.index] = 1.0
        return Rows(C=C, lower=np.array([self.lo]), upper=np.array([self.hi]))


def sample_humanoid() -> tuple[RobotModel, np.ndarray]:
    """pinocchio's sample humanoid with level sole frames ``right_sole``/``left_sole``.

    The sole frames sit at the ankle joints with world-aligned axes at the neutral
    configuration (local ``z`` up), so the contact limits of ``hqp.tasks.contact`` apply.
    Torque limits are raised to 1000 N m (the sample model's are 10 N m).
    """
    pm = pin.buildSampleModelHumanoid()
    data = pm.createData()
    q = pin.neutral(pm)
    pin.forwardKinematics(pm, data, q)
    for side in ("rleg", "lleg"):
        jid = pm.getJointId(f"{side}_wrist2_joint")
        oMi = data.oMi[jid]
        placement = pin.SE3(oMi.rotation.T, np.zeros(3))
        pm.addFrame(pin.Frame(f"{'right' if side == 'rleg' else 'left'}_sole", jid,
                              pm.getFrameId(f"{side}_wrist2_joint"), placement,
                              pin.FrameType.OP_FRAME))
    m = RobotModel(pm, name="sample", torque_limits=np.full(pm.nv - 6, 1e3))
    return m, q
