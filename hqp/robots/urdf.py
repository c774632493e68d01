"""Any humanoid from its URDF: :func:`from_urdf` and robot TOML files (:func:`load_file`).

``from_urdf(urdf, feet=(left, right), hands=(left, right))`` finds everything else, each
with an override option (see :data:`OPTIONS`):

* **Robot axes.** In the URDF's zero configuration, *up* points from the middle of the
  feet to the floating base, *left* from the right foot to the left one, *forward* is
  left x up. The standing configuration turns the base so that these axes are the
  world's ``x``, ``y``, ``z``.
* **Soles** (frames ``left_foot`` and ``right_foot``): from the collision geometry of each
  foot's body (every geometry rigidly attached to the foot frame's joint), in the robot
  axes at the zero configuration: the sole plane is the lowest point, the rectangle the
  bounding box of boxes and meshes, or of the centres of spheres (contact spheres at the
  sole's corners, as on the Unitree G1). The frame sits at the rectangle's centre on the
  sole plane, ``x`` forward and ``z`` normal to the sole. Mesh bounding boxes come from
  the meshes coal loads for pinocchio; Collada files declared ``Y_UP`` are read as ROS
  tools read them (assimp turns them to ``Z_UP``; the rotation is undone).
* **Hands** (``left_hand``, ``right_hand``): the named frames, plus ``hand_offset``.
* **Trunk** (``trunk``): the body where the two arms branch (the last joint common to both
  hands' chains), axes along the robot's. **Head** (``head``): the end of the branch of
  the trunk that holds neither arm (the neck), else a frame of the trunk's body whose name
  contains ``head``, else none. **Pelvis** (``pelvis``): the floating base's body.
* **Limits**: the URDF's; a joint without a position range, a velocity or an effort limit
  is an error naming it and the option that supplies it.
* **Capsules** for distance primitives: one per limb link, the hands and the soles.
* **Standing configuration**: soles flat on ``z = 0`` side by side, knees bent by
  ``knee_bend``, arms hanging, centre of mass above the middle of the soles, every joint
  inside its limits (see :func:`standing_configuration`).
* **Files**: a mesh-free URDF (the controller's and PlaCo's model, uniform frames as links)
  and an MJCF (MuJoCo) generated from one
  :class:`~hqp.robots.description.Description` into a cache directory, as for the bundled
  robots: a free joint, one motor per joint, one box per sole as the only colliding geometry,
  STL and OBJ meshes as visuals (capsules where a body has none MuJoCo can load).

A robot TOML file holds the same call: ``urdf`` (relative to the file, absolute, or
``package://...`` resolved through ``package_dirs`` and example-robot-data), ``feet``,
``hands``, optional ``name``, ``package_dirs`` and any option of :data:`OPTIONS`.
"""

from __future__ import annotations

import hashlib
import logging
import math
import os
import re
import site
import sys
import tempfile
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin
import tomllib

import hqp
from hqp.errors import HQPError, InvalidFrame
from hqp.model.layout import ContactType
from hqp.robots import description as desc_mod
from hqp.robots.description import (
    ContactParameters,
    Geom,
    Site,
    from_pinocchio,
    to_mjcf,
    to_urdf,
    write_if_changed,
)
from hqp.robots.robot import (
    ROOT_JOINT,
    BodyCapsule,
    ContactSurface,
    Robot,
    build_pinocchio_model,
    solve_standing,
)

logger = logging.getLogger(__name__)

SOLE_THICKNESS = 0.01
"""Thickness of the MuJoCo sole boxes [m] (bottom face = sole surface)."""

UNIFORM_FRAMES = ("left_foot", "right_foot", "left_hand", "right_hand", "trunk", "head",
                  "pelvis")
"""Frames every robot gets under these names."""

OPTIONS: dict[str, str] = {
    "sole": "{length, width [m], center = [x, y, z] in the foot frame}: the sole rectangle, "
            "instead of the foot's collision geometry",
    "hand_offset": "[x, y, z] [m]: the hand point in each hand frame (default: its origin)",
    "trunk": "frame or link of the trunk (default: where the arms branch)",
    "head": "frame or link of the head, or \"\" for none (default: the end of the neck)",
    "limb_radius": "radius of the limbs' capsules [m] (default: 5 % of the leg length)",
    "friction": "sole/floor friction coefficient (default 1.0)",
    "knee_bend": "knee flexion of the standing configuration [rad] (default 0.35)",
    "standing": "{joint = value [rad]}: joints of the standing configuration's seed "
                "(these joints keep their value unless they are leg joints)",
    "srdf": "SRDF file whose reference configuration seeds the standing one",
    "reference": "name of that reference configuration (default \"half_sitting\")",
    "arms_down": "whether the standing configuration hangs the arms down (default true)",
    "position_limits": "{joint = [lower, upper] [rad]}: replace or supply the URDF's",
    "velocity_limits": "{joint = limit [rad/s]}: replace or supply the URDF's",
    "torque_limits": "{joint = limit [N m]}: replace or supply the URDF's",
}
"""Override options of :func:`from_urdf` (and keys of a robot TOML file)."""

CONTACT = ContactParameters(solref=(0.01, 1.0), solimp=(0.99, 0.999, 0.001, 0.5, 2.0),
                            friction=1.0)
"""Sole/floor contact parameters (the bundled robots')."""


class RobotDescriptionError(HQPError):
    """A URDF, its options or a robot TOML file do not describe a humanoid hqp can build."""


# -- example-robot-data and package:// paths ----------------------------------------------------


def erd_share_dir() -> Path:
    """Return the ``share`` directory that holds ``example-robot-data/robots``.

    ``EXAMPLE_ROBOT_DATA_SHARE`` overrides the search of ``cmeel.prefix/share`` on ``sys.path``.

    Raises:
        RobotDescriptionError: example-robot-data is not installed.

    """
    candidates: list[Path] = []
    env = os.environ.get("EXAMPLE_ROBOT_DATA_SHARE")
    if env:
        candidates.append(Path(env))
    for entry in [*sys.path, *site.getsitepackages()]:
        candidates.append(Path(entry) / "cmeel.prefix" / "share")
    candidates.append(Path(sys.prefix) / "share")
    for share in candidates:
        if (share / "example-robot-data" / "robots").is_dir():
            return share
    raise RobotDescriptionError(
        "example-robot-data not found (looked for cmeel.prefix/share/example-robot-data/robots "
        "under sys.path); install it with `pip install example-robot-data` or set "
        "EXAMPLE_ROBOT_DATA_SHARE"
    )


