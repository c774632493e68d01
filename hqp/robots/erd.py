"""Robots from example-robot-data: Unitree G1 (29 DoF) and PAL Robotics TALOS (32 DoF).

The URDFs ship with the ``example-robot-data`` package (no Python module in
the installed version: the files live under
``<site-packages>/cmeel.prefix/share/example-robot-data/robots/``; set
``EXAMPLE_ROBOT_DATA_SHARE`` to the ``share`` directory to override). At first
use, one :class:`~hqp.robots.description.Description` is built from
pinocchio's model of the source URDF (fixed links merged) plus the uniform
frames, and both files are generated from it into a cache directory
(``$HQP_CACHE_DIR`` or ``<tempdir>/hqp-<version>``), keyed by a hash of the
inputs; example-robot-data's own files are never copied into the project.

The generated URDF (:attr:`Robot.urdf_path`, the controller's and PlaCo's
model) has no meshes, and the uniform frames as links on fixed joints; tests
check that it has the source URDF's inertias, placements and limits. The
generated MJCF carries exactly the same inertias and joint placements, with:

* a free joint on the root, one motor per actuated joint (no control clipping;
  the torque limits are the URDF ``effort`` and live in the controller's model);
* joint ranges the URDF's widened by 0.2 rad, no damping, armature or friction
  loss (TALOS's URDF declares damping and friction on its upper body; neither
  pinocchio's dynamics nor the controller use them, so the simulator must not
  either);
* one box per sole (``condim`` 3) as the only colliding geometry, the STL
  meshes as visual geoms (DAE meshes, which MuJoCo cannot load, are dropped);
* sites for the uniform frames (``left_foot``, ``right_foot``, ``left_hand``,
  ``right_hand``, ``trunk``, ``pelvis``, ``head``).

Sole geometry: G1's four contact spheres of ``*_ankle_roll_link`` span
``x in [-0.05, 0.12]``, ``y in [-0.03, 0.03]`` (rear pair at +-0.025) and touch
the ground 0.035 m below the link; TALOS's sole collision mesh spans
``x in [-0.1163, 0.1046]``, ``y in [-0.0672, 0.0672]`` around ``*_sole_link``.
"""

from __future__ import annotations

import hashlib
import os
import site
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pinocchio as pin

import hqp
from hqp.errors import HQPError, UnknownName
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
    BodyCapsule,
    ContactSurface,
    Robot,
    build_pinocchio_model,
    solve_standing,
)

SOLE_THICKNESS = 0.01
"""Thickness of the MuJoCo sole boxes [m] (bottom face = sole surface)."""
FRICTION = 1.0
"""Sole/floor friction coefficient."""
CONTACT = ContactParameters(solref=(0.01, 1.0), solimp=(0.99, 0.999, 0.001, 0.5, 2.0),
                            friction=FRICTION)
"""Sole/floor contact parameters (same as the paper humanoid's)."""


