"""The one place where pinocchio and MuJoCo states are converted.

Conventions, checked numerically in ``tests/test_convert.py``:

* Configuration. Pinocchio's free flyer is ``[x, y, z, qx, qy, qz, qw]``
  (quaternion ``xyzw``); MuJoCo's free joint is ``[x, y, z, qw, qx, qy, qz]``
  (``wxyz``). The other joints are matched by name (the two joint orders may
  differ).
* Velocity. Pinocchio's free-flyer velocity is ``[v, omega]``, both in the
  base frame. MuJoCo's free-joint velocity is ``[pdot, omega]``: the linear
  part is the velocity of the base origin in the **world** frame (it is the
  time derivative of the position in ``qpos``), the angular part is in the
  **base** frame. So ``qvel = T v`` with ``T = blkdiag(R, I3, I)`` (``R`` the
  base orientation), up to the joint permutation.
* Generalized forces are dual: ``f_pin = T^T f_mj``. Hence
  ``M_pin = T^T M_mj T`` and, since ``qacc = T vdot + Tdot v`` with
  ``Tdot v = [R (omega x v); 0]``, ``h_pin = T^T (c_mj + M_mj Tdot v)``, with
  ``c_mj`` MuJoCo's ``qfrc_bias``.
* Actuators are matched to joints through their transmission; ``ctrl`` is the
  joint torque divided by the actuator's gear.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pinocchio as pin

from hqp.errors import HQPError, check_array
from hqp.model import RobotModel


class StateMap:
    """Maps states and dynamics between a pinocchio model and a MuJoCo model of one robot.

    Args:
        model: The controller's model (:class:`~hqp.model.RobotModel`, floating
            base) or a pinocchio model whose joint 1 is a free flyer.
        mj_model: The MuJoCo model (one free joint, hinge/slide joints with the
            pinocchio joints' names, motors on joints).

    Raises:
        HQPError: A pinocchio joint missing from MuJoCo (lists MuJoCo's
            joints), not exactly one free joint, or a MuJoCo joint with no
            pinocchio counterpart.

    """

    def __init__(self, model: RobotModel | pin.Model, mj_model: mujoco.MjModel) -> None:
        pmodel = model.model if isinstance(model, RobotModel) else model
        if pmodel.joints[1].nv != 6:
            raise HQPError("StateMap: pinocchio joint 1 must be a free flyer")
        self.nq = pmodel.nq
        self.nv = pmodel.nv
        self.mj_model = mj_model
        free_type = mujoco.mjtJoint.mjJNT_FREE
        free = [j for j in range(mj_model.njnt) if mj_model.jnt_type[j] == free_type]
        if len(free) != 1:
            raise HQPError(f"StateMap: MuJoCo model has {len(free)} free joints, expected 1")
        self._free_q = int(mj_model.jnt_qposadr[free[0]])
        self._free_v = int(mj_model.jnt_dofadr[free[0]])
        mj_names = {mj_model.joint(j).name: j for j in range(mj_model.njnt) if j != free[0]}
        names = list(pmodel.names[2:])
        missing = [n for n in names if n not in mj_names]
        if missing:
            raise HQPError(
                f"StateMap: joints {missing} not in the MuJoCo model; its joints: "
                + ", ".join(sorted(mj_names))
            )
        extra = sorted(set(mj_names) - set(names))
        if extra:
            raise HQPError(f"StateMap: MuJoCo joints {extra} have no pinocchio counterpart")
        self.joint_names = tuple(names)
        pin_joints = [pmodel.joints[pmodel.getJointId(n)] for n in names]
        self._pin_q = np.array([jm.idx_q for jm in pin_joints], dtype=int)
        self._pin_v = np.array([jm.idx_v for jm in pin_joints], dtype=int)
        self._mj_q = np.array([mj_model.jnt_qposadr[mj_names[n]] for n in names], dtype=int)
        self._mj_v = np.array([mj_model.jnt_dofadr[mj_names[n]] for n in names], dtype=int)

        # Actuators: actuator u drives pinocchio velocity index act_v[u] with gear act_gear[u].
        joint_of_mj = {mj_names[n]: i for i, n in enumerate(names)}
        act_v, gear = [], []
        for u in range(mj_model.nu):
            if mj_model.actuator_trntype[u] != mujoco.mjtTrn.mjTRN_JOINT:
                name = mj_model.actuator(u).name
                raise HQPError(f"StateMap: actuator {name!r} is not on a joint")
            jid = int(mj_model.actuator_trnid[u, 0])
            if jid not in joint_of_mj:
                name = mj_model.actuator(u).name
                raise HQPError(f"StateMap: actuator {name!r} drives the free joint")
            act_v.append(self._pin_v[joint_of_mj[jid]])
            gear.append(float(mj_model.actuator_gear[u, 0]))
        self._act_v = np.array(act_v, dtype=int)
        self._act_gear = np.array(gear)
        self.nu = mj_model.nu
        # One gather per vector: pinocchio entry i reads MuJoCo entry take[i] (the quaternion
        # reordered from wxyz to xyzw, the joints permuted).
        f, b = self._free_q, self._free_v
        self._q_take = np.empty(self.nq, dtype=np.intp)
        self._q_take[:7] = (f, f + 1, f + 2, f + 4, f + 5, f + 6, f + 3)
        self._q_take[self._pin_q] = self._mj_q
        self._v_take = np.empty(self.nv, dtype=np.intp)
        self._v_take[:6] = np.arange(b, b + 6)
        self._v_take[self._pin_v] = self._mj_v
        self._rotation = np.empty((3, 3))  # workspace of state_from_data

    # -- configuration ------------------------------------------------------------------------

    def q_from_qpos(self, qpos: np.ndarray) -> np.ndarray:
        """Pinocchio configuration ``(nq,)`` from MuJoCo's ``qpos`` ``(mj.nq,)``."""
        return np.asarray(qpos, dtype=float)[self._q_take]

    def qpos_from_q(self, q: np.ndarray) -> np.ndarray:
        """MuJoCo ``qpos`` ``(mj.nq,)`` from a pinocchio configuration ``(nq,)``.

        Raises:
            InvalidInput: Wrong shape or non-finite entries.

        """
        q = check_array(q, (self.nq,), "StateMap.qpos_from_q: q")
        qpos = np.array(self.mj_model.qpos0, dtype=float)
        f = self._free_q
        qpos[f : f + 3] = q[:3]
        x, y, z, w = q[3:7]
        qpos[f + 3 : f + 7] = (w, x, y, z)
        qpos[self._mj_q] = q[self._pin_q]
        return qpos

    def base_rotation(self, q: np.ndarray) -> np.ndarray:
        """Return the base orientation ``R`` ``(3, 3)`` (world from base) of a configuration."""
        return rotation_from_quat_xyzw(np.asarray(q, dtype=float)[3:7], np.empty((3, 3)))

    # -- velocity ---------------------------------------------------------------------------

    def velocity_matrix(self, q: np.ndarray) -> np.ndarray:
        """``T`` ``(mj.nv, nv)`` with ``qvel = T v`` (rows in MuJoCo order, columns pinocchio's)."""
        R = self.base_rotation(q)
        T = np.zeros((self.mj_model.nv, self.nv))
        b = self._free_v
        T[b : b + 3, 0:3] = R
        T[b + 3 : b + 6, 3:6] = np.eye(3)
        T[self._mj_v, self._pin_v] = 1.0
        return T

    def v_from_qvel(self, qvel: np.ndarray, q: np.ndarray) -> np.ndarray:
        """Pinocchio velocity ``(nv,)`` from MuJoCo's ``qvel`` at pinocchio configuration ``q``."""
        return self._v_from_qvel(np.asarray(qvel, dtype=float),
                                 rotation_from_quat_xyzw(np.asarray(q, dtype=float)[3:7],
                                                         self._rotation))

    def _v_from_qvel(self, qvel: np.ndarray, R: np.ndarray) -> np.ndarray:
        """Return ``v = T^T qvel``, ``T = blkdiag(R, I3, I)`` orthogonal.

        The one place where MuJoCo's world-frame linear velocity of the base becomes
        pinocchio's base-frame one.
        """
        v = qvel[self._v_take]
        b = self._free_v
        v[0:3] = R.T @ qvel[b : b + 3]
        return v

    def qvel_from_v(self, v: np.ndarray, q: np.ndarray) -> np.ndarray:
        """MuJoCo ``qvel`` ``(mj.nv,)`` from a pinocchio velocity at configuration ``q``.

        Raises:
            InvalidInput: Wrong shape or non-finite entries.

        """
        v = check_array(v, (self.nv,), "StateMap.qvel_from_v: v")
        R = self.base_rotation(q)
        qvel = np.zeros(self.mj_model.nv)
        b = self._free_v
        qvel[b : b + 3] = R @ v[0:3]
        qvel[b + 3 : b + 6] = v[3:6]
        qvel[self._mj_v] = v[self._pin_v]
        return qvel

    def state_from_data(self, data: mujoco.MjData) -> tuple[np.ndarray, np.ndarray]:
        """Pinocchio ``(q, v)`` from MuJoCo data (fresh arrays; MuJoCo's are read in place)."""
        q = data.qpos[self._q_take]
        return q, self._v_from_qvel(data.qvel, rotation_from_quat_xyzw(q[3:7], self._rotation))

    # -- forces and dynamics --------------------------------------------------------------------

    def ctrl_from_tau(self, tau: np.ndarray) -> np.ndarray:
        """MuJoCo ``ctrl`` ``(nu,)`` from actuated torques ``(nv - 6,)``, pinocchio order [N m].

        Raises:
            InvalidInput: Wrong shape or non-finite entries.

        """
        tau = check_array(tau, (self.nv - 6,), "StateMap.ctrl_from_tau: tau")
        return tau[self._act_v - 6] / self._act_gear

    def write_ctrl(self, tau: np.ndarray, ctrl: np.ndarray) -> None:
        """Write :meth:`ctrl_from_tau` of checked torques ``(nv - 6,)`` into ``ctrl`` ``(nu,)``."""
        np.divide(tau[self._act_v - 6], self._act_gear, out=ctrl)

    def tau_from_ctrl(self, ctrl: np.ndarray) -> np.ndarray:
        """Actuated-joint torques ``(nv - 6,)`` (pinocchio order) of MuJoCo motors' ``ctrl``."""
        tau = np.zeros(self.nv - 6)
        tau[self._act_v - 6] = np.asarray(ctrl, dtype=float) * self._act_gear
        return tau

    def generalized_force(self, qfrc: np.ndarray, q: np.ndarray) -> np.ndarray:
        """Pinocchio generalized force ``T^T qfrc`` ``(nv,)`` of a MuJoCo one ``(mj.nv,)``."""
        return self.velocity_matrix(q).T @ np.asarray(qfrc, dtype=float)

    def mass_matrix(self, data: mujoco.MjData) -> np.ndarray:
        """Pinocchio's mass matrix ``T^T M_mj T`` ``(nv, nv)`` from MuJoCo data (after forward)."""
        M_mj = np.zeros((self.mj_model.nv, self.mj_model.nv))
        mujoco.mj_fullM(self.mj_model, data, M_mj)
        T = self.velocity_matrix(self.q_from_qpos(data.qpos))
        return T.T @ M_mj @ T

    def bias_force(self, data: mujoco.MjData) -> np.ndarray:
        """Pinocchio's nonlinear effects ``h`` ``(nv,)`` from MuJoCo data after ``mj_forward``.

        ``h = T^T (qfrc_bias + M_mj Tdot v)``, ``Tdot v = [R (omega x v_lin); 0]``.
        """
        q, v = self.state_from_data(data)
        M_mj = np.zeros((self.mj_model.nv, self.mj_model.nv))
        mujoco.mj_fullM(self.mj_model, data, M_mj)
        dTv = np.zeros(self.mj_model.nv)
        b = self._free_v
        dTv[b : b + 3] = self.base_rotation(q) @ np.cross(v[3:6], v[0:3])
        T = self.velocity_matrix(q)
        return T.T @ (np.asarray(data.qfrc_bias) + M_mj @ dTv)


def rotation_from_quat_xyzw(quat: np.ndarray, out: np.ndarray) -> np.ndarray:
    """Write the rotation matrix of a quaternion ``(x, y, z, w)`` into ``out`` ``(3, 3)``.

    The quaternion is normalised first. The operations are Eigen's
    ``Quaternion::normalized().toRotationMatrix()`` (pinocchio's) in the same order, so the
    matrix is the same to the last bit (``tests/test_convert.py`` checks it), without building
    a pinocchio object per call.

    Returns:
        ``out``.

    """
    x, y, z, w = quat.tolist()
    n2 = (x * x + z * z) + (y * y + w * w)
    if n2 > 0.0:  # (Eigen leaves a zero quaternion as it is)
        n = math.sqrt(n2)
        x, y, z, w = x / n, y / n, z / n, w / n
    tx, ty, tz = 2.0 * x, 2.0 * y, 2.0 * z
    twx, twy, twz = tx * w, ty * w, tz * w
    txx, txy, txz = tx * x, ty * x, tz * x
    tyy, tyz, tzz = ty * y, tz * y, tz * z
    out.flat = (1.0 - (tyy + tzz), txy - twz, txz + twy,
                txy + twz, 1.0 - (txx + tzz), tyz - twx,
                txz - twy, tyz + twx, 1.0 - (txx + tyy))
    return out
