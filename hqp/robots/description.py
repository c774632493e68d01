"""A small, format-neutral description of a rigid-body robot and its MJCF/URDF writers.

One :class:`Description` (a tree of :class:`Body`, each with at most one
revolute :class:`Joint`, an :class:`Inertial`, simple :class:`Geom` shapes and
named :class:`Site` frames) generates both files:

* :func:`to_mjcf`: MuJoCo model with ``<compiler angle="radian"/>``, explicit
  inertials, a free joint on the root, the ``implicitfast`` integrator at 1 ms,
  a floor, one motor per actuated joint (no control clipping), joint ranges
  wider than the controller's limits by :attr:`Description.sim_range_margin`,
  and neither damping, armature nor friction loss.
* :func:`to_urdf`: URDF with the controller's limits; sites become massless
  links on fixed joints (PlaCo and pinocchio see them as frames).

:func:`from_pinocchio` builds a description from a pinocchio model (used for
the URDF robots of example-robot-data), so their MuJoCo models carry exactly
pinocchio's inertias and joint placements.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from xml.sax.saxutils import quoteattr

import numpy as np
import pinocchio as pin

from hqp.errors import InvalidInput


def _fmt(values: object) -> str:
    """Format numbers for XML: 12 significant digits, ``-0`` written as ``0``."""
    arr = np.atleast_1d(np.asarray(values, dtype=float)).ravel()
    out = []
    for x in arr:
        s = f"{x:.12g}"
        out.append("0" if s in ("-0", "0") else s)
    return " ".join(out)


@dataclass(frozen=True)
class Joint:
    """A revolute joint that moves its body relative to the parent body.

    Attributes:
        name: Joint name (also the motor's name in MuJoCo).
        axis: Unit axis ``(3,)`` in the body frame.
        lower: Controller's lower position limit [rad].
        upper: Controller's upper position limit [rad].
        effort: Torque limit [N m].
        velocity: Velocity limit [rad/s].

    """

    name: str
    axis: tuple[float, float, float]
    lower: float
    upper: float
    effort: float
    velocity: float


@dataclass(frozen=True)
class Inertial:
    """Mass properties of a body, in the body frame.

    Attributes:
        mass: Mass [kg].
        com: Centre of mass ``(3,)`` [m].
        inertia: Rotational inertia about the centre of mass ``(3, 3)`` [kg m^2],
            body-frame axes.

    """

    mass: float
    com: np.ndarray
    inertia: np.ndarray


@dataclass(frozen=True)
class Geom:
    """A simple shape attached to a body.

    Attributes:
        kind: ``"box"`` (size = half-lengths), ``"sphere"`` (size = radius),
            ``"capsule"`` (``fromto`` endpoints, size = radius) or ``"mesh"``
            (``mesh`` = file path, size = scale).
        size: Shape parameters (see ``kind``).
        pos: Position ``(3,)`` in the body frame [m].
        rotation: Orientation ``(3, 3)`` in the body frame.
        fromto: Capsule endpoints ``(6,)`` in the body frame [m].
        mesh: Mesh file path (``kind == "mesh"``).
        contact: Whether the geom collides (only sole geoms do).
        name: Geom name (optional).
        rgba: Colour.

    """

    kind: str
    size: tuple[float, ...]
    pos: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rotation: np.ndarray | None = None
    fromto: tuple[float, ...] | None = None
    mesh: str | None = None
    contact: bool = False
    name: str = ""
    rgba: tuple[float, float, float, float] = (0.7, 0.7, 0.75, 1.0)


@dataclass(frozen=True)
class Site:
    """A named frame rigidly attached to a body.

    Attributes:
        name: Frame name (a site in MJCF, a massless link in URDF).
        pos: Position ``(3,)`` in the body frame [m].
        rotation: Orientation ``(3, 3)`` in the body frame (identity if ``None``).
        in_urdf: Whether the URDF gets a link for it (``False`` for a site that
            marks a body's own frame, which the URDF already has as a link).

    """

    name: str
    pos: tuple[float, float, float]
    rotation: np.ndarray | None = None
    in_urdf: bool = True


@dataclass
class Body:
    """A rigid body of the tree.

    Attributes:
        name: Body (link) name.
        parent: Parent body name (``None`` for the root, which floats).
        pos: Position of the body frame in the parent frame at zero joint angle [m].
        rotation: Orientation ``(3, 3)`` of the body frame in the parent frame.
        joint: The revolute joint between parent and body (``None`` for the root).
        inertial: Mass properties.
        geoms: Shapes (visual, and contact where flagged).
        sites: Named frames.

    """

    name: str
    parent: str | None
    pos: tuple[float, float, float]
    rotation: np.ndarray | None
    joint: Joint | None
    inertial: Inertial
    geoms: list[Geom] = field(default_factory=list)
    sites: list[Site] = field(default_factory=list)


@dataclass
class ContactParameters:
    """MuJoCo contact parameters of the soles and the floor.

    Attributes:
        solref: ``(timeconst [s], dampratio)``.
        solimp: ``(dmin, dmax, width [m], midpoint, power)``.
        friction: Sliding friction coefficient.

    """

    solref: tuple[float, float] = (0.01, 1.0)
    solimp: tuple[float, ...] = (0.99, 0.999, 0.001, 0.5, 2.0)
    friction: float = 1.0


@dataclass
class Description:
    """A robot: bodies in depth-first order (parents before children).

    Attributes:
        name: Robot name.
        bodies: Bodies, root first, each after its parent.
        root_height: Initial height of the root in the MJCF [m].
        sim_range_margin: MuJoCo joint ranges are the controller's widened by
            this much on each side [rad].
        contact: Sole/floor contact parameters.
        keyframes: Named MuJoCo configurations (MuJoCo ``qpos`` order).

    """

    name: str
    bodies: list[Body]
    root_height: float = 1.0
    sim_range_margin: float = 0.2
    contact: ContactParameters = field(default_factory=ContactParameters)
    keyframes: dict[str, np.ndarray] = field(default_factory=dict)

    def __post_init__(self) -> None:
        seen: set[str] = set()
        for i, body in enumerate(self.bodies):
            if (body.parent is None) != (i == 0):
                raise InvalidInput(f"Description {self.name!r}: only the first body is the root")
            if body.parent is not None and body.parent not in seen:
                raise InvalidInput(
                    f"Description {self.name!r}: body {body.name!r} comes before its parent"
                )
            if (body.joint is None) != (body.parent is None):
                raise InvalidInput(
                    f"Description {self.name!r}: body {body.name!r} needs exactly one joint"
                )
            seen.add(body.name)

    @property
    def joints(self) -> list[Joint]:
        """Actuated joints, in depth-first order."""
        return [b.joint for b in self.bodies if b.joint is not None]

    @property
    def mass(self) -> float:
        """Total mass [kg]."""
        return float(sum(b.inertial.mass for b in self.bodies))

    def children(self, name: str | None) -> list[Body]:
        """Bodies whose parent is ``name``."""
        return [b for b in self.bodies if b.parent == name]


# -- MJCF ---------------------------------------------------------------------------------------


def _quat_attr(rotation: np.ndarray | None) -> str:
    if rotation is None or np.allclose(rotation, np.eye(3), atol=1e-12):
        return ""
    quat = pin.Quaternion(np.asarray(rotation, dtype=float))
    quat.normalize()
    return f' quat="{_fmt([quat.w, quat.x, quat.y, quat.z])}"'


def _inertial_mjcf(inertial: Inertial) -> str:
    inertia = np.asarray(inertial.inertia, dtype=float)
    full = [inertia[0, 0], inertia[1, 1], inertia[2, 2],
            inertia[0, 1], inertia[0, 2], inertia[1, 2]]
    return (
        f'<inertial pos="{_fmt(inertial.com)}" mass="{_fmt(inertial.mass)}" '
        f'fullinertia="{_fmt(full)}"/>'
    )


def _geom_mjcf(geom: Geom, meshes: dict[str, str]) -> str:
    name = f" name={quoteattr(geom.name)}" if geom.name else ""
    cls = ' class="sole"' if geom.contact else ' class="visual"'
    rgba = f' rgba="{_fmt(geom.rgba)}"'
    if geom.kind == "capsule":
        return (
            f'<geom{name}{cls} type="capsule" fromto="{_fmt(geom.fromto)}" '
            f'size="{_fmt(geom.size)}"{rgba}/>'
        )
    if geom.kind == "mesh":
        mesh_name = meshes[f"{geom.mesh}|{_fmt(geom.size)}"]
        return (
            f'<geom{name}{cls} type="mesh" mesh="{mesh_name}" pos="{_fmt(geom.pos)}"'
            f"{_quat_attr(geom.rotation)}{rgba}/>"
        )
    return (
        f'<geom{name}{cls} type="{geom.kind}" size="{_fmt(geom.size)}" pos="{_fmt(geom.pos)}"'
        f"{_quat_attr(geom.rotation)}{rgba}/>"
    )


def to_mjcf(desc: Description) -> str:
    """MuJoCo XML of a description (robot, floor, motors, keyframes).

    Returns:
        The MJCF text.

    """
    meshes: dict[str, str] = {}
    for body in desc.bodies:
        for geom in body.geoms:
            if geom.kind == "mesh":
                key = f"{geom.mesh}|{_fmt(geom.size)}"
                meshes.setdefault(key, f"mesh{len(meshes)}")
    c = desc.contact
    lines = [
        f"<mujoco model={quoteattr(desc.name)}>",
        "  <!-- Generated by hqp.robots.description; do not edit by hand. -->",
        '  <compiler angle="radian" autolimits="true" inertiafromgeom="false"/>',
        '  <option timestep="0.001" integrator="implicitfast"/>',
        "  <default>",
        '    <geom contype="0" conaffinity="0" group="1"/>',
        '    <default class="visual"><geom contype="0" conaffinity="0" group="1"/></default>',
        '    <default class="sole">',
        f'      <geom contype="1" conaffinity="0" condim="3" group="3" friction="{_fmt(c.friction)}'
        f' 0.005 0.0001" solref="{_fmt(c.solref)}" solimp="{_fmt(c.solimp)}"/>',
        "    </default>",
        "  </default>",
    ]
    if meshes:
        lines.append("  <asset>")
        for key, mesh_name in meshes.items():
            path, scale = key.split("|")
            lines.append(
                f"    <mesh name={quoteattr(mesh_name)} file={quoteattr(path)} scale=\"{scale}\"/>"
            )
        lines.append("  </asset>")
    lines += [
        "  <worldbody>",
        '    <light name="sun" pos="0 0 5" dir="0 0 -1" directional="true"/>',
        f'    <geom name="floor" type="plane" size="0 0 0.05" contype="1" conaffinity="1" '
        f'condim="3" friction="{_fmt(c.friction)} 0.005 0.0001" solref="{_fmt(c.solref)}" '
        f'solimp="{_fmt(c.solimp)}" rgba="0.8 0.8 0.8 1"/>',
    ]

    def emit(body: Body, indent: str) -> None:
        pos = (0.0, 0.0, desc.root_height) if body.parent is None else body.pos
        lines.append(
            f"{indent}<body name={quoteattr(body.name)} pos=\"{_fmt(pos)}\""
            f"{_quat_attr(body.rotation)}>"
        )
        inner = indent + "  "
        if body.joint is None:
            lines.append(f'{inner}<freejoint name="root"/>')
        else:
            j = body.joint
            m = desc.sim_range_margin
            lines.append(
                f"{inner}<joint name={quoteattr(j.name)} type=\"hinge\" axis=\"{_fmt(j.axis)}\" "
                f'limited="true" range="{_fmt([j.lower - m, j.upper + m])}"/>'
            )
        lines.append(inner + _inertial_mjcf(body.inertial))
        for geom in body.geoms:
            lines.append(inner + _geom_mjcf(geom, meshes))
        for site in body.sites:
            lines.append(
                f"{inner}<site name={quoteattr(site.name)} pos=\"{_fmt(site.pos)}\""
                f'{_quat_attr(site.rotation)} size="0.01"/>'
            )
        for child in desc.children(body.name):
            emit(child, inner)
        lines.append(f"{indent}</body>")

    emit(desc.bodies[0], "    ")
    lines.append("  </worldbody>")
    lines.append("  <actuator>")
    for j in desc.joints:
        lines.append(
            f"    <motor name={quoteattr(j.name)} joint={quoteattr(j.name)} gear=\"1\" "
            'ctrllimited="false"/>'
        )
    lines.append("  </actuator>")
    if desc.keyframes:
        lines.append("  <keyframe>")
        for name, qpos in desc.keyframes.items():
            lines.append(f"    <key name={quoteattr(name)} qpos=\"{_fmt(qpos)}\"/>")
        lines.append("  </keyframe>")
    lines.append("</mujoco>")
    return "\n".join(lines) + "\n"


# -- URDF ---------------------------------------------------------------------------------------


def _rpy(rotation: np.ndarray | None) -> str:
    if rotation is None:
        return "0 0 0"
    return _fmt(pin.rpy.matrixToRpy(np.asarray(rotation, dtype=float)))


def _urdf_geometry(geom: Geom) -> tuple[str, str, str] | None:
    """(origin xyz, origin rpy, geometry xml) of a geom, or None if URDF cannot show it."""
    if geom.kind == "box":
        size = _fmt(2 * np.asarray(geom.size))
        return _fmt(geom.pos), _rpy(geom.rotation), f'<box size="{size}"/>'
    if geom.kind == "sphere":
        return _fmt(geom.pos), _rpy(geom.rotation), f'<sphere radius="{_fmt(geom.size[0])}"/>'
    if geom.kind == "capsule" and geom.fromto is not None:
        a = np.asarray(geom.fromto[:3])
        b = np.asarray(geom.fromto[3:])
        axis = b - a
        length = float(np.linalg.norm(axis))
        if length < 1e-9:
            return None
        z = axis / length
        rot = pin.Quaternion.FromTwoVectors(np.array([0.0, 0.0, 1.0]), z).matrix()
        return (
            _fmt((a + b) / 2),
            _rpy(rot),
            f'<cylinder radius="{_fmt(geom.size[0])}" length="{_fmt(length)}"/>',
        )
    return None


def to_urdf(desc: Description) -> str:
    """URDF text of a description (controller limits; sites as massless links).

    Returns:
        The URDF text.

    """
    lines = [
        '<?xml version="1.0"?>',
        "<!-- Generated by hqp.robots.description; do not edit by hand. -->",
        f"<robot name={quoteattr(desc.name)}>",
    ]
    for body in desc.bodies:
        inertial = body.inertial
        inertia = np.asarray(inertial.inertia, dtype=float)
        lines += [
            f"  <link name={quoteattr(body.name)}>",
            "    <inertial>",
            f'      <origin xyz="{_fmt(inertial.com)}" rpy="0 0 0"/>',
            f'      <mass value="{_fmt(inertial.mass)}"/>',
            f'      <inertia ixx="{_fmt(inertia[0, 0])}" ixy="{_fmt(inertia[0, 1])}" '
            f'ixz="{_fmt(inertia[0, 2])}" iyy="{_fmt(inertia[1, 1])}" iyz="{_fmt(inertia[1, 2])}" '
            f'izz="{_fmt(inertia[2, 2])}"/>',
            "    </inertial>",
        ]
        for geom in body.geoms:
            shown = _urdf_geometry(geom)
            if shown is None:
                continue
            xyz, rpy, geometry = shown
            tag = "collision" if geom.contact else "visual"
            lines += [
                f"    <{tag}>",
                f'      <origin xyz="{xyz}" rpy="{rpy}"/>',
                f"      <geometry>{geometry}</geometry>",
                f"    </{tag}>",
            ]
        lines.append("  </link>")
        if body.joint is not None:
            j = body.joint
            lines += [
                f"  <joint name={quoteattr(j.name)} type=\"revolute\">",
                f"    <parent link={quoteattr(str(body.parent))}/>",
                f"    <child link={quoteattr(body.name)}/>",
                f'    <origin xyz="{_fmt(body.pos)}" rpy="{_rpy(body.rotation)}"/>',
                f'    <axis xyz="{_fmt(j.axis)}"/>',
                f'    <limit lower="{_fmt(j.lower)}" upper="{_fmt(j.upper)}" '
                f'effort="{_fmt(j.effort)}" velocity="{_fmt(j.velocity)}"/>',
                "  </joint>",
            ]
        for site in body.sites:
            if not site.in_urdf:
                continue
            lines += [
                f"  <link name={quoteattr(site.name)}/>",
                f"  <joint name={quoteattr(site.name + '_fixed')} type=\"fixed\">",
                f"    <parent link={quoteattr(body.name)}/>",
                f"    <child link={quoteattr(site.name)}/>",
                f'    <origin xyz="{_fmt(site.pos)}" rpy="{_rpy(site.rotation)}"/>',
                "  </joint>",
            ]
    lines.append("</robot>")
    return "\n".join(lines) + "\n"


def write_if_changed(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` unless the file already holds exactly that text."""
    if path.exists() and path.read_text() == text:
        return
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(path.suffix + f".tmp{np.random.default_rng().integers(1 << 30)}")
    tmp.write_text(text)
    tmp.replace(path)


# -- from pinocchio -----------------------------------------------------------------------------


def from_pinocchio(
    model: pin.Model,
    *,
    name: str,
    sites: dict[str, tuple[str, pin.SE3]] | None = None,
    geoms: dict[str, list[Geom]] | None = None,
    body_names: dict[int, str] | None = None,
    root_height: float = 1.0,
    contact: ContactParameters | None = None,
) -> Description:
    """Describe a pinocchio model with a free-flyer root and 1-DoF revolute joints.

    Each joint ``j >= 1`` becomes a body whose frame is the joint frame, with
    pinocchio's inertia ``model.inertias[j]`` (fixed links already merged by the
    URDF parser) and the joint's placement in its parent joint frame.

    Args:
        model: Pinocchio model (joint 1 a free flyer; other joints revolute,
            aligned or unaligned).
        name: Robot name.
        sites: Extra named frames: ``name -> (body name, placement in that body)``.
        geoms: Geoms by body name.
        body_names: Body name by joint index (default: ``model.names[j]``).
        root_height: Initial root height of the MJCF [m].
        contact: Contact parameters.

    Raises:
        InvalidInput: A joint that is neither the free flyer nor revolute.

    """
    body_names = dict(body_names or {})
    names = {j: body_names.get(j, model.names[j]) for j in range(1, model.njoints)}
    bodies: list[Body] = []
    for j in range(1, model.njoints):
        jm = model.joints[j]
        short = jm.shortname()
        inertia = model.inertias[j]
        inertial = Inertial(
            mass=float(inertia.mass), com=np.array(inertia.lever), inertia=np.array(inertia.inertia)
        )
        placement = model.jointPlacements[j]
        if j == 1:
            if short != "JointModelFreeFlyer":
                raise InvalidInput(f"{name}: joint 1 must be a free flyer, got {short}")
            joint = None
            parent = None
        else:
            if short in ("JointModelRX", "JointModelRY", "JointModelRZ"):
                axis = np.eye(3)["XYZ".index(short[-1])]
            elif short == "JointModelRevoluteUnaligned":
                axis = np.array(jm.extract().axis)
            else:
                raise InvalidInput(f"{name}: joint {model.names[j]!r} of type {short} unsupported")
            lo = float(model.lowerPositionLimit[jm.idx_q])
            hi = float(model.upperPositionLimit[jm.idx_q])
            joint = Joint(
                name=model.names[j],
                axis=(float(axis[0]), float(axis[1]), float(axis[2])),
                lower=lo,
                upper=hi,
                effort=float(model.effortLimit[jm.idx_v]),
                velocity=float(model.velocityLimit[jm.idx_v]),
            )
            parent = names[model.parents[j]]
        bodies.append(
            Body(
                name=names[j],
                parent=parent,
                pos=tuple(float(x) for x in placement.translation),  # type: ignore[arg-type]
                rotation=np.array(placement.rotation),
                joint=joint,
                inertial=inertial,
                geoms=list((geoms or {}).get(names[j], [])),
            )
        )
    by_name = {b.name: b for b in bodies}
    for site_name, (body_name, placement) in (sites or {}).items():
        by_name[body_name].sites.append(
            Site(
                site_name,
                tuple(float(x) for x in placement.translation),  # type: ignore[arg-type]
                np.array(placement.rotation),
            )
        )
    return Description(
        name=name, bodies=bodies, root_height=root_height, contact=contact or ContactParameters()
    )
