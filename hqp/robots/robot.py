"""The :class:`Robot` record returned by :func:`hqp.robots.load`, and its helpers.

A robot bundles its files (URDF for pinocchio and PlaCo, MJCF for MuJoCo),
the frames that play common roles under uniform names (``left_foot``,
``right_foot``: sole centres, z axis normal to the sole; ``left_hand``,
``right_hand``; ``trunk``; ``pelvis``: the floating base; ``head`` where the
robot has one), its contact surfaces and a standing configuration.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pinocchio as pin

from hqp.errors import HQPError, InvalidInput
from hqp.model import RobotModel
from hqp.model.layout import ContactType

if TYPE_CHECKING:
    import mujoco

ROOT_JOINT = "root_joint"
"""Name of the free-flyer joint in every robot's pinocchio model."""

DIMENSIONS = ("left_shoulder", "right_shoulder", "left_hand", "right_hand", "arm_length",
              "leg_length", "feet_center", "standing_height", "com_height", "foot_length",
              "foot_width", "trunk", "head")
"""Names of :meth:`Robot.dimensions` (``robot.<name>`` in behavior files)."""


@dataclass(frozen=True)
class ContactSurface:
    """A contact frame of a robot with its kind and geometry.

    Attributes:
        name: Contact name (the frame name, e.g. ``"left_foot"``).
        frame: Frame at which the contact wrench applies; for a sole its
            origin is the sole centre on the sole surface, z normal to the sole
            pointing into the robot.
        kind: :attr:`ContactType.SURFACE` for soles, :attr:`ContactType.POINT`
            for point contacts.
        half_length: Half extent of the sole along the frame's x axis [m].
        half_width: Half extent of the sole along the frame's y axis [m].
        friction: Friction coefficient (the MuJoCo geom's sliding friction).

    """

    name: str
    frame: str
    kind: ContactType
    half_length: float = 0.0
    half_width: float = 0.0
    friction: float = 1.0

    def corners(self) -> np.ndarray:
        """Sole corners in the contact frame ``(4, 3)`` [m], front-left first, counter-clockwise."""
        a, b = self.half_length, self.half_width
        return np.array([[a, b, 0.0], [-a, b, 0.0], [-a, -b, 0.0], [a, -b, 0.0]])


@dataclass(frozen=True)
class BodyCapsule:
    """A capsule proxy of a body part for distance primitives.

    Attributes:
        name: Capsule name.
        frame: Frame the capsule is attached to.
        a: First endpoint in the frame ``(3,)`` [m].
        b: Second endpoint in the frame ``(3,)`` [m].
        radius: Radius [m].

    """

    name: str
    frame: str
    a: tuple[float, float, float]
    b: tuple[float, float, float]
    radius: float


