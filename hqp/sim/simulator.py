"""MuJoCo execution of joint torques: the robot's MJCF, motor actuators, contact sensing.

The simulator is the "real robot" of hqp: it loads the robot's MuJoCo model (1 kHz,
``implicitfast`` by default), applies the commanded torques through the motor actuators, and
reports a :class:`~hqp.model.RobotState` in pinocchio's convention (through the one state
conversion of :mod:`hqp.sim.convert`). It does not hide the controller's faults:

* torques beyond the limits (the robot's controller-model limits, and the actuators' own
  ``ctrlrange`` / ``forcerange`` where MuJoCo limits them) are clipped as a motor would, but
  every clipped entry is counted (:attr:`Simulator.clip_count`) and logged, so tests can
  assert there was none;
* contact state is read from MuJoCo (which geoms touch the floor, foot slip and lift-off, the
  centre of pressure of the floor contact forces), for logs and tests only, never for the
  controller's model.

Two contact modes (``contacts``): ``"unilateral"`` (the default: MuJoCo's soft, unilateral
floor contacts, the feet may slip, tip and lift off) and ``"welded"`` (the seed papers' rigid
feet: each foot body is held by a MuJoCo weld equality at the pose it has on :meth:`reset`,
its collisions with the floor are off, so the weld carries the whole support wrench, which
may pull on the floor or put its centre of pressure outside the sole). In both modes
:meth:`Simulator.foot_wrenches` reads the wrench the world exerts on each foot (MuJoCo's
``cfrc_ext``, contacts and equality constraints included) and :meth:`Simulator.sole_cops`
the centre of pressure it implies in each sole's frame.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from hqp.errors import InvalidInput, check_array
from hqp.model import RobotState
from hqp.model.geometry import cross3, monotone_chain
from hqp.sim import convert

if TYPE_CHECKING:
    from hqp.robots import Robot

logger = logging.getLogger(__name__)

FALL_HEIGHT_RATIO = 0.6
"""A robot has fallen when its pelvis is below this fraction of its standing height."""


@dataclass(frozen=True)
class ContactReading:
    """Contact state read from MuJoCo at one instant.

    Attributes:
        foot_contact: Whether each foot (``robot.feet`` order) touches the floor.
        foot_position: World position of each foot site ``(nfeet, 3)`` [m].
        other_contact: Names of the bodies other than the feet that touch the floor.
        normal_force: Total normal force of the floor on each foot ``(nfeet,)`` [N].
        cop: Centre of pressure of all floor contact forces ``(2,)`` [m] (``nan`` if none).

    """

    foot_contact: np.ndarray
    foot_position: np.ndarray
    other_contact: tuple[str, ...]
    normal_force: np.ndarray
    cop: np.ndarray


CONTACT_MODES = ("unilateral", "welded")
"""How the feet touch the floor (module docstring); the first is the default."""

WELD_SOLREF = (0.002, 1.0)
"""``solref`` of the feet's weld equalities (time constant [s], damping ratio): the stiffest
MuJoCo advises at 1 ms (twice the time step); a passively collapsing paper-humanoid moves its
welded feet by about 1 mm in 0.2 s."""
WELD_SOLIMP = (0.99, 0.999, 0.001, 0.5, 2.0)
"""``solimp`` of the feet's weld equalities (impedance close to 1: a nearly hard constraint)."""

COP_MIN_FORCE = 0.01
"""A foot's centre of pressure is defined where its normal force exceeds this fraction of the
robot's weight (below it, a moment of round-off size moves it by centimetres)."""

SEAT_DEPTH = 5e-5
"""Depth [m] the feet start below the floor on a default :meth:`Simulator.reset`: about
the robots' equilibrium sink standing (0.03-0.06 mm), so both soles are in contact from
the first step."""