def _search_dirs(package_dirs: Sequence[str | Path]) -> list[Path]:
    dirs = [Path(p) for p in package_dirs]
    try:
        dirs.append(erd_share_dir())
    except RobotDescriptionError:
        pass
    return dirs


def resolve_path(path: str | Path, package_dirs: Sequence[str | Path] = (),
                 base: Path | None = None) -> Path:
    """Resolve a URDF path: ``package://pkg/...`` through ``package_dirs``, else a file path.

    ``package://`` paths are looked up in each of ``package_dirs`` then in
    example-robot-data's ``share`` directory (``package://example-robot-data/robots/...``).
    A relative file path is taken relative to ``base`` (default: the working directory).

    Raises:
        RobotDescriptionError: No such file (names where it looked).

    """
    text = str(path)
    if text.startswith("package://"):
        rest = text[len("package://"):]
        dirs = _search_dirs(package_dirs)
        for d in dirs:
            if (d / rest).is_file():
                return (d / rest).resolve()
        raise RobotDescriptionError(f"{text}: not found under the package directories "
                                    f"{', '.join(str(d) for d in dirs) or '(none)'}")
    p = Path(text).expanduser()
    if not p.is_absolute() and base is not None:
        p = base / p
    if not p.is_file():
        raise RobotDescriptionError(f"URDF {str(p)!r}: no such file")
    return p.resolve()


# -- options ------------------------------------------------------------------------------------


@dataclass(frozen=True)
class _Options:
    sole: Mapping[str, Any] | None
    hand_offset: tuple[float, float, float]
    trunk: str | None
    head: str | None
    limb_radius: float | None
    friction: float
    knee_bend: float
    standing: Mapping[str, float]
    srdf: Path | None
    reference: str
    arms_down: bool
    position_limits: Mapping[str, tuple[float, float]]
    velocity_limits: Mapping[str, float]
    torque_limits: Mapping[str, float]