@dataclass(frozen=True, eq=False)
class Robot:
    """A bundled robot: files, frames, contacts, limits and standing configuration.

    Attributes:
        name: Registry name (``"paper-humanoid"``, ``"g1"``, ``"talos"``).
        urdf_path: URDF file (pinocchio, PlaCo) with every frame of the common
            roles; for g1 and talos a mesh-free file generated from the source.
        mjcf_path: MJCF file (MuJoCo: robot, floor, one motor per actuated joint).
        contacts: Contact surfaces (the soles).
        hands: ``(left, right)`` hand frame names.
        feet: ``(left, right)`` sole frame names.
        base_frame: Frame of the floating base (the pelvis).
        head_frame: Head frame (``None`` if the robot has none).
        q_standing: Standing configuration ``(nq,)``, pinocchio convention:
            both soles flat on the floor ``z = 0``, knees slightly bent, arms
            down, centre of mass above the middle of the soles.
        standing_height: Height of the base frame in ``q_standing`` [m].
        extra_frames: Frames added to pinocchio's model by :meth:`model`:
            ``name -> (parent frame name, placement in that frame)``.
        position_limits: Controller's ``(lower, upper)`` over actuated joints
            (``None``: the URDF's).
        velocity_limits: Controller's velocity limits [rad/s] (``None``: URDF's).
        torque_limits: Controller's torque limits [N m] (``None``: URDF's).
        capsules: Capsule proxies of the limbs for distance primitives.
        package_dirs: Package directories for the source URDF's mesh paths.
        source_urdf_path: The URDF the robot was generated from (``None`` when
            :attr:`urdf_path` is the source).

    """

    name: str
    urdf_path: Path
    mjcf_path: Path
    contacts: tuple[ContactSurface, ...]
    hands: tuple[str, str]
    feet: tuple[str, str]
    base_frame: str
    head_frame: str | None
    q_standing: np.ndarray
    standing_height: float
    extra_frames: Mapping[str, tuple[str, pin.SE3]] = field(default_factory=dict)
    position_limits: tuple[np.ndarray, np.ndarray] | None = None
    velocity_limits: np.ndarray | None = None
    torque_limits: np.ndarray | None = None
    capsules: tuple[BodyCapsule, ...] = ()
    package_dirs: tuple[str, ...] = ()
    source_urdf_path: Path | None = None

    def pinocchio_model(self) -> pin.Model:
        """Build a fresh pinocchio model: URDF, free flyer ``root_joint``, :attr:`extra_frames`."""
        return build_pinocchio_model(self.urdf_path, self.extra_frames)

    def model(self) -> RobotModel:
        """Build a fresh :class:`~hqp.model.RobotModel` (floating base, the robot's limits)."""
        model = RobotModel(
            self.pinocchio_model(),
            name=self.name,
            floating_base=True,
            position_limits=self.position_limits,
            velocity_limits=self.velocity_limits,
            torque_limits=self.torque_limits,
        )
        model.source = self
        return model

    def mujoco_model(self) -> mujoco.MjModel:
        """Load a fresh ``mujoco.MjModel`` from :attr:`mjcf_path`."""
        import mujoco

        return mujoco.MjModel.from_xml_path(str(self.mjcf_path))

    def dimensions(self) -> dict[str, Any]:
        """Sizes and standing positions of the robot (``robot.<name>`` in behavior files).

        Positions are world coordinates [m] in :attr:`q_standing` (``(3,)`` arrays); the
        names are :data:`DIMENSIONS`. A shoulder is the first joint of the arm below the
        trunk (the last joint common to both hands' chains); ``arm_length`` is the sum of the
        arm's segments from the shoulder to the hand point (the reach of the straight arm),
        ``leg_length`` the same from the hip (the first joint of the leg) to the sole.
        """
        model = self.pinocchio_model()
        data = model.createData()
        q = np.asarray(self.q_standing)
        pin.framesForwardKinematics(model, data, q)
        pin.centerOfMass(model, data, q)

        def chain(frame: str) -> list[int]:
            joint = model.frames[model.getFrameId(frame)].parentJoint
            out = []
            while joint > 1:
                out.append(joint)
                joint = model.parents[joint]
            return out[::-1]

        def length(joints: list[int], frame: str) -> float:
            points = [data.oMi[j].translation for j in joints]
            points.append(data.oMf[model.getFrameId(frame)].translation)
            return float(sum(np.linalg.norm(b - a) for a, b in zip(points[:-1], points[1:])))

        left, right = chain(self.hands[0]), chain(self.hands[1])
        common = [j for j in left if j in right]
        arms = [[j for j in c if j not in common] for c in (left, right)]
        legs = [chain(f) for f in self.feet]
        out: dict[str, Any] = {}
        for side, arm, hand in zip(("left", "right"), arms, self.hands):
            out[f"{side}_shoulder"] = data.oMi[arm[0]].translation.copy() if arm else \
                data.oMf[model.getFrameId(hand)].translation.copy()
            out[f"{side}_hand"] = data.oMf[model.getFrameId(hand)].translation.copy()
        out["arm_length"] = 0.5 * sum(length(a, h) for a, h in zip(arms, self.hands))
        out["leg_length"] = 0.5 * sum(length(leg, f) for leg, f in zip(legs, self.feet))
        feet = [data.oMf[model.getFrameId(f)].translation for f in self.feet]
        out["feet_center"] = 0.5 * (feet[0] + feet[1])
        out["standing_height"] = float(self.standing_height)
        out["com_height"] = float(data.com[0][2])
        sole = self.contact(self.feet[0])
        out["foot_length"] = 2.0 * sole.half_length
        out["foot_width"] = 2.0 * sole.half_width
        out["trunk"] = data.oMf[model.getFrameId("trunk")].translation.copy()
        head = self.head_frame if self.head_frame is not None else "trunk"
        out["head"] = data.oMf[model.getFrameId(head)].translation.copy()
        return out

    def contact(self, name: str) -> ContactSurface:
        """Return a contact surface by name.

        Raises:
            InvalidInput: Unknown contact (lists the contacts).

        """
        for c in self.contacts:
            if c.name == name:
                return c
        raise InvalidInput(
            f"robot {self.name!r}: unknown contact {name!r}; contacts: "
            + ", ".join(c.name for c in self.contacts)
        )