class Simulator:
    """A MuJoCo simulation of a bundled robot driven by joint torques.

    Args:
        robot: The robot (its ``mjcf_path``, feet, standing configuration).
        dt: Simulation time step [s] (default 1 ms).
        integrator: MuJoCo integrator name (default ``"implicitfast"``).
        torque_limits: Limits of the commanded torques ``(na,)`` [N m], in the controller
            model's joint order (default: the robot model's ``tau_max``).
        contacts: ``"unilateral"`` (MuJoCo's floor contacts) or ``"welded"`` (the feet held
            by weld equalities at their pose on :meth:`reset`; module docstring).

    Raises:
        InvalidInput: A non-positive time step, unknown integrator or contact mode, or an
            actuated joint without a motor.

    """

    def __init__(
        self,
        robot: Robot,
        dt: float = 0.001,
        integrator: str = "implicitfast",
        torque_limits: np.ndarray | None = None,
        contacts: str = CONTACT_MODES[0],
    ) -> None:
        import mujoco

        if not np.isfinite(dt) or dt <= 0.0:
            raise InvalidInput(f"Simulator: dt must be positive, got {dt}")
        if contacts not in CONTACT_MODES:
            raise InvalidInput(f"Simulator: contacts must be one of {CONTACT_MODES}, "
                               f"got {contacts!r}")
        self.robot = robot
        self.contact_mode = contacts
        """``"unilateral"`` or ``"welded"``."""
        self.mj_model = (robot.mujoco_model() if contacts == "unilateral"
                         else _welded_model(robot))
        self.mj_data = mujoco.MjData(self.mj_model)
        try:
            self.mj_model.opt.integrator = getattr(
                mujoco.mjtIntegrator, f"mjINT_{integrator.upper()}"
            )
        except AttributeError:
            raise InvalidInput(f"Simulator: unknown MuJoCo integrator {integrator!r}") from None
        self.mj_model.opt.timestep = float(dt)
        self.dt = float(dt)
        model = robot.model()
        self.nq, self.nv, self.na = model.nq, model.nv, model.na
        self.joint_names = model.joint_names
        self.converter = convert.StateMap(model, self.mj_model)
        # Motor of each actuated joint, in the controller model's order.
        motor_of_joint: dict[str, int] = {}
        for a in range(self.mj_model.nu):
            if self.mj_model.actuator_trntype[a] == mujoco.mjtTrn.mjTRN_JOINT:
                j = int(self.mj_model.actuator_trnid[a, 0])
                motor_of_joint[mujoco.mj_id2name(self.mj_model, mujoco.mjtObj.mjOBJ_JOINT, j)] = a
        missing = [n for n in self.joint_names if n not in motor_of_joint]
        if missing:
            raise InvalidInput(f"Simulator: no motor for joints {missing} in {robot.mjcf_path}")
        self.actuators = np.array([motor_of_joint[n] for n in self.joint_names])
        gear = self.mj_model.actuator_gear[self.actuators, 0]
        self.gear = np.where(gear == 0.0, 1.0, gear)
        limits = model.tau_max if torque_limits is None else check_array(
            torque_limits, (self.na,), "Simulator: torque_limits")
        limits = np.array(limits, dtype=float)
        for i, a in enumerate(self.actuators):
            if self.mj_model.actuator_ctrllimited[a]:
                lo, hi = self.mj_model.actuator_ctrlrange[a] * self.gear[i]
                limits[i] = min(limits[i], abs(lo), abs(hi))
            if self.mj_model.actuator_forcelimited[a]:
                lo, hi = self.mj_model.actuator_forcerange[a]
                limits[i] = min(limits[i], abs(lo), abs(hi))
        self.torque_limits = limits
        self.clip_count = 0
        """Number of torque entries clipped so far."""
        self.last_clipped = 0
        """Number of torque entries clipped at the last step."""
        self._push_body = 1  # the floating base body (first body after the world)
        # Contact bookkeeping: floor geoms and the bodies of the feet.
        self._floor_geoms = {g for g in range(self.mj_model.ngeom)
                             if self.mj_model.geom_bodyid[g] == 0}
        self._foot_sites = [mujoco.mj_name2id(self.mj_model, mujoco.mjtObj.mjOBJ_SITE, f)
                            for f in robot.feet]
        if min(self._foot_sites) < 0:
            raise InvalidInput(f"Simulator: foot sites {robot.feet} missing in {robot.mjcf_path}")
        self._foot_bodies = [int(self.mj_model.site_bodyid[s]) for s in self._foot_sites]
        # bodies of each foot's subtree (a toe is part of its foot)
        self._foot_subtrees = [[b for b in range(1, self.mj_model.nbody)
                                if self._body_root_foot(b) == i] for i in range(len(robot.feet))]
        # per geom: -2 a floor geom, the index of the foot it belongs to, or -1
        self._geom_role = np.full(self.mj_model.ngeom, -1, dtype=np.intp)
        for g in range(self.mj_model.ngeom):
            body = int(self.mj_model.geom_bodyid[g])
            foot = self._body_root_foot(body)
            self._geom_role[g] = -2 if g in self._floor_geoms else (-1 if foot is None else foot)
        self._geom_roles = self._geom_role.tolist()
        self._pyramidal = int(self.mj_model.opt.cone) == int(mujoco.mjtCone.mjCONE_PYRAMIDAL)
        self._feet = tuple(robot.feet)
        # sole corners in each sole's frame (fixed)
        self._sole_corners = [robot.contact(foot).corners() for foot in robot.feet]
        self._foot_site_index = np.array(self._foot_sites, dtype=np.intp)
        self._wrench = np.zeros(6)
        self._welds = np.zeros(0, dtype=int)
        if contacts == "welded":
            self._welds = np.array([mujoco.mj_name2id(self.mj_model, mujoco.mjtObj.mjOBJ_EQUALITY,
                                                      _weld_name(foot)) for foot in robot.feet])
            for g in range(self.mj_model.ngeom):  # the weld alone holds the feet
                if self._body_root_foot(int(self.mj_model.geom_bodyid[g])) is not None:
                    self.mj_model.geom_contype[g] = 0
                    self.mj_model.geom_conaffinity[g] = 0
        self.weight = float(self.mj_model.body_subtreemass[1]
                            * np.linalg.norm(self.mj_model.opt.gravity))
        """Weight of the robot [N]."""
        self._mujoco = mujoco
        self._ctrl = self.mj_data.ctrl  # (MuJoCo's array, written in place)
        self._clip_above = self.torque_limits * (1.0 + 1e-9)
        self.reset()

    # -- state ------------------------------------------------------------------------------

    @property
    def time(self) -> float:
        """Simulated time [s]."""
        return float(self.mj_data.time)

    def reset(self, q: np.ndarray | None = None, v: np.ndarray | None = None) -> None:
        """Reset to a state (default: the robot's standing configuration at rest), time 0."""
        mujoco = self._mujoco
        mujoco.mj_resetData(self.mj_model, self.mj_data)
        if q is None:
            # The standing configuration puts the soles exactly on the floor, so round-off
            # decides whether MuJoCo sees a contact (paper-humanoid's right sole was 1e-17 m
            # above it: no contact on the first step, and the controller's first torques
            # spun the unsupported ankle to 2.3 rad/s in 1 ms). Seat the feet instead.
            q = np.array(self.robot.q_standing, dtype=float)
            q[2] -= SEAT_DEPTH
        else:
            q = check_array(q, (self.nq,), "Simulator: q")
        v = np.zeros(self.nv) if v is None else check_array(v, (self.nv,), "Simulator: v")
        self.set_state(q, v)
        if self._welds.size:
            self._weld_feet()
        self.clip_count = 0
        self.last_clipped = 0
        self._pushing = False  # (mj_resetData cleared the applied forces)

    def _weld_feet(self) -> None:
        """Hold each welded foot at its current pose (the weld's relative pose, anchor at 0).

        MuJoCo's weld data: anchor ``[0:3]``, the pose of body 2 (the world) in body 1 (the
        foot) ``[3:10]`` (position, quaternion ``wxyz``), torque scale ``[10]``.
        """
        m, d = self.mj_model, self.mj_data
        for eq, body in zip(self._welds, self._foot_bodies):
            R = d.xmat[body].reshape(3, 3)
            m.eq_data[eq, 0:3] = 0.0
            m.eq_data[eq, 3:6] = -R.T @ d.xpos[body]
            m.eq_data[eq, 6:10] = d.xquat[body] * np.array([1.0, -1.0, -1.0, -1.0])
            m.eq_data[eq, 10] = 1.0
        self._mujoco.mj_forward(m, d)

    def set_state(self, q: np.ndarray, v: np.ndarray) -> None:
        """Set the state from pinocchio's ``(q, v)``."""
        self.mj_data.qpos[:] = self.converter.qpos_from_q(q)
        self.mj_data.qvel[:] = self.converter.qvel_from_v(v, q)
        self.mj_data.ctrl[:] = 0.0
        self._mujoco.mj_forward(self.mj_model, self.mj_data)

    def state(self, reading: ContactReading | None = None) -> RobotState:
        """Return the current state in pinocchio's convention, with the feet's sensed contacts.

        The sensed contacts are which feet touch the floor (:meth:`feet_touching`); the rest of
        a contact reading (forces, centre of pressure) is computed only by :meth:`contacts`.

        Args:
            reading: The contact reading of the current instant, if already read.

        """
        q, v = self.converter.state_from_data(self.mj_data)
        touching = self.feet_touching() if reading is None else reading.foot_contact
        return RobotState(q, v, self.mj_data.time, dict(zip(self._feet, touching.tolist())))

    def feet_touching(self) -> np.ndarray:
        """Whether each foot touches the floor ``(nfeet,)`` (:meth:`contacts`' ``foot_contact``).

        Reads only which geoms MuJoCo found in contact (no forces): the part of a contact
        reading that the controller's sensed state needs.
        """
        touching = np.zeros(len(self._feet), dtype=bool)
        if self._welds.size:  # the welds hold the feet
            touching[:] = True
        elif self.mj_data.ncon:
            role = self._geom_roles  # (a few contacts: Python ints beat numpy calls)
            for g1, g2 in self.mj_data.contact.geom.tolist():
                r1, r2 = role[g1], role[g2]
                if r1 == -2 and r2 >= 0:
                    touching[r2] = True
                elif r2 == -2 and r1 >= 0:
                    touching[r1] = True
        return touching

    # -- stepping ---------------------------------------------------------------------------

    def apply(self, tau: np.ndarray) -> int:
        """Set the motor commands from torques ``(na,)`` [N m]; return the clipped entry count.

        Raises:
            InvalidInput: Wrong shape or non-finite torques.

        """
        magnitude = (np.abs(tau) if isinstance(tau, np.ndarray) and tau.dtype == np.float64
                     and tau.shape == (self.na,) else None)
        if magnitude is not None and (magnitude <= self._clip_above).all():
            n = 0  # the common case, one comparison (NaN fails it and is checked below)
        else:
            tau = check_array(tau, (self.na,), "Simulator: tau")
            over = np.abs(tau) > self._clip_above
            n = int(over.sum())
            if n:
                if self.clip_count == 0:
                    names = [self.joint_names[i] for i in np.flatnonzero(over)]
                    logger.warning("t=%.3f: torques clipped at joints %s", self.time, names)
                tau = np.clip(tau, -self.torque_limits, self.torque_limits)
        self.clip_count += n
        self.last_clipped = n
        self.converter.write_ctrl(tau, self._ctrl)
        return n

    def step(self, tau: np.ndarray | None = None, force: np.ndarray | None = None) -> None:
        """Advance one time step with torques ``tau`` and an optional base force ``(3,)`` [N]."""
        if tau is not None:
            self.apply(tau)
        if force is not None:
            xfrc = self.mj_data.xfrc_applied
            xfrc[:] = 0.0
            xfrc[self._push_body, :3] = force
            self._pushing = True
        elif self._pushing:  # the last step's force ends
            self.mj_data.xfrc_applied[:] = 0.0
            self._pushing = False
        self._mujoco.mj_step(self.mj_model, self.mj_data)

    # -- sensing (logs and tests only) ------------------------------------------------------

    def _body_root_foot(self, body: int) -> int | None:
        """Index of the foot whose body is ``body`` or one of its ancestors (else ``None``)."""
        m = self.mj_model
        while body > 0:
            if body in self._foot_bodies:
                return self._foot_bodies.index(body)
            body = int(m.body_parentid[body])
        return None

    def contacts(self) -> ContactReading:
        """Read the floor contacts: feet in contact, other bodies touching, CoP."""
        mujoco = self._mujoco
        m, d = self.mj_model, self.mj_data
        nfeet = len(self._foot_sites)
        touching_feet = [False] * nfeet
        normal_sums = [0.0] * nfeet  # (Python floats add as numpy's float64 do)
        others: set[str] = set()
        fz_sum = 0.0
        moment = np.zeros(2)
        ncon = d.ncon
        if ncon:  # a few contacts: Python ints and floats beat numpy calls
            contact = d.contact
            role = self._geom_roles
            on_foot: list[int] = []  # contact indices
            foot_of: list[int] = []  # the foot of each
            for i, (g1, g2) in enumerate(contact.geom.tolist()):
                if role[g1] == -2:
                    foot, other = role[g2], g2
                elif role[g2] == -2:
                    foot, other = role[g1], g1
                else:
                    continue
                if foot >= 0:
                    on_foot.append(i)
                    foot_of.append(foot)
                else:
                    body = int(m.geom_bodyid[other])
                    others.add(mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, body) or str(body))
            if on_foot:
                fn = self._normal_forces(contact, on_foot)
                for foot, f in zip(foot_of, fn.tolist()):  # in contact order
                    touching_feet[foot] = True
                    normal_sums[foot] += f
                fz_sum = float(fn.sum())
                # every contact on a foot (the common case): the same contiguous copy of the
                # points as the indexed one, without the index
                points = (np.ascontiguousarray(contact.pos[:, :2]) if len(on_foot) == ncon
                          else contact.pos[on_foot, :2])
                moment = fn @ points
        touching = np.array(touching_feet, dtype=bool)
        normal = np.array(normal_sums)
        feet = d.site_xpos[self._foot_site_index]  # (a copy)
        if self._welds.size:  # the welds carry the support: their wrenches give force and CoP
            wrenches = self.foot_wrenches()
            touching[:] = True
            normal = wrenches[:, 2].copy()
            fz_sum = float(normal.sum())
            moment = np.zeros(2)
            for p, w in zip(feet, wrenches):  # moment about each site -> point on the floor
                moment += w[2] * p[:2] + np.array([-w[4], w[3]])
        cop = moment / fz_sum if fz_sum > 1e-9 else np.full(2, np.nan)
        return ContactReading(touching, feet, tuple(sorted(others)), normal, cop)

    def _normal_forces(self, contact: object, which: list[int]) -> np.ndarray:
        """Return the normal forces of the contacts ``which`` [N] (``mj_contactForce``'s).

        The constraint forces decoded as MuJoCo decodes them (a pyramid's normal force is the
        sum of its edge forces, added one after the other in MuJoCo's order: the same bits as
        ``mj_contactForce``), without one call per contact.
        """
        efc = self.mj_data.efc_force
        address = contact.efc_address.tolist()  # type: ignore[attr-defined]
        dim = contact.dim.tolist()  # type: ignore[attr-defined]
        pyramidal = self._pyramidal
        out = []
        for i in which:
            a, n = address[i], dim[i]
            if a < 0:
                out.append(0.0)
            elif n == 1 or not pyramidal:
                out.append(float(efc[a]))
            else:
                f = 0.0
                for edge in efc[a: a + 2 * (n - 1)].tolist():
                    f += edge
                out.append(f)
        return np.array(out)

    def foot_wrenches(self) -> np.ndarray:
        """Wrench the world exerts on each foot ``(nfeet, 6)``: force, torque about its site.

        World-aligned ``[f_x, f_y, f_z, tau_x, tau_y, tau_z]`` [N, N m], from MuJoCo's
        ``cfrc_ext`` (floor contacts in ``"unilateral"`` mode, the weld in ``"welded"`` mode)
        summed over the foot's bodies, its torque moved from the subtree centre of mass it is
        expressed at to the foot site. Valid after a step (or :meth:`reset`).
        """
        mujoco = self._mujoco
        m, d = self.mj_model, self.mj_data
        mujoco.mj_rnePostConstraint(m, d)
        out = np.zeros((len(self._foot_sites), 6))
        for i, (site, bodies) in enumerate(zip(self._foot_sites, self._foot_subtrees)):
            p = d.site_xpos[site]
            for b in bodies:
                torque, force = d.cfrc_ext[b, :3], d.cfrc_ext[b, 3:]
                c = d.subtree_com[int(m.body_rootid[b])]
                out[i, :3] += force
                out[i, 3:] += torque + cross3(c - p, force)
        return out

    def sole_cops(self, wrenches: np.ndarray | None = None) -> np.ndarray:
        """Centre of pressure of each foot's wrench in its sole frame ``(nfeet, 2)`` [m].

        ``x = -tau_y / f_z``, ``y = tau_x / f_z`` in the foot site's frame (``nan`` where the
        normal force is at most :data:`COP_MIN_FORCE` x the robot's weight: the foot pulls on
        the floor or carries next to nothing, and its centre of pressure is not defined).

        Args:
            wrenches: :meth:`foot_wrenches` of the current instant, if already read.

        """
        w = self.foot_wrenches() if wrenches is None else np.asarray(wrenches)
        out = np.full((len(self._foot_sites), 2), np.nan)
        f_min = COP_MIN_FORCE * self.weight
        for i, site in enumerate(self._foot_sites):
            R = self.mj_data.site_xmat[site].reshape(3, 3)
            f, tau = R.T @ w[i, :3], R.T @ w[i, 3:]
            if f[2] > f_min:
                out[i] = (-tau[1] / f[2], tau[0] / f[2])
        return out

    def sole_corners(self) -> np.ndarray:
        """World positions of the sole corners of the feet ``(nfeet, 4, 3)`` [m]."""
        out = []
        for corners, s in zip(self._sole_corners, self._foot_sites):
            R = self.mj_data.site_xmat[s].reshape(3, 3)
            out.append(self.mj_data.site_xpos[s] + corners @ R.T)
        return np.array(out)

    def com(self) -> np.ndarray:
        """Centre of mass of the robot from MuJoCo ``(3,)`` [m]."""
        return np.array(self.mj_data.subtree_com[1])

    def base_height(self) -> float:
        """Height of the floating base [m]."""
        return float(self.mj_data.xpos[self._push_body, 2])

    def fall_reason(self, reading: ContactReading | None = None) -> str | None:
        """Why the robot has fallen (``None``: it has not).

        Fallen: anything but a foot touches the floor, or the pelvis is below
        :data:`FALL_HEIGHT_RATIO` x the standing height.

        Args:
            reading: The contact reading of the current instant, if already read.

        """
        others = (reading if reading is not None else self.contacts()).other_contact
        if others:
            return f"{', '.join(others)} touches the floor"
        pelvis = self.base_height()
        if pelvis < FALL_HEIGHT_RATIO * self.robot.standing_height:
            return f"pelvis at {pelvis:.3f} m below {FALL_HEIGHT_RATIO} x standing"
        return None

    def fallen(self, reading: ContactReading | None = None) -> bool:
        """Whether the robot fell (:meth:`fall_reason`)."""
        return self.fall_reason(reading) is not None