def _number(where: str, value: Any, *, positive: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise RobotDescriptionError(f"{where}: expected a finite number, got {value!r}")
    if positive and value <= 0:
        raise RobotDescriptionError(f"{where}: expected a positive number, got {value!r}")
    return float(value)


def _vector3(where: str, value: Any) -> tuple[float, float, float]:
    if not isinstance(value, (list, tuple)) or len(value) != 3:
        raise RobotDescriptionError(f"{where}: expected [x, y, z], got {value!r}")
    x, y, z = (_number(where, v) for v in value)
    return x, y, z


def _mapping(where: str, value: Any) -> Mapping[str, Any]:
    if not isinstance(value, Mapping):
        raise RobotDescriptionError(f"{where}: expected a table {{name = value}}, got {value!r}")
    return value


def _options(name: str, options: Mapping[str, Any], package_dirs: Sequence[str | Path],
             base: Path | None) -> _Options:
    for key in options:
        if key not in OPTIONS:
            raise RobotDescriptionError(f"robot {name!r}: unknown option {key!r}; options: "
                                        f"{', '.join(OPTIONS)}")
    sole = options.get("sole")
    if sole is not None:
        sole = _mapping(f"robot {name!r}: sole", sole)
        for k in sole:
            if k not in ("length", "width", "center"):
                raise RobotDescriptionError(f"robot {name!r}: sole: unknown key {k!r}; expected "
                                            "length, width, center")
        for k in ("length", "width"):
            if k not in sole:
                raise RobotDescriptionError(f"robot {name!r}: sole: missing {k!r} [m]")
            _number(f"robot {name!r}: sole.{k}", sole[k], positive=True)
        _vector3(f"robot {name!r}: sole.center", sole.get("center", [0.0, 0.0, 0.0]))
    srdf = options.get("srdf")
    srdf_path = None
    if srdf is not None:
        srdf_path = resolve_path(srdf, package_dirs, base)
    head = options.get("head")
    for key in ("trunk", "head"):
        if options.get(key) is not None and not isinstance(options[key], str):
            raise RobotDescriptionError(f"robot {name!r}: {key}: expected a frame name")
    position_limits = {
        j: tuple(_number(f"robot {name!r}: position_limits.{j}", x) for x in v)
        for j, v in _mapping(f"robot {name!r}: position_limits",
                             options.get("position_limits", {})).items()
    }
    for j, v in position_limits.items():
        if len(v) != 2 or not v[0] < v[1]:
            raise RobotDescriptionError(f"robot {name!r}: position_limits.{j}: expected "
                                        f"[lower, upper] with lower < upper, got {list(v)}")
    return _Options(
        sole=sole,
        hand_offset=_vector3(f"robot {name!r}: hand_offset",
                             options.get("hand_offset", [0.0, 0.0, 0.0])),
        trunk=options.get("trunk"),
        head=head,
        limb_radius=(None if options.get("limb_radius") is None else
                     _number(f"robot {name!r}: limb_radius", options["limb_radius"],
                             positive=True)),
        friction=_number(f"robot {name!r}: friction", options.get("friction", 1.0),
                         positive=True),
        knee_bend=_number(f"robot {name!r}: knee_bend", options.get("knee_bend", 0.35)),
        standing={j: _number(f"robot {name!r}: standing.{j}", v) for j, v in
                  _mapping(f"robot {name!r}: standing", options.get("standing", {})).items()},
        srdf=srdf_path,
        reference=str(options.get("reference", "half_sitting")),
        arms_down=bool(options.get("arms_down", True)),
        position_limits=position_limits,  # type: ignore[arg-type]
        velocity_limits={j: _number(f"robot {name!r}: velocity_limits.{j}", v, positive=True)
                         for j, v in _mapping(f"robot {name!r}: velocity_limits",
                                              options.get("velocity_limits", {})).items()},
        torque_limits={j: _number(f"robot {name!r}: torque_limits.{j}", v, positive=True)
                       for j, v in _mapping(f"robot {name!r}: torque_limits",
                                            options.get("torque_limits", {})).items()},
    )


# -- the model ----------------------------------------------------------------------------------


def _frame_id(model: pin.Model, name: str, what: str, robot: str) -> int:
    """Id of a frame (a link of the URDF is a body frame), or :class:`InvalidFrame`."""
    if not isinstance(name, str) or not model.existFrame(name):
        names = [f.name for f in model.frames if f.type in (pin.FrameType.BODY,
                                                            pin.FrameType.OP_FRAME)]
        raise InvalidFrame(str(name), names, where=f"robot {robot!r}: {what}")
    return model.getFrameId(name)


def _source_model(urdf: Path, name: str, opts: _Options) -> pin.Model:
    """Pinocchio model of the source URDF (free flyer), limits overridden and checked."""
    try:
        model = pin.buildModelFromUrdf(str(urdf), pin.JointModelFreeFlyer(), ROOT_JOINT)
    except (RuntimeError, ValueError) as exc:
        raise RobotDescriptionError(f"URDF {str(urdf)!r}: pinocchio cannot read it: "
                                    f"{str(exc).splitlines()[0]}") from None
    unsupported = [f"{model.names[j]} ({model.joints[j].shortname()})"
                   for j in range(2, model.njoints) if model.joints[j].nq != 1
                   or not model.joints[j].shortname().startswith(("JointModelR",))
                   or model.joints[j].shortname().startswith("JointModelRUB")]
    if unsupported:
        raise RobotDescriptionError(f"robot {name!r}: only revolute joints with a range are "
                                    f"supported; found {', '.join(unsupported)}")
    joints = {model.names[j]: model.joints[j] for j in range(2, model.njoints)}
    for table, label in ((opts.position_limits, "position_limits"),
                         (opts.velocity_limits, "velocity_limits"),
                         (opts.torque_limits, "torque_limits")):
        for joint in table:
            if joint not in joints:
                raise RobotDescriptionError(f"robot {name!r}: {label}: unknown joint {joint!r}; "
                                            f"joints: {', '.join(joints)}")
    lower, upper = model.lowerPositionLimit.copy(), model.upperPositionLimit.copy()
    effort, velocity = model.effortLimit.copy(), model.velocityLimit.copy()
    for joint, (lo, hi) in opts.position_limits.items():
        lower[joints[joint].idx_q], upper[joints[joint].idx_q] = lo, hi
    for joint, v in opts.velocity_limits.items():
        velocity[joints[joint].idx_v] = v
    for joint, v in opts.torque_limits.items():
        effort[joints[joint].idx_v] = v
    _physical_inertias(model, name)
    model.lowerPositionLimit, model.upperPositionLimit = lower, upper
    model.effortLimit, model.velocityLimit = effort, velocity
    missing: dict[str, list[str]] = {"position_limits": [], "velocity_limits": [],
                                     "torque_limits": []}
    for joint, jm in joints.items():
        lo, hi = lower[jm.idx_q], upper[jm.idx_q]
        if not (np.isfinite(lo) and np.isfinite(hi) and lo < hi and hi - lo < 4 * np.pi):
            missing["position_limits"].append(joint)
        if not (np.isfinite(velocity[jm.idx_v]) and velocity[jm.idx_v] > 0):
            missing["velocity_limits"].append(joint)
        if not (np.isfinite(effort[jm.idx_v]) and effort[jm.idx_v] > 0):
            missing["torque_limits"].append(joint)
    for label, bad in missing.items():
        if bad:
            what = {"position_limits": "position range (lower < upper)",
                    "velocity_limits": "velocity limit", "torque_limits": "effort limit"}
            raise RobotDescriptionError(
                f"robot {name!r}: URDF {urdf.name} gives no {what[label]} for joint"
                f"{'s' if len(bad) > 1 else ''} {', '.join(bad)}; give {label} = "
                f"{{{bad[0]} = ...}}")
    return model


def _physical_inertias(model: pin.Model, name: str) -> None:
    """Make every body's principal moments satisfy the triangle inequality (in place).

    MuJoCo refuses a body whose principal moments break ``A + B >= C`` (no rigid body has
    them; some URDFs carry rounded values that do) or are not positive (a point mass). A
    moment below ``1e-8 m`` [kg m^2] is raised to it; each offending moment is lowered to the
    sum of the other two (0.1 % below it); in the controller's model, hence in both
    generated files. Each change is logged.
    """
    for j in range(1, model.njoints):
        inertia = model.inertias[j]
        if inertia.mass <= 0.0:
            continue
        moments, axes = np.linalg.eigh(np.asarray(inertia.inertia))
        fixed = np.maximum(moments, 1e-8 * inertia.mass)  # a point mass: a 0.2 mm ball's
        for k in range(3):
            others = fixed.sum() - fixed[k]
            if fixed[k] > others + 1e-9 * moments.max():
                fixed[k] = 0.999 * others  # strictly inside, after rounding to text
        if np.allclose(fixed, moments, rtol=0.0, atol=0.0):
            continue
        logger.warning("robot %r: body of joint %r: principal moments %s break the triangle "
                       "inequality or are not positive; %s used", name, model.names[j], moments,
                       fixed)
        model.inertias[j] = pin.Inertia(inertia.mass, np.array(inertia.lever),
                                        axes @ np.diag(fixed) @ axes.T)


def _chain(model: pin.Model, joint: int) -> list[int]:
    """Joints from the root's child down to ``joint`` (the free flyer excluded)."""
    out = []
    while joint > 1:
        out.append(joint)
        joint = model.parents[joint]
    return out[::-1]


def _robot_axes(model: pin.Model, data: pin.Data, feet: tuple[int, int], name: str
                ) -> np.ndarray:
    """Rotation ``(3, 3)`` whose columns are the robot's forward, left, up at the zero pose."""
    p_left, p_right = (data.oMf[f].translation for f in feet)
    middle = 0.5 * (p_left + p_right)
    up = data.oMi[1].translation - middle
    if np.linalg.norm(up) < 1e-3:
        raise RobotDescriptionError(f"robot {name!r}: the feet are at the floating base")
    left = p_left - p_right
    if np.linalg.norm(left) < 1e-3:
        raise RobotDescriptionError(f"robot {name!r}: the left and right feet are at the same "
                                    "place; check the feet frames")
    base = data.oMi[1].rotation
    up = _nearest_axis(base, up)
    left = _nearest_axis(base, left)
    if abs(left @ up) > 0.5:
        raise RobotDescriptionError(f"robot {name!r}: the feet are not side by side below the "
                                    "floating base in the URDF's zero configuration; check the "
                                    "feet frames")
    return np.column_stack([np.cross(left, up), left, up])


def _nearest_axis(rotation: np.ndarray, direction: np.ndarray) -> np.ndarray:
    """Return the axis (+-x, +-y, +-z of ``rotation``) nearest to ``direction`` (world)."""
    scores = rotation.T @ direction
    k = int(np.argmax(np.abs(scores)))
    return np.sign(scores[k]) * rotation[:, k]


def _collada_y_up(path: str) -> bool:
    if not path.lower().endswith(".dae"):
        return False
    try:
        with open(path, "rb") as f:
            head = f.read(4096).decode("utf-8", "replace")
    except OSError:
        return False
    return re.search(r"<up_axis>\s*Y_UP\s*</up_axis>", head) is not None


def _geometry_points(obj: pin.GeometryObject) -> tuple[np.ndarray, np.ndarray] | None:
    """Points ``(k, 3)`` of a collision object in its own frame and a radius per point."""
    geo = obj.geometry
    kind = type(geo).__name__
    if kind == "Sphere":
        return np.zeros((1, 3)), np.array([float(geo.radius)])
    if kind == "Box":
        h = np.asarray(geo.halfSide, dtype=float)
        corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
        return corners * h, np.zeros(8)
    if hasattr(geo, "vertices"):
        v = np.asarray(geo.vertices(), dtype=float).reshape(-1, 3) * np.asarray(obj.meshScale)
        if obj.meshPath and _collada_y_up(obj.meshPath):
            v = v @ pin.utils.rotate("x", np.pi / 2).T
        return v, np.zeros(len(v))
    geo.computeLocalAABB()
    lo, hi = np.asarray(geo.aabb_local.min_), np.asarray(geo.aabb_local.max_)
    corners = np.array([[a, b, c] for a in (lo[0], hi[0]) for b in (lo[1], hi[1])
                        for c in (lo[2], hi[2])])
    return corners, np.zeros(8)


@dataclass(frozen=True)
class _Sole:
    half_length: float
    half_width: float
    placement: pin.SE3  # sole frame in the foot frame


def _sole(model: pin.Model, data: pin.Data, gmodel: pin.GeometryModel | None, foot: int,
          axes: np.ndarray, opts: _Options, name: str, label: str) -> _Sole:
    """Find the sole rectangle of a foot frame (see the module docstring)."""
    frame = model.frames[foot]
    R_foot = data.oMf[foot].rotation
    rotation = R_foot.T @ axes  # robot axes in the foot frame
    if opts.sole is not None:
        centre = np.asarray(opts.sole.get("center", [0.0, 0.0, 0.0]), dtype=float)
        return _Sole(0.5 * float(opts.sole["length"]), 0.5 * float(opts.sole["width"]),
                     pin.SE3(rotation, centre))
    objects = [] if gmodel is None else [o for o in gmodel.geometryObjects
                                         if o.parentJoint == frame.parentJoint]
    if not objects:
        raise RobotDescriptionError(
            f"robot {name!r}: {label} foot {frame.name!r} has no collision geometry on its body "
            f"({model.names[frame.parentJoint]!r}); give the sole: sole = {{length = ..., "
            "width = ..., center = [x, y, z]}} [m], center in the foot frame")
    points, radii, spheres = [], [], []
    oMf = data.oMf[foot]
    for obj in objects:
        got = _geometry_points(obj)
        if got is None:
            continue
        local, radius = got
        oMo = data.oMi[obj.parentJoint] * obj.placement
        world = local @ oMo.rotation.T + oMo.translation
        points.append((world - oMf.translation) @ axes)  # robot axes, from the foot origin
        radii.append(radius)
        spheres.append(type(obj.geometry).__name__ == "Sphere")
    p = np.vstack(points)
    r = np.concatenate(radii)
    bottom = float(np.min(p[:, 2] - r))
    lo, hi = p[:, :2].min(axis=0), p[:, :2].max(axis=0)
    if not all(spheres):  # boxes and meshes: their extent; spheres: their centres
        lo = np.minimum(lo, (p[:, :2] - r[:, None]).min(axis=0))
        hi = np.maximum(hi, (p[:, :2] + r[:, None]).max(axis=0))
    half = 0.5 * (hi - lo)
    if min(half) < 0.005:
        raise RobotDescriptionError(
            f"robot {name!r}: {label} foot {frame.name!r}: its collision geometry spans "
            f"{2 * half[0]:.3f} x {2 * half[1]:.3f} m on the floor, not a sole; give the sole: "
            "sole = {length = ..., width = ..., center = [x, y, z]} [m]")
    centre_robot = np.array([0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]), bottom])
    centre = R_foot.T @ (axes @ centre_robot)
    return _Sole(float(half[0]), float(half[1]), pin.SE3(rotation, centre))