def build_pinocchio_model(
    urdf_path: Path, extra_frames: Mapping[str, tuple[str, pin.SE3]] | None = None
) -> pin.Model:
    """Pinocchio model of a URDF with a free flyer named :data:`ROOT_JOINT` and extra frames.

    Args:
        urdf_path: URDF file.
        extra_frames: ``name -> (parent frame name, placement in the parent frame)``;
            each becomes an ``OP_FRAME`` on the parent frame's joint.

    Raises:
        HQPError: An extra frame's parent is missing or its name already exists.

    """
    model = pin.buildModelFromUrdf(str(urdf_path), pin.JointModelFreeFlyer(), ROOT_JOINT)
    for name, (parent_name, placement) in (extra_frames or {}).items():
        if model.existFrame(name):
            raise HQPError(f"{urdf_path.name}: frame {name!r} already exists")
        if not model.existFrame(parent_name):
            raise HQPError(f"{urdf_path.name}: parent frame {parent_name!r} of {name!r} missing")
        parent_id = model.getFrameId(parent_name)
        parent = model.frames[parent_id]
        model.addFrame(
            pin.Frame(
                name,
                parent.parentJoint,
                parent_id,
                parent.placement * placement,
                pin.FrameType.OP_FRAME,
            )
        )
    return model


def solve_standing(
    model: pin.Model,
    q_seed: np.ndarray,
    feet: tuple[str, str],
    *,
    com_offset: np.ndarray | None = None,
    weight: Callable[[int], float] | None = None,
    active: Callable[[int], bool] | None = None,
    iterations: int = 100,
    tol: float = 1e-12,
) -> np.ndarray:
    """Find a standing configuration near ``q_seed``: soles flat on ``z = 0``, CoM above them.

    Solves ``min ||q - q_seed||_W`` (tangent-space, weights ``W``) subject to:
    each sole frame at ``(x_seed, y_seed, 0)`` with identity orientation, and
    the horizontal centre of mass at the midpoint of the sole centres (plus
    ``com_offset``). Gauss-Newton with the constraint linearised each step.

    Args:
        model: Pinocchio model with a free flyer.
        q_seed: Seed configuration ``(nq,)`` (feet roughly level).
        feet: ``(left, right)`` sole frame names.
        com_offset: Horizontal offset ``(2,)`` of the centre of mass goal [m].
        weight: Weight of velocity index ``i`` in ``W`` (default: 1).
        active: Whether velocity index ``i`` may move (default: all); the
            others keep their seed values exactly.
        iterations: Maximum Gauss-Newton steps.
        tol: Stop when the squared constraint error is below this.

    Returns:
        The configuration ``(nq,)``.

    Raises:
        HQPError: The iteration did not converge.

    """
    data = model.createData()
    fids = [model.getFrameId(f) for f in feet]
    pin.framesForwardKinematics(model, data, q_seed)
    targets = []
    for fid in fids:
        p = data.oMf[fid].translation.copy()
        targets.append(pin.SE3(np.eye(3), np.array([p[0], p[1], 0.0])))
    com_goal = 0.5 * (targets[0].translation[:2] + targets[1].translation[:2])
    if com_offset is not None:
        com_goal = com_goal + np.asarray(com_offset, dtype=float)
    w = np.array([weight(i) if weight else 1.0 for i in range(model.nv)])
    w_inv = 1.0 / w
    if active is not None:
        w_inv *= np.array([1.0 if active(i) else 0.0 for i in range(model.nv)])
    q = q_seed.copy()
    err = np.inf
    for _ in range(iterations):
        pin.computeJointJacobians(model, data, q)
        pin.updateFramePlacements(model, data)
        rows = []
        errs = []
        for fid, target in zip(fids, targets):
            oMf = data.oMf[fid]
            J = pin.getFrameJacobian(model, data, fid, pin.LOCAL_WORLD_ALIGNED)
            errs.append(target.translation - oMf.translation)
            errs.append(oMf.rotation @ pin.log3(oMf.rotation.T @ target.rotation))
            rows.append(J)
        Jc = pin.jacobianCenterOfMass(model, data, q)
        errs.append(com_goal - data.com[0][:2])
        rows.append(Jc[:2])
        e = np.concatenate(errs)
        J = np.vstack(rows)
        err = float(e @ e)
        d0 = w_inv * w * pin.difference(model, q, q_seed)  # zero on locked indices
        if err < tol and np.linalg.norm(d0) < 1e-12:
            break
        JW = J * w_inv
        step = d0 + w_inv * (J.T @ np.linalg.solve(JW @ J.T, e - J @ d0))
        q = pin.integrate(model, q, step)
        if err < tol and np.linalg.norm(step) < 1e-10:
            break
    if err > 1e-10:
        raise HQPError(f"standing configuration: no convergence (squared error {err:.3g})")
    return q