def _weld_name(foot: str) -> str:
    """Name of the weld equality of a foot."""
    return f"hqp_weld_{foot}"


def _welded_model(robot: Robot) -> object:
    """Return the robot's MuJoCo model with a weld equality per foot body (data set on reset)."""
    import mujoco

    spec = mujoco.MjSpec.from_file(str(robot.mjcf_path))
    plain = spec.compile()
    for foot in robot.feet:
        site = mujoco.mj_name2id(plain, mujoco.mjtObj.mjOBJ_SITE, foot)
        if site < 0:
            raise InvalidInput(f"Simulator: foot site {foot!r} missing in {robot.mjcf_path}")
        eq = spec.add_equality()
        eq.name = _weld_name(foot)
        eq.type = mujoco.mjtEq.mjEQ_WELD
        eq.objtype = mujoco.mjtObj.mjOBJ_BODY
        eq.name1 = mujoco.mj_id2name(plain, mujoco.mjtObj.mjOBJ_BODY,
                                     int(plain.site_bodyid[site]))
        eq.solref = list(WELD_SOLREF)
        eq.solimp = list(WELD_SOLIMP)
    return spec.compile()


def _hull(points: np.ndarray) -> np.ndarray:
    """Convex hull of 2D points ``(k, 2)``, counter-clockwise (Andrew's monotone chain)."""
    return monotone_chain(sorted(map(tuple, np.round(points, 12).tolist())))


def inside_polygon(point: np.ndarray, vertices: np.ndarray) -> float:
    """Signed distance of a 2D point inside the convex hull of ``vertices`` ``(k, 2)`` [m].

    Positive inside (distance to the nearest edge line), negative outside (the largest
    violation of an edge's half-plane, a lower bound of the distance to the hull).
    """
    hull = _hull(np.asarray(vertices, dtype=float)[:, :2]).tolist()
    k = len(hull)
    if k < 3:
        return float("-inf")
    px, py = (float(c) for c in np.asarray(point)[:2])
    worst = -math.inf
    for i in range(k):  # (a few edges: floats, not arrays)
        x0, y0 = hull[i]
        x1, y1 = hull[(i + 1) % k]
        nx, ny = y1 - y0, -(x1 - x0)  # outward for a CCW hull
        norm = math.sqrt(nx * nx + ny * ny)
        worst = max(worst, nx / norm * (px - x0) + ny / norm * (py - y0))
    return float(-worst)