def _add_frame(model: pin.Model, name: str, parent_frame: int, placement: pin.SE3,
               robot: str) -> None:
    """Add an ``OP_FRAME`` ``name`` at ``placement`` in the frame ``parent_frame``."""
    if model.existFrame(name):
        raise RobotDescriptionError(
            f"robot {robot!r}: the URDF already has a frame {name!r}; hqp names its own frames "
            f"{', '.join(UNIFORM_FRAMES)}: rename that link in the URDF")
    parent = model.frames[parent_frame]
    model.addFrame(pin.Frame(name, parent.parentJoint, parent_frame,
                             parent.placement * placement, pin.FrameType.OP_FRAME))


def _rename_existing(model: pin.Model, name: str, robot: str) -> None:
    """Rename a frame of the URDF that has a uniform name (``head`` -> ``head_link``)."""
    if not model.existFrame(name):
        return
    new = f"{name}_link"
    while model.existFrame(new):
        new += "_"
    fid = model.getFrameId(name)
    frame = model.frames[fid]
    frame.name = new
    model.frames[fid] = frame
    logger.info("robot %r: the URDF's frame %r is %r in hqp's model", robot, name, new)


def _common_joint(model: pin.Model, a: int, b: int) -> int:
    chain_a = [1, *_chain(model, a)]
    chain_b = set([1, *_chain(model, b)])
    common = [j for j in chain_a if j in chain_b]
    return common[-1]


def _head_frame(model: pin.Model, data: pin.Data, trunk_joint: int, hands: tuple[int, int],
                ) -> tuple[int, int] | None:
    """(parent frame id, joint) of the head, or ``None`` (see the module docstring)."""
    arms = set()
    for h in hands:
        arms.update(_chain(model, model.frames[h].parentJoint))
    neck = [j for j in range(2, model.njoints)
            if j not in arms and trunk_joint in _chain(model, j) and j != trunk_joint]
    if neck:
        end = max(neck, key=lambda j: (len(_chain(model, j)), data.oMi[j].translation[2]))
        body = next((i for i, f in enumerate(model.frames)
                     if f.parentJoint == end and f.type == pin.FrameType.BODY), None)
        if body is not None:
            return body, end
    on_trunk = [i for i, f in enumerate(model.frames)
                if f.parentJoint == trunk_joint and "head" in f.name.lower()
                and f.type in (pin.FrameType.BODY, pin.FrameType.OP_FRAME)]
    if on_trunk:
        return on_trunk[0], trunk_joint
    return None