def erd_share_dir() -> Path:
    """Return the ``share`` directory that holds ``example-robot-data/robots``.

    Raises:
        HQPError: example-robot-data is not installed.

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
    raise HQPError(
        "example-robot-data not found (looked for cmeel.prefix/share/example-robot-data/robots "
        "under sys.path); install it with `pip install example-robot-data` or set "
        "EXAMPLE_ROBOT_DATA_SHARE"
    )


def erd_robots_dir() -> Path:
    """``.../share/example-robot-data/robots``."""
    return erd_share_dir() / "example-robot-data" / "robots"


@dataclass(frozen=True)
class _Spec:
    name: str
    urdf: str
    srdf: str | None
    frames: dict[str, tuple[str, tuple[float, float, float]]]
    sole_half: tuple[float, float]
    seed: dict[str, float]
    head: str | None
    limb_radius: float


G1 = _Spec(
    name="g1",
    urdf="g1_description/urdf/g1_29dof_rev_1_0.urdf",
    srdf=None,
    frames={
        "left_foot": ("left_ankle_roll_link", (0.035, 0.0, -0.035)),
        "right_foot": ("right_ankle_roll_link", (0.035, 0.0, -0.035)),
        "left_hand": ("left_rubber_hand", (0.054, 0.0, 0.0)),
        "right_hand": ("right_rubber_hand", (0.054, 0.0, 0.0)),
        "trunk": ("torso_link", (0.0, 0.0, 0.0)),
        "head": ("d435_link", (0.0, 0.0, 0.0)),
    },
    sole_half=(0.085, 0.03),
    limb_radius=0.035,
    seed={
        "left_hip_pitch_joint": -0.2, "left_knee_joint": 0.4, "left_ankle_pitch_joint": -0.2,
        "right_hip_pitch_joint": -0.2, "right_knee_joint": 0.4, "right_ankle_pitch_joint": -0.2,
        "left_shoulder_roll_joint": 0.2, "right_shoulder_roll_joint": -0.2,
        "left_elbow_joint": 1.2, "right_elbow_joint": 1.2,
    },
    head="head",
)

TALOS = _Spec(
    name="talos",
    urdf="talos_data/robots/talos_reduced.urdf",
    srdf="talos_data/srdf/talos.srdf",
    frames={
        "left_foot": ("left_sole_link", (-0.0059, 0.0, 0.0)),
        "right_foot": ("right_sole_link", (-0.0059, 0.0, 0.0)),
        "left_hand": ("gripper_left_base_link", (0.0, 0.0, -0.1)),
        "right_hand": ("gripper_right_base_link", (0.0, 0.0, -0.1)),
        "trunk": ("torso_2_link", (0.0, 0.0, 0.0)),
        "pelvis": ("base_link", (0.0, 0.0, 0.0)),
        "head": ("head_2_link", (0.0, 0.0, 0.0)),
    },
    sole_half=(0.1104, 0.0672),
    limb_radius=0.06,
    seed={},
    head="head",
)

SPECS = {"g1": G1, "talos": TALOS}


def _extra_frames(spec: _Spec) -> dict[str, tuple[str, pin.SE3]]:
    return {
        name: (parent, pin.SE3(np.eye(3), np.array(offset)))
        for name, (parent, offset) in spec.frames.items()
    }


def _seed(spec: _Spec, model: pin.Model) -> np.ndarray:
    if spec.srdf is not None:
        pin.loadReferenceConfigurations(model, str(erd_robots_dir() / spec.srdf), False)
        q = np.array(model.referenceConfigurations["half_sitting"])
    else:
        q = pin.neutral(model)
        q[2] = 1.0
    for joint, value in spec.seed.items():
        q[model.joints[model.getJointId(joint)].idx_q] = value
    return q


def _standing(spec: _Spec, model: pin.Model) -> np.ndarray:
    """Standing pose: base translation and leg joints move, base stays upright, rest as seeded."""
    legs: set[int] = set()
    for foot in ("left_foot", "right_foot"):
        joint = model.frames[model.getFrameId(foot)].parentJoint
        while joint > 1:
            legs.add(model.joints[joint].idx_v)
            joint = model.parents[joint]
    return solve_standing(
        model, _seed(spec, model), ("left_foot", "right_foot"),
        weight=lambda i: 1e-2 if i < 3 else 1.0, active=lambda i: i < 3 or i in legs,
    )


def _body_names(model: pin.Model) -> dict[int, str]:
    names: dict[int, str] = {}
    for frame in model.frames:
        if frame.type == pin.FrameType.BODY and frame.parentJoint not in names:
            names[frame.parentJoint] = frame.name
    return names


def _visual_geoms(
    spec: _Spec, model: pin.Model, body_names: dict[int, str]
) -> dict[str, list[Geom]]:
    geoms: dict[str, list[Geom]] = {}
    gmodel = pin.buildGeomFromUrdf(
        model,
        str(erd_robots_dir() / spec.urdf),
        pin.GeometryType.VISUAL,
        package_dirs=[str(erd_share_dir())],
    )
    for obj in gmodel.geometryObjects:
        path = obj.meshPath
        if not path or not path.lower().endswith(".stl") or not Path(path).is_file():
            continue  # MuJoCo loads STL (and OBJ/MSH) only; other meshes are dropped
        geoms.setdefault(body_names[obj.parentJoint], []).append(
            Geom(
                "mesh",
                tuple(float(s) for s in obj.meshScale),
                pos=tuple(float(x) for x in obj.placement.translation),  # type: ignore[arg-type]
                rotation=np.array(obj.placement.rotation),
                mesh=str(Path(path).resolve()),
            )
        )
    return geoms


def generate(spec: _Spec, model: pin.Model, q_standing: np.ndarray) -> tuple[str, str]:
    """(URDF text, MJCF text) of an example-robot-data robot (see the module docstring).

    Both come from one :class:`~hqp.robots.description.Description` of pinocchio's
    model of the source URDF (with the uniform frames as sites). The URDF has no
    meshes (PlaCo and pinocchio need none), the uniform frames as links on fixed
    joints, and the sole boxes as collision geometry.
    """
    body_names = _body_names(model)
    geoms = _visual_geoms(spec, model, body_names)
    sites: dict[str, tuple[str, pin.SE3]] = {}
    for name in [*spec.frames, "pelvis"]:
        frame = model.frames[model.getFrameId(name)]
        sites[name] = (body_names[frame.parentJoint], frame.placement)
    half_x, half_y = spec.sole_half
    for side in ("left", "right"):
        body, placement = sites[f"{side}_foot"]
        centre = placement.act(np.array([0.0, 0.0, 0.5 * SOLE_THICKNESS]))
        geoms.setdefault(body, []).append(
            Geom("box", (half_x, half_y, 0.5 * SOLE_THICKNESS),
                 pos=tuple(float(x) for x in centre),  # type: ignore[arg-type]
                 rotation=np.array(placement.rotation), contact=True, name=f"{side}_sole",
                 rgba=(0.2, 0.2, 0.2, 1.0))
        )
    description = from_pinocchio(
        model, name=spec.name, sites=sites, geoms=geoms, body_names=body_names,
        root_height=float(q_standing[2]), contact=CONTACT,
    )
    description.keyframes["standing"] = np.concatenate(
        [q_standing[:3], q_standing[6:7], q_standing[3:6], q_standing[7:]]
    )
    bodies = {b.name for b in description.bodies}
    for body in description.bodies:
        body.sites = [
            Site(s.name, s.pos, s.rotation, in_urdf=s.name not in bodies) for s in body.sites
        ]
    return to_urdf(description), to_mjcf(description)


def capsules(spec: _Spec, model: pin.Model) -> tuple[BodyCapsule, ...]:
    """Capsule proxies of the limbs: one per link between consecutive joints, plus hands and feet.

    Each leg and arm link gets a capsule from its joint to its child joint (links of zero
    length are skipped), the last link of each chain a capsule to the hand frame, and each
    foot a capsule along its sole (heel to toe, resting on the sole). Radius:
    ``spec.limb_radius`` (hands: 0.8 of it; feet: a third of the sole width).
    """
    body_names = _body_names(model)
    r = spec.limb_radius
    ends = {model.frames[model.getFrameId(f)].parentJoint: f for f in ("left_hand", "right_hand")}
    chains: set[int] = set()
    for frame in ("left_foot", "right_foot", "left_hand", "right_hand"):
        joint = model.frames[model.getFrameId(frame)].parentJoint
        while joint > 1:
            chains.add(joint)
            joint = model.parents[joint]
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
    half_x, half_y = spec.sole_half
    radius = half_y / 1.5
    for side in ("left", "right"):
        frame = model.frames[model.getFrameId(f"{side}_foot")]
        a = frame.placement.act(np.array([-half_x + radius, 0.0, radius]))
        b = frame.placement.act(np.array([half_x - radius, 0.0, radius]))
        out.append(BodyCapsule(f"{side}_foot", body_names[frame.parentJoint],
                               (float(a[0]), float(a[1]), float(a[2])),
                               (float(b[0]), float(b[1]), float(b[2])), radius))
    return tuple(out)


def cache_dir() -> Path:
    """Directory of generated files: ``$HQP_CACHE_DIR`` or ``<tempdir>/hqp-<version>``."""
    env = os.environ.get("HQP_CACHE_DIR")
    root = Path(env) if env else Path(tempfile.gettempdir()) / f"hqp-{hqp.__version__}"
    return root / "robots"


def robot(name: str) -> Robot:
    """Return the example-robot-data robot ``name`` (``"g1"`` or ``"talos"``).

    Raises:
        UnknownName: Not one of those names.
        HQPError: example-robot-data is not installed.

    """
    if name not in SPECS:
        raise UnknownName("robot", name, SPECS)
    spec = SPECS[name]
    source = erd_robots_dir() / spec.urdf
    extra = _extra_frames(spec)
    model = build_pinocchio_model(source, extra)
    if not model.existFrame("pelvis"):
        raise HQPError(f"{name}: no pelvis frame")
    q = _standing(spec, model)
    data = model.createData()
    pin.framesForwardKinematics(model, data, q)

    digest = hashlib.sha256()
    # the generated files name the meshes by absolute path: the installation is part of the key
    # (two environments with the same URDF share the temporary directory, not their meshes)
    digest.update(str(source.resolve()).encode())
    for part in (source, Path(__file__), Path(desc_mod.__file__)):
        digest.update(part.read_bytes())
    digest.update(np.round(q, 9).tobytes())
    stem = cache_dir() / f"{name}-{digest.hexdigest()[:16]}"
    mjcf_path, urdf_path = stem.with_suffix(".xml"), stem.with_suffix(".urdf")
    if not (mjcf_path.exists() and urdf_path.exists()):
        urdf_text, mjcf_text = generate(spec, model, q)
        write_if_changed(urdf_path, urdf_text)
        write_if_changed(mjcf_path, mjcf_text)
    generated = build_pinocchio_model(urdf_path)
    if list(generated.names) != list(model.names):
        raise HQPError(f"{name}: generated URDF {urdf_path} has another joint order")

    half_x, half_y = spec.sole_half
    contacts = tuple(
        ContactSurface(f, f, ContactType.SURFACE, half_x, half_y, FRICTION)
        for f in ("left_foot", "right_foot")
    )
    q.setflags(write=False)
    return Robot(
        name=name,
        urdf_path=urdf_path,
        mjcf_path=mjcf_path,
        contacts=contacts,
        hands=("left_hand", "right_hand"),
        feet=("left_foot", "right_foot"),
        base_frame="pelvis",
        head_frame=spec.head,
        q_standing=q,
        standing_height=float(data.oMf[model.getFrameId("pelvis")].translation[2]),
        source_urdf_path=source,
        capsules=capsules(spec, model),
        package_dirs=(str(erd_share_dir()),),
    )