# -- standing -----------------------------------------------------------------------------------


def _legs(model: pin.Model, feet: Sequence[str]) -> list[list[int]]:
    return [_chain(model, model.frames[model.getFrameId(f)].parentJoint) for f in feet]


def _knee(model: pin.Model, data: pin.Data, leg: list[int], foot: int, axes: np.ndarray
          ) -> tuple[int, float] | None:
    """(knee joint, flexion sign) of a leg: the pitch joint nearest mid-leg (zero pose)."""
    if len(leg) < 3:
        return None
    hip = data.oMi[leg[0]].translation @ axes[:, 2]
    ankle = data.oMf[foot].translation @ axes[:, 2]
    pitch = []
    for j in leg:
        axis = data.oMi[j].rotation @ _joint_axis(model, j)
        if abs(axis @ axes[:, 1]) > 0.9:
            pitch.append(j)
    if not pitch:
        return None
    middle = 0.5 * (hip + ankle)
    knee = min(pitch, key=lambda j: abs(data.oMi[j].translation @ axes[:, 2] - middle))
    # flexion moves the foot backward (the shank swings back)
    axis = data.oMi[knee].rotation @ _joint_axis(model, knee)
    lever = data.oMf[foot].translation - data.oMi[knee].translation
    backward = np.cross(axis, lever) @ axes[:, 0]
    return knee, (-1.0 if backward > 0 else 1.0)


def _joint_axis(model: pin.Model, j: int) -> np.ndarray:
    short = model.joints[j].shortname()
    if short in ("JointModelRX", "JointModelRY", "JointModelRZ"):
        return np.eye(3)["XYZ".index(short[-1])]
    return np.asarray(model.joints[j].extract().axis, dtype=float)


def _arms_down(model: pin.Model, q: np.ndarray, hands: Sequence[str], trunk_joint: int,
               axes: np.ndarray, locked: set[int]) -> np.ndarray:
    """Hang each arm: its hand below its shoulder, the arm joints inside their limits."""
    from scipy.optimize import least_squares

    data = model.createData()
    pin.framesForwardKinematics(model, data, q)
    q = q.copy()
    for hand in hands:
        fid = model.getFrameId(hand)
        arm = [j for j in _chain(model, model.frames[fid].parentJoint)
               if trunk_joint in _chain(model, j) and j != trunk_joint]
        arm = [j for j in arm if model.joints[j].idx_v not in locked]
        if not arm:
            continue
        shoulder = data.oMi[arm[0]].translation.copy()
        reach = float(np.linalg.norm(data.oMf[fid].translation - shoulder))
        lateral = (shoulder - data.oMi[trunk_joint].translation) @ axes[:, 1]
        goal = shoulder - 0.95 * reach * axes[:, 2] + 0.1 * reach * np.sign(lateral) * axes[:, 1]
        if (data.oMf[fid].translation - shoulder) @ axes[:, 2] < -0.8 * reach:
            continue  # already hanging
        idx = [model.joints[j].idx_q for j in arm]
        lo = model.lowerPositionLimit[idx] + 1e-3
        hi = model.upperPositionLimit[idx] - 1e-3
        x0 = np.clip(q[idx], lo, hi)

        def residual(x: np.ndarray, idx: list[int] = idx, fid: int = fid,
                     goal: np.ndarray = goal, x0: np.ndarray = x0) -> np.ndarray:
            qq = q.copy()
            qq[idx] = x
            pin.framesForwardKinematics(model, data, qq)
            return np.concatenate([data.oMf[fid].translation - goal, 0.05 * (x - x0)])

        q[idx] = least_squares(residual, x0, bounds=(lo, hi)).x
    return q


def standing_configuration(model: pin.Model, feet: Sequence[str], hands: Sequence[str],
                           trunk_joint: int, axes: np.ndarray, opts: _Options, name: str
                           ) -> np.ndarray:
    """Find a standing configuration ``(nq,)`` of a model with the uniform frames.

    The seed: the zero configuration (or the SRDF's reference configuration) with the base
    turned to the robot's axes and every joint brought 0.02 rad inside its range, each
    knee (the leg's pitch joint nearest mid-leg) bent by
    ``knee_bend`` in the direction that swings the shank back, the arms hung below the
    shoulders (a bounded least-squares fit of the arm joints), and ``standing`` applied. Then
    :func:`~hqp.robots.robot.solve_standing` moves the base translation and the leg joints
    (the knees ten times stiffer) until the soles lie flat on ``z = 0`` and the centre of
    mass is above their middle.

    Raises:
        RobotDescriptionError: No convergence, or the result leaves a joint's limits (the
            message names the joints and their values).

    """
    data = model.createData()
    if opts.srdf is not None:
        try:
            pin.loadReferenceConfigurations(model, str(opts.srdf), False)
        except (RuntimeError, ValueError) as exc:
            raise RobotDescriptionError(f"robot {name!r}: SRDF {opts.srdf}: {exc}") from None
        if opts.reference not in model.referenceConfigurations:
            raise RobotDescriptionError(
                f"robot {name!r}: SRDF {opts.srdf.name} has no configuration "
                f"{opts.reference!r}; it has {', '.join(model.referenceConfigurations) or 'none'}")
        q = np.array(model.referenceConfigurations[opts.reference])
    else:
        q = pin.neutral(model)
    q[3:7] = pin.Quaternion(axes.T).normalized().coeffs()  # the robot's axes on the world's
    margin = np.minimum(0.02, 0.25 * (model.upperPositionLimit[7:] - model.lowerPositionLimit[7:]))
    q[7:] = np.clip(q[7:], model.lowerPositionLimit[7:] + margin,
                    model.upperPositionLimit[7:] - margin)  # a zero outside the range
    legs = _legs(model, feet)
    leg_dofs = {model.joints[j].idx_v for leg in legs for j in leg}
    joints = {model.names[j]: model.joints[j] for j in range(2, model.njoints)}
    for joint in opts.standing:
        if joint not in joints:
            raise RobotDescriptionError(f"robot {name!r}: standing: unknown joint {joint!r}; "
                                        f"joints: {', '.join(joints)}")
    knees: set[int] = set()
    if opts.srdf is None and not opts.standing:
        pin.framesForwardKinematics(model, data, pin.neutral(model))
        for leg, foot in zip(legs, feet):
            found = _knee(model, data, leg, model.getFrameId(foot), _robot_axes_at_zero(
                model, data, feet))
            if found is None:
                continue
            knee, sign = found
            jm = model.joints[knee]
            lo, hi = model.lowerPositionLimit[jm.idx_q], model.upperPositionLimit[jm.idx_q]
            q[jm.idx_q] = float(np.clip(sign * opts.knee_bend, lo + 0.02, hi - 0.02))
            knees.add(jm.idx_v)
    for joint, value in opts.standing.items():
        q[joints[joint].idx_q] = value
    if opts.arms_down and opts.srdf is None and not opts.standing:
        q = _arms_down(model, q, hands, trunk_joint, axes, leg_dofs)
    pin.framesForwardKinematics(model, data, q)
    q[2] -= min(data.oMf[model.getFrameId(f)].translation[2] for f in feet)
    try:
        q = solve_standing(model, q, (feet[0], feet[1]),
                           weight=lambda i: 1e-2 if i < 3 else (10.0 if i in knees else 1.0),
                           active=lambda i: i < 3 or i in leg_dofs)
    except HQPError as exc:
        raise RobotDescriptionError(
            f"robot {name!r} cannot stand: with the base upright, the soles flat side by side "
            f"and the centre of mass above them, the leg joints found no solution ({exc}); "
            "seed it with standing = {joint = value} or knee_bend") from None
    outside = []
    for joint, jm in joints.items():
        lo, hi = model.lowerPositionLimit[jm.idx_q], model.upperPositionLimit[jm.idx_q]
        if not lo - 1e-9 <= q[jm.idx_q] <= hi + 1e-9:
            outside.append(f"{joint} = {q[jm.idx_q]:.3f} outside [{lo:.3f}, {hi:.3f}]")
    if outside:
        raise RobotDescriptionError(
            f"robot {name!r} cannot stand within its limits: the standing configuration found "
            f"puts {'; '.join(outside)}; seed it with standing = {{joint = value}} or knee_bend")
    return q


def _robot_axes_at_zero(model: pin.Model, data: pin.Data, feet: Sequence[str]) -> np.ndarray:
    return _robot_axes(model, data, (model.getFrameId(feet[0]), model.getFrameId(feet[1])), "")


# -- capsules and files -------------------------------------------------------------------------


def _body_names(model: pin.Model) -> dict[int, str]:
    names: dict[int, str] = {}
    for frame in model.frames:
        if frame.type == pin.FrameType.BODY and frame.parentJoint not in names:
            names[frame.parentJoint] = frame.name
    return names


def capsules(model: pin.Model, limb_radius: float, soles: Mapping[str, _Sole]
             ) -> tuple[BodyCapsule, ...]:
    """Capsule proxies of the limbs: one per link between consecutive joints, hands and feet.

    Each leg and arm link gets a capsule from its joint to its child joint (links shorter than
    3 cm are skipped), the last link of each arm a capsule to the hand frame, and each foot a
    capsule along its sole (heel to toe, resting on the sole). Radius: ``limb_radius``
    (hands: 0.8 of it; feet: a third of the sole width).
    """
    body_names = _body_names(model)
    r = limb_radius
    ends = {model.frames[model.getFrameId(f)].parentJoint: f for f in ("left_hand", "right_hand")}
    chains: set[int] = set()
    for frame in ("left_foot", "right_foot", "left_hand", "right_hand"):
        chains.update(_chain(model, model.frames[model.getFrameId(frame)].parentJoint))
    out: list[BodyCapsule] = []
    for j in sorted(chains):
        children = [c for c in range(j + 1, model.njoints) if model.parents[c] == j and c in chains]
        targets = [model.jointPlacements[c].translation for c in children]
        radii = [r] * len(targets)
        if j in ends:
            targets.append(model.frames[model.getFrameId(ends[j])].placement.translation)
            radii.append(0.8 * r)
        for k, (b, radius) in enumerate(zip(targets, radii)):
            if np.linalg.norm(b) < 0.03:
                continue
            out.append(BodyCapsule(f"{body_names[j]}_{k}", body_names[j], (0.0, 0.0, 0.0),
                                   (float(b[0]), float(b[1]), float(b[2])), radius))
    for side in ("left", "right"):
        frame = model.frames[model.getFrameId(f"{side}_foot")]
        sole = soles[side]
        radius = sole.half_width / 1.5
        a = frame.placement.act(np.array([-sole.half_length + radius, 0.0, radius]))
        b = frame.placement.act(np.array([sole.half_length - radius, 0.0, radius]))
        out.append(BodyCapsule(f"{side}_foot", body_names[frame.parentJoint],
                               (float(a[0]), float(a[1]), float(a[2])),
                               (float(b[0]), float(b[1]), float(b[2])), radius))
    return tuple(out)


def _visual_objects(model: pin.Model, urdf: Path, package_dirs: Sequence[Path]
                    ) -> list[pin.GeometryObject]:
    """Load the URDF's visual geometry objects (none, with a warning, if they cannot be)."""
    try:
        gmodel = pin.buildGeomFromUrdf(model, str(urdf), pin.GeometryType.VISUAL,
                                       package_dirs=[str(d) for d in package_dirs])
    except (RuntimeError, ValueError) as exc:
        logger.warning("%s: visual meshes not loaded (%s)", urdf.name, exc)
        return []
    return list(gmodel.geometryObjects)


def _visual_geoms(objects: Sequence[pin.GeometryObject], body_names: dict[int, str],
                  caps: Sequence[BodyCapsule]) -> dict[str, list[Geom]]:
    """STL/OBJ meshes of the URDF's visuals; the capsules where a body has none."""
    geoms: dict[str, list[Geom]] = {}
    for obj in objects:
        path = obj.meshPath
        if not path or not path.lower().endswith((".stl", ".obj")) or not Path(path).is_file():
            continue  # MuJoCo loads STL and OBJ (not DAE)
        geoms.setdefault(body_names[obj.parentJoint], []).append(
            Geom("mesh", tuple(float(s) for s in obj.meshScale),
                 pos=tuple(float(x) for x in obj.placement.translation),  # type: ignore[arg-type]
                 rotation=np.array(obj.placement.rotation), mesh=str(Path(path).resolve())))
    by_joint: dict[str, list[BodyCapsule]] = {}
    for c in caps:
        by_joint.setdefault(c.frame, []).append(c)
    for body, cs in by_joint.items():
        if body in geoms:
            continue
        geoms[body] = [Geom("capsule", (c.radius,), fromto=(*c.a, *c.b),
                            rgba=(0.7, 0.7, 0.75, 1.0)) for c in cs]
    return geoms


def _generate(model: pin.Model, name: str, visuals: Sequence[pin.GeometryObject],
              q_standing: np.ndarray, soles: Mapping[str, _Sole],
              caps: Sequence[BodyCapsule], friction: float) -> tuple[str, str]:
    """(URDF text, MJCF text) of the robot: one description, uniform frames as sites."""
    body_names = _body_names(model)
    geoms = _visual_geoms(visuals, body_names, caps)
    sites: dict[str, tuple[str, pin.SE3]] = {}
    for frame_name in UNIFORM_FRAMES:
        if not model.existFrame(frame_name):
            continue
        frame = model.frames[model.getFrameId(frame_name)]
        sites[frame_name] = (body_names[frame.parentJoint], frame.placement)
    for side in ("left", "right"):
        body, placement = sites[f"{side}_foot"]
        sole = soles[side]
        centre = placement.act(np.array([0.0, 0.0, 0.5 * SOLE_THICKNESS]))
        geoms.setdefault(body, []).append(
            Geom("box", (sole.half_length, sole.half_width, 0.5 * SOLE_THICKNESS),
                 pos=tuple(float(x) for x in centre),  # type: ignore[arg-type]
                 rotation=np.array(placement.rotation), contact=True, name=f"{side}_sole",
                 rgba=(0.2, 0.2, 0.2, 1.0)))
    contact = ContactParameters(CONTACT.solref, CONTACT.solimp, friction)
    description = from_pinocchio(model, name=name, sites=sites, geoms=geoms,
                                 body_names=body_names, root_height=float(q_standing[2]),
                                 contact=contact)
    description.keyframes["standing"] = np.concatenate(
        [q_standing[:3], q_standing[6:7], q_standing[3:6], q_standing[7:]])
    bodies = {b.name for b in description.bodies}
    for body in description.bodies:
        body.sites = [Site(s.name, s.pos, s.rotation, in_urdf=s.name not in bodies)
                      for s in body.sites]
    return to_urdf(description), to_mjcf(description)


def cache_dir() -> Path:
    """Directory of generated files: ``$HQP_CACHE_DIR`` or ``<tempdir>/hqp-<version>``."""
    env = os.environ.get("HQP_CACHE_DIR")
    root = Path(env) if env else Path(tempfile.gettempdir()) / f"hqp-{hqp.__version__}"
    return root / "robots"


# -- from_urdf ----------------------------------------------------------------------------------


def _pair(value: Any, what: str, name: str) -> tuple[str, str]:
    if (not isinstance(value, (list, tuple)) or len(value) != 2
            or not all(isinstance(v, str) for v in value)):
        raise RobotDescriptionError(f"robot {name!r}: {what}: expected (left, right) frame "
                                    f"names, got {value!r}")
    return value[0], value[1]


def from_urdf(
    urdf_path: str | Path,
    *,
    feet: Sequence[str],
    hands: Sequence[str],
    name: str | None = None,
    package_dirs: Sequence[str | Path] = (),
    **options: Any,
) -> Robot:
    """Build a :class:`Robot` from a humanoid's URDF (see the module docstring).

    Args:
        urdf_path: The URDF file (a path, or ``package://...``).
        feet: ``(left, right)`` frames or links of the feet.
        hands: ``(left, right)`` frames or links of the hands.
        name: Robot name (default: the URDF file's stem).
        package_dirs: Directories where ``package://`` mesh paths are found
            (example-robot-data's is always searched last).
        **options: Overrides, see :data:`OPTIONS`.

    Returns:
        The robot; its generated URDF and MJCF are cached (``$HQP_CACHE_DIR``).

    Raises:
        InvalidFrame: A foot, hand, trunk or head frame that does not exist (lists those that
            do).
        RobotDescriptionError: A foot without collision geometry (and no ``sole``), a joint
            without limits, an unsupported joint, an unknown option, or a robot that cannot
            stand.

    """
    urdf = resolve_path(urdf_path, package_dirs)
    name = name if name is not None else urdf.stem
    feet_pair = _pair(feet, "feet", name)
    hands_pair = _pair(hands, "hands", name)
    opts = _options(name, options, package_dirs, None)
    dirs = _search_dirs(package_dirs)
    model = _source_model(urdf, name, opts)
    data = model.createData()
    pin.framesForwardKinematics(model, data, pin.neutral(model))
    foot_ids = tuple(_frame_id(model, f, f"{s} foot", name) for f, s in zip(feet_pair,
                                                                            ("left", "right")))
    hand_ids = tuple(_frame_id(model, h, f"{s} hand", name) for h, s in zip(hands_pair,
                                                                            ("left", "right")))
    axes = _robot_axes(model, data, foot_ids, name)  # type: ignore[arg-type]
    gmodel = None
    if opts.sole is None:
        try:
            gmodel = pin.buildGeomFromUrdf(model, str(urdf), pin.GeometryType.COLLISION,
                                           package_dirs=[str(d) for d in dirs])
        except (RuntimeError, ValueError) as exc:
            raise RobotDescriptionError(
                f"robot {name!r}: the collision meshes of {urdf.name} cannot be loaded "
                f"({str(exc).splitlines()[0]}); give package_dirs or the sole") from None
    soles = {side: _sole(model, data, gmodel, fid, axes, opts, name, side)
             for side, fid in zip(("left", "right"), foot_ids)}
    visuals = _visual_objects(model, urdf, dirs)

    # the uniform frames
    trunk_joint = _common_joint(model, *(model.frames[h].parentJoint for h in hand_ids))
    if opts.trunk is not None:
        trunk_frame = _frame_id(model, opts.trunk, "trunk", name)
        trunk_joint = model.frames[trunk_frame].parentJoint
    else:
        trunk_frame = next(i for i, f in enumerate(model.frames)
                           if f.parentJoint == trunk_joint and f.type == pin.FrameType.BODY)
    head: tuple[int, int] | None
    if opts.head is not None:
        if opts.head == "":
            head = None
        else:
            fid = _frame_id(model, opts.head, "head", name)
            head = (fid, model.frames[fid].parentJoint)
    else:
        head = _head_frame(model, data, trunk_joint, hand_ids)  # type: ignore[arg-type]
    placements: dict[str, tuple[int, pin.SE3]] = {}
    for side, fid in zip(("left", "right"), foot_ids):
        placements[f"{side}_foot"] = (fid, soles[side].placement)
    for side, fid in zip(("left", "right"), hand_ids):
        placements[f"{side}_hand"] = (fid, pin.SE3(np.eye(3), np.array(opts.hand_offset)))

    def aligned(fid: int) -> pin.SE3:
        return pin.SE3(data.oMf[fid].rotation.T @ axes, np.zeros(3))

    placements["trunk"] = (trunk_frame, aligned(trunk_frame))
    if head is not None:
        # a head frame named in the options is taken as it is (a camera's axes); the one found
        # on the neck gets the robot's axes (x forward: the gaze primitive's default ray)
        placements["head"] = (head[0], pin.SE3.Identity() if opts.head else aligned(head[0]))
    root_body = next(i for i, f in enumerate(model.frames)
                     if f.parentJoint == 1 and f.type == pin.FrameType.BODY)
    if model.frames[root_body].name != "pelvis":
        placements["pelvis"] = (root_body, pin.SE3.Identity())
    for frame_name in placements:
        _rename_existing(model, frame_name, name)
    extra: dict[str, tuple[str, pin.SE3]] = {}
    for frame_name, (fid, placement) in placements.items():
        _add_frame(model, frame_name, fid, placement, name)
        extra[frame_name] = (model.frames[fid].name, placement)

    q = standing_configuration(model, ("left_foot", "right_foot"),
                               ("left_hand", "right_hand"), trunk_joint, axes, opts, name)
    data = model.createData()
    pin.framesForwardKinematics(model, data, q)
    legs = _legs(model, ("left_foot", "right_foot"))
    leg_length = float(np.mean([np.linalg.norm(data.oMi[leg[0]].translation
                                               - data.oMf[model.getFrameId(f)].translation)
                                for leg, f in zip(legs, ("left_foot", "right_foot"))]))
    radius = opts.limb_radius if opts.limb_radius is not None else 0.05 * leg_length
    caps = capsules(model, radius, soles)

    digest = hashlib.sha256()
    digest.update(str(urdf).encode())  # meshes are named by absolute path
    digest.update(urdf.read_bytes())
    for part in (Path(__file__), Path(desc_mod.__file__)):
        digest.update(part.read_bytes())
    digest.update(repr((name, feet_pair, hands_pair, sorted(options.items(), key=str),
                        [str(d) for d in dirs])).encode())
    digest.update(np.round(q, 9).tobytes())
    stem = cache_dir() / f"{re.sub(r'[^A-Za-z0-9_.-]', '_', name)}-{digest.hexdigest()[:16]}"
    mjcf_path, urdf_out = stem.with_suffix(".xml"), stem.with_suffix(".urdf")
    if not (mjcf_path.exists() and urdf_out.exists()):
        urdf_text, mjcf_text = _generate(model, name, visuals, q, soles, caps, opts.friction)
        write_if_changed(urdf_out, urdf_text)
        write_if_changed(mjcf_path, mjcf_text)
    generated = build_pinocchio_model(urdf_out)
    if list(generated.names) != list(model.names):
        raise RobotDescriptionError(f"{name}: generated URDF {urdf_out} has another joint order")
    contacts = tuple(
        ContactSurface(f"{side}_foot", f"{side}_foot", ContactType.SURFACE,
                       soles[side].half_length, soles[side].half_width, opts.friction)
        for side in ("left", "right"))
    q.setflags(write=False)
    return Robot(
        name=name,
        urdf_path=urdf_out,
        mjcf_path=mjcf_path,
        contacts=contacts,
        hands=("left_hand", "right_hand"),
        feet=("left_foot", "right_foot"),
        base_frame="pelvis",
        head_frame="head" if head is not None else None,
        q_standing=q,
        standing_height=float(data.oMf[model.getFrameId("pelvis")].translation[2]),
        source_urdf_path=urdf,
        capsules=caps,
        package_dirs=tuple(str(d) for d in dirs),
    )


# -- robot TOML files ---------------------------------------------------------------------------


FILE_KEYS = ("urdf", "feet", "hands", "name", "package_dirs")
"""Keys of a robot TOML file besides the :data:`OPTIONS`."""


def load_file(path: str | Path) -> Robot:
    """Build the robot of a robot TOML file (see the module docstring).

    Relative paths in the file (``urdf``, ``package_dirs``, ``srdf``) are relative to the file.

    Raises:
        RobotDescriptionError: No such file, not TOML, a missing or unknown key (the message
            names the file), or any error of :func:`from_urdf`.
        InvalidFrame: A frame that does not exist.

    """
    p = Path(path)
    if not p.is_file():
        raise RobotDescriptionError(f"{p}: no such robot file")
    try:
        data = tomllib.loads(p.read_text())
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise RobotDescriptionError(f"{p}: not valid TOML: {exc}") from None
    for key in data:
        if key not in FILE_KEYS and key not in OPTIONS:
            raise RobotDescriptionError(f"{p}: unknown key {key!r}; expected "
                                        f"{', '.join((*FILE_KEYS, *OPTIONS))}")
    for key in ("urdf", "feet", "hands"):
        if key not in data:
            raise RobotDescriptionError(f"{p}: missing key {key!r} (a robot file needs urdf, "
                                        "feet = [left, right], hands = [left, right])")
    if not isinstance(data["urdf"], str):
        raise RobotDescriptionError(f"{p}: urdf: expected a path string")
    base = p.resolve().parent
    dirs = data.get("package_dirs", [])
    if not isinstance(dirs, list) or not all(isinstance(d, str) for d in dirs):
        raise RobotDescriptionError(f"{p}: package_dirs: expected a list of directories")
    package_dirs = [str((base / Path(d).expanduser()).resolve()) for d in dirs]
    options = {k: v for k, v in data.items() if k in OPTIONS}
    if "srdf" in options and isinstance(options["srdf"], str) and not str(
            options["srdf"]).startswith("package://"):
        options["srdf"] = str(base / Path(options["srdf"]).expanduser())
    urdf = data["urdf"]
    if not urdf.startswith("package://"):
        urdf = str(base / Path(urdf).expanduser())
    try:
        return from_urdf(urdf, feet=data["feet"], hands=data["hands"],
                         name=data.get("name", p.stem), package_dirs=package_dirs, **options)
    except RobotDescriptionError as exc:
        raise RobotDescriptionError(f"{p}: {exc}") from None


__all__ = ["OPTIONS", "RobotDescriptionError", "from_urdf", "load_file", "resolve_path"]
