"""The hierarchy paper's humanoid (section 5): 24 DoF, 1.65 m, 71 kg.

Degrees of freedom: 2 x 6 legs (hip yaw, hip roll, hip pitch, knee, ankle
pitch, ankle roll), 2 torso (yaw, pitch), 2 x 4 arms (shoulder pitch, roll,
yaw, elbow), 2 head (yaw, pitch), on a floating pelvis.

Axes and signs (x forward, y left, z up; zero = upright, legs straight, arms
hanging): yaw joints turn about +z, roll joints about +x, pitch joints about
+y, the knee about -y. Hence hip and shoulder flexion are negative, torso and
head flexion (bending forward, looking down) positive, ankle dorsiflexion
negative, and -- the convention of the paper's Figures 4-5 -- knee flexion and
elbow flexion are negative angles. Roll: positive moves a limb to the left
(abduction of the left hip and shoulder, eversion of the left ankle).

Sources:

* Segment lengths, as fractions of the height H: D. A. Winter, *Biomechanics
  and Motor Control of Human Movement*, 4th ed., Wiley 2009, Fig. 4.1 (after
  Drillis and Contini 1966): ankle 0.039 H, knee 0.285 H, hip 0.530 H,
  shoulder 0.818 H, chin 0.870 H, eye 0.936 H; upper arm 0.186 H, forearm
  0.146 H, hand 0.108 H; shoulder width 0.259 H, hip width 0.191 H; foot
  length 0.152 H, foot width 0.055 H.
* Segment masses, centre-of-mass positions and principal radii of gyration
  (fractions of segment length): P. de Leva, "Adjustments to
  Zatsiorsky-Seluyanov's segment inertia parameters", J. Biomech. 29(9),
  1223-1230, 1996, Table 4 (males): trunk split into lower (OMPH-MIDH),
  middle and upper trunk; head VERT-CERV; hand WJC-DAC3; the trunk
  sub-segment lengths keep de Leva's ratios 145.7 : 215.5 : 170.7 mm.
* Joint ranges: American Academy of Orthopaedic Surgeons, *Joint Motion:
  Method of Measuring and Recording* (1965), average values as tabulated in
  C. C. Norkin and D. J. White, *Measurement of Joint Motion*, Appendix A:
  hip flexion 120, extension 30, abduction 45, adduction 30, rotation 45/45;
  ankle dorsiflexion 20, plantarflexion 50, inversion 35, eversion 15;
  thoracolumbar flexion 80, extension 25, rotation 45; cervical flexion 45,
  extension 45, rotation 60; shoulder flexion 180, extension 60, abduction
  180, medial rotation 70, lateral rotation 90 (degrees). Shoulder adduction
  is blocked by the trunk at 0; 30 degrees (in front of the trunk) is an
  assumption of this model. Knee and elbow flexion are limited at the values
  plotted in the hierarchy paper's Figures 4-5 (about -1.5 rad and -1.3 rad,
  "Knee Flexion Limit", "Elbow Limit"), tighter than AAOS's 135 and 150
  degrees, so that the hand-reach experiment meets its limits as the paper's
  does; :data:`ANATOMICAL_FLEXION` keeps the AAOS values.
* Torque and velocity limits: PAL Robotics' TALOS (O. Stasse et al., "TALOS:
  A new humanoid research platform targeted for industrial applications",
  IEEE-RAS Humanoids 2017), a 1.75 m humanoid, as given by the ``effort`` and
  ``velocity`` of ``talos_reduced.urdf`` in example-robot-data: legs
  ``leg_*_1..6``, torso ``torso_1..2``, arms ``arm_*_1..4`` (taken in chain
  order: shoulder pitch, roll, yaw, elbow), head ``head_2`` (yaw), ``head_1``
  (pitch). ``tests/test_robots.py`` checks them against that file.

Modelling assumptions: the hip joint centres lie a quarter of the hip
(bitrochanteric) width from the midline; the ankle is a quarter of the foot
length in front of the heel, so the sole centre is that far in front of the
ankle; the neck pivot lies halfway between shoulder and chin heights; each
massless-in-anatomy link between two joints at one point (hip yaw/roll,
ankle, torso yaw, shoulder pitch/roll, head yaw) holds a 0.2 kg joint
housing taken from its distal segment, so the total stays exactly 71 kg.

Run ``python -m hqp.robots.paper_humanoid`` to regenerate ``data/``; a test
checks that the committed files equal the generator's output.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import pinocchio as pin

from hqp.robots.description import (
    Body,
    ContactParameters,
    Description,
    Geom,
    Inertial,
    Joint,
    Site,
    to_mjcf,
    to_urdf,
    write_if_changed,
)
from hqp.robots.robot import ROOT_JOINT, BodyCapsule, solve_standing

NAME = "paper-humanoid"
DATA_DIR = Path(__file__).parent / "data"
URDF_PATH = DATA_DIR / "paper_humanoid.urdf"
MJCF_PATH = DATA_DIR / "paper_humanoid.xml"

HEIGHT = 1.65
"""Standing height H (sole to vertex, legs straight) [m] (paper, section 5)."""
MASS = 71.0
"""Total mass [kg] (paper, section 5)."""

DEG = np.pi / 180.0

# Winter (2009), Fig. 4.1: heights and lengths as fractions of H.
ANKLE_H, KNEE_H, HIP_H, SHOULDER_H, CHIN_H, EYE_H = 0.039, 0.285, 0.530, 0.818, 0.870, 0.936
UPPER_ARM_L, FOREARM_L, HAND_L = 0.186, 0.146, 0.108
SHOULDER_W, HIP_W, FOOT_L, FOOT_W = 0.259, 0.191, 0.152, 0.055

# de Leva (1996), Table 4, males: mass fraction, CoM from the proximal end (fraction of
# length), radii of gyration (sagittal = about x, transverse = about y, longitudinal).
DE_LEVA = {
    "head": (0.0694, 0.5002, (0.303, 0.315, 0.261)),  # VERT-CERV, CoM from vertex
    "upper_trunk": (0.1596, 0.2999, (0.716, 0.454, 0.659)),  # SUPR-XYPH
    "middle_trunk": (0.1633, 0.4502, (0.482, 0.383, 0.468)),  # XYPH-OMPH
    "lower_trunk": (0.1117, 0.6115, (0.615, 0.551, 0.587)),  # OMPH-MIDH
    "upper_arm": (0.0271, 0.5772, (0.285, 0.269, 0.158)),  # SJC-EJC
    "forearm": (0.0162, 0.4574, (0.276, 0.265, 0.121)),  # EJC-WJC
    "hand": (0.0061, 0.3624, (0.288, 0.235, 0.184)),  # WJC-DAC3
    "thigh": (0.1416, 0.4095, (0.329, 0.329, 0.149)),  # HJC-KJC
    "shank": (0.0433, 0.4395, (0.251, 0.246, 0.102)),  # KJC-AJC
    "foot": (0.0137, 0.4415, (0.257, 0.245, 0.124)),  # HEEL-TTIP (longitudinal = x)
}
TRUNK_RATIOS = (145.7, 215.5, 170.7)  # de Leva: lower, middle, upper trunk lengths [mm]

HOUSING_MASS = 0.2
"""Mass of each joint housing link [kg] (modelling assumption, see module docstring)."""
HOUSING_RADIUS = 0.04

# Controller's position limits [rad] (see sources above); left side, right mirrored for roll/yaw.
ANATOMICAL_FLEXION = {"knee": 135 * DEG, "elbow": 150 * DEG}
"""AAOS knee and elbow flexion ranges [rad] (the model uses the paper's tighter limits)."""
KNEE_FLEXION_LIMIT = 1.5
"""Knee flexion limit [rad] (paper, Figures 4-5)."""
ELBOW_FLEXION_LIMIT = 1.3
"""Elbow flexion limit [rad] (paper, Figures 4-5)."""

LIMITS_LEFT = {
    "hip_yaw": (-45 * DEG, 45 * DEG),
    "hip_roll": (-30 * DEG, 45 * DEG),
    "hip_pitch": (-120 * DEG, 30 * DEG),
    "knee": (-KNEE_FLEXION_LIMIT, 0.0),
    "ankle_pitch": (-20 * DEG, 50 * DEG),
    "ankle_roll": (-35 * DEG, 15 * DEG),
    "shoulder_pitch": (-180 * DEG, 60 * DEG),
    "shoulder_roll": (-30 * DEG, 180 * DEG),
    "shoulder_yaw": (-70 * DEG, 90 * DEG),
    "elbow": (-ELBOW_FLEXION_LIMIT, 0.0),
    "torso_yaw": (-45 * DEG, 45 * DEG),
    "torso_pitch": (-25 * DEG, 80 * DEG),
    "head_yaw": (-60 * DEG, 60 * DEG),
    "head_pitch": (-45 * DEG, 45 * DEG),
}
MIRRORED = {"hip_roll", "ankle_roll", "shoulder_roll", "shoulder_yaw", "hip_yaw"}

# TALOS (talos_reduced.urdf): (effort [N m], velocity [rad/s]) and the TALOS joint it comes from.
TALOS_LIMITS = {
    "hip_yaw": (100.0, 3.87, "leg_left_1_joint"),
    "hip_roll": (160.0, 5.8, "leg_left_2_joint"),
    "hip_pitch": (160.0, 5.8, "leg_left_3_joint"),
    "knee": (300.0, 7.0, "leg_left_4_joint"),
    "ankle_pitch": (160.0, 5.8, "leg_left_5_joint"),
    "ankle_roll": (100.0, 4.8, "leg_left_6_joint"),
    "torso_yaw": (78.0, 5.4, "torso_1_joint"),
    "torso_pitch": (78.0, 5.4, "torso_2_joint"),
    "shoulder_pitch": (44.64, 2.7, "arm_left_1_joint"),
    "shoulder_roll": (22.32, 3.66, "arm_left_2_joint"),
    "shoulder_yaw": (17.86, 4.58, "arm_left_3_joint"),
    "elbow": (17.86, 4.58, "arm_left_4_joint"),
    "head_yaw": (4.0, 1.0, "head_2_joint"),
    "head_pitch": (8.0, 1.0, "head_1_joint"),
}

SOLE_THICKNESS = 0.01
"""Thickness of the MuJoCo sole box [m] (its bottom face is the sole surface)."""
FRICTION = 1.0
"""Sole/floor friction coefficient (MuJoCo's default sliding friction)."""
CONTACT = ContactParameters(solref=(0.01, 1.0), solimp=(0.99, 0.999, 0.001, 0.5, 2.0),
                            friction=FRICTION)
"""Sole/floor contact parameters (tuned so a standing robot sinks < 1 mm, see tests)."""


def _segment(key: str, length: float, mass: float | None = None) -> tuple[float, float, np.ndarray]:
    """(mass [kg], CoM distance from the proximal end [m], principal inertia (3,)) of a segment."""
    fraction, com, radii = DE_LEVA[key]
    m = fraction * MASS if mass is None else mass
    inertia = m * (np.asarray(radii) * length) ** 2
    return m, com * length, inertia


def _housing() -> Inertial:
    i = 0.4 * HOUSING_MASS * HOUSING_RADIUS**2
    return Inertial(HOUSING_MASS, np.zeros(3), np.diag([i, i, i]))


def _limit(side: str, joint: str) -> tuple[float, float]:
    lo, hi = LIMITS_LEFT[joint]
    if side == "right" and joint in MIRRORED:
        lo, hi = -hi, -lo
    return lo, hi


def _joint(side: str, key: str, axis: tuple[float, float, float]) -> Joint:
    lo, hi = _limit(side, key) if side else LIMITS_LEFT[key]
    effort, velocity, _ = TALOS_LIMITS[key]
    name = f"{side}_{key}" if side else key
    return Joint(name, axis, lo, hi, effort, velocity)


def _combine(parts: list[tuple[float, np.ndarray, np.ndarray]]) -> Inertial:
    """Rigidly combine (mass, com (3,), inertia about own com (3, 3)) parts."""
    m = sum(p[0] for p in parts)
    c = sum(p[0] * p[1] for p in parts) / m
    inertia = np.zeros((3, 3))
    for mi, ci, Ii in parts:
        d = ci - c
        inertia += Ii + mi * (d @ d * np.eye(3) - np.outer(d, d))
    return Inertial(m, c, inertia)


X, Y, Z, NEG_Y = (1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0), (0.0, -1.0, 0.0)


def description(
    keyframes: dict[str, np.ndarray] | None = None, root_height: float = 1.0
) -> Description:
    """Describe the paper humanoid as a :class:`~hqp.robots.description.Description`.

    Args:
        keyframes: MuJoCo keyframes to include.
        root_height: Initial pelvis height of the MJCF [m].

    """
    H = HEIGHT
    l_trunk = (SHOULDER_H - HIP_H) * H  # SUPR-MIDH
    total = sum(TRUNK_RATIOS)
    l_lower, l_middle, l_upper = (r / total * l_trunk for r in TRUNK_RATIOS)
    l_thigh = (HIP_H - KNEE_H) * H
    l_shank = (KNEE_H - ANKLE_H) * H
    h_ankle = ANKLE_H * H
    l_foot, w_foot = FOOT_L * H, FOOT_W * H
    heel = -0.25 * l_foot  # heel x relative to the ankle (assumption)
    sole_x = heel + 0.5 * l_foot
    hip_y = 0.25 * HIP_W * H
    shoulder_y = 0.5 * SHOULDER_W * H
    z_neck = 0.5 * (SHOULDER_H + CHIN_H) * H
    l_head = H - z_neck
    l_upper_arm, l_forearm, l_hand = UPPER_ARM_L * H, FOREARM_L * H, HAND_L * H

    bodies: list[Body] = []

    # Pelvis = lower trunk (OMPH-MIDH); origin at the mid-hip point.
    m, c, inertia = _segment("lower_trunk", l_lower)
    pelvis = Body(
        "pelvis", None, (0.0, 0.0, 0.0), None, None,
        Inertial(m, np.array([0.0, 0.0, l_lower - c]), np.diag(inertia)),
        geoms=[Geom("box", (0.09, hip_y + 0.05, 0.6 * l_lower), pos=(0.0, 0.0, 0.4 * l_lower),
                    rgba=(0.4, 0.4, 0.5, 1.0))],
        sites=[Site("pelvis", (0.0, 0.0, 0.0), in_urdf=False)],
    )
    bodies.append(pelvis)

    for side, s in (("left", 1.0), ("right", -1.0)):
        p = side
        bodies.append(Body(f"{p}_hip_yaw_link", "pelvis", (0.0, s * hip_y, 0.0), None,
                           _joint(side, "hip_yaw", Z), _housing()))
        bodies.append(Body(f"{p}_hip_roll_link", f"{p}_hip_yaw_link", (0.0, 0.0, 0.0), None,
                           _joint(side, "hip_roll", X), _housing()))
        m, c, inertia = _segment("thigh", l_thigh, DE_LEVA["thigh"][0] * MASS - 2 * HOUSING_MASS)
        bodies.append(Body(
            f"{p}_thigh", f"{p}_hip_roll_link", (0.0, 0.0, 0.0), None, _joint(side, "hip_pitch", Y),
            Inertial(m, np.array([0.0, 0.0, -c]), np.diag(inertia)),
            geoms=[Geom("capsule", (0.06,), fromto=(0, 0, -0.05, 0, 0, -l_thigh + 0.05))],
        ))
        m, c, inertia = _segment("shank", l_shank)
        bodies.append(Body(
            f"{p}_shank", f"{p}_thigh", (0.0, 0.0, -l_thigh), None, _joint(side, "knee", NEG_Y),
            Inertial(m, np.array([0.0, 0.0, -c]), np.diag(inertia)),
            geoms=[Geom("capsule", (0.045,), fromto=(0, 0, -0.04, 0, 0, -l_shank + 0.04))],
        ))
        bodies.append(Body(f"{p}_ankle_link", f"{p}_shank", (0.0, 0.0, -l_shank), None,
                           _joint(side, "ankle_pitch", Y), _housing()))
        m, c, inertia = _segment("foot", l_foot, DE_LEVA["foot"][0] * MASS - HOUSING_MASS)
        # Foot principal axes: longitudinal along x, transverse along y, sagittal vertical.
        foot_inertia = np.diag([inertia[2], inertia[1], inertia[0]])
        bodies.append(Body(
            f"{p}_foot_link", f"{p}_ankle_link", (0.0, 0.0, 0.0), None,
            _joint(side, "ankle_roll", X),
            Inertial(m, np.array([heel + c, 0.0, -0.5 * h_ankle]), foot_inertia),
            geoms=[Geom("box", (0.5 * l_foot, 0.5 * w_foot, 0.5 * SOLE_THICKNESS),
                        pos=(sole_x, 0.0, -h_ankle + 0.5 * SOLE_THICKNESS), contact=True,
                        name=f"{p}_sole", rgba=(0.2, 0.2, 0.2, 1.0)),
                   Geom("box", (0.5 * l_foot, 0.5 * w_foot, 0.5 * (h_ankle - SOLE_THICKNESS)),
                        pos=(sole_x, 0.0, -0.5 * (h_ankle - SOLE_THICKNESS)))],
            sites=[Site(f"{p}_foot", (sole_x, 0.0, -h_ankle))],
        ))

    bodies.append(Body("torso_yaw_link", "pelvis", (0.0, 0.0, l_lower), None,
                       _joint("", "torso_yaw", Z), _housing()))
    m_mid, c_mid, i_mid = _segment("middle_trunk", l_middle)
    m_up, c_up, i_up = _segment("upper_trunk", l_upper)
    trunk_inertial = _combine([
        (m_mid - HOUSING_MASS, np.array([0.0, 0.0, l_middle - c_mid]),
         np.diag(i_mid) * (m_mid - HOUSING_MASS) / m_mid),
        (m_up, np.array([0.0, 0.0, l_middle + l_upper - c_up]), np.diag(i_up)),
    ])
    z_shoulder = l_middle + l_upper  # SUPR at shoulder height, relative to OMPH
    bodies.append(Body(
        "trunk", "torso_yaw_link", (0.0, 0.0, 0.0), None, _joint("", "torso_pitch", Y),
        trunk_inertial,
        geoms=[Geom("box", (0.1, shoulder_y - 0.05, 0.5 * z_shoulder),
                    pos=(0.0, 0.0, 0.5 * z_shoulder), rgba=(0.4, 0.4, 0.5, 1.0))],
        sites=[Site("trunk", (0.0, 0.0, 0.0), in_urdf=False)],
    ))
    bodies.append(Body("head_yaw_link", "trunk", (0.0, 0.0, z_neck - HIP_H * H - l_lower), None,
                       _joint("", "head_yaw", Z), _housing()))
    m, c, inertia = _segment("head", l_head, DE_LEVA["head"][0] * MASS - HOUSING_MASS)
    bodies.append(Body(
        "head_link", "head_yaw_link", (0.0, 0.0, 0.0), None, _joint("", "head_pitch", Y),
        Inertial(m, np.array([0.0, 0.0, l_head - c]), np.diag(inertia)),
        geoms=[Geom("sphere", (0.09,), pos=(0.0, 0.0, l_head - c), rgba=(0.9, 0.75, 0.6, 1.0))],
        sites=[Site("head", (0.0, 0.0, EYE_H * H - z_neck)), Site("head_top", (0.0, 0.0, l_head))],
    ))

    for side, s in (("left", 1.0), ("right", -1.0)):
        p = side
        bodies.append(Body(f"{p}_shoulder_pitch_link", "trunk", (0.0, s * shoulder_y, z_shoulder),
                           None, _joint(side, "shoulder_pitch", Y), _housing()))
        bodies.append(Body(f"{p}_shoulder_roll_link", f"{p}_shoulder_pitch_link", (0.0, 0.0, 0.0),
                           None, _joint(side, "shoulder_roll", X), _housing()))
        m, c, inertia = _segment("upper_arm", l_upper_arm,
                                 DE_LEVA["upper_arm"][0] * MASS - 2 * HOUSING_MASS)
        bodies.append(Body(
            f"{p}_upper_arm", f"{p}_shoulder_roll_link", (0.0, 0.0, 0.0), None,
            _joint(side, "shoulder_yaw", Z),
            Inertial(m, np.array([0.0, 0.0, -c]), np.diag(inertia)),
            geoms=[Geom("capsule", (0.04,), fromto=(0, 0, -0.03, 0, 0, -l_upper_arm + 0.03))],
        ))
        m_f, c_f, i_f = _segment("forearm", l_forearm)
        m_h, c_h, i_h = _segment("hand", l_hand)
        hand_point = np.array([0.0, 0.0, -l_forearm - c_h])
        bodies.append(Body(
            f"{p}_forearm", f"{p}_upper_arm", (0.0, 0.0, -l_upper_arm), None,
            _joint(side, "elbow", Y),
            _combine([(m_f, np.array([0.0, 0.0, -c_f]), np.diag(i_f)),
                      (m_h, hand_point, np.diag(i_h))]),
            geoms=[Geom("capsule", (0.035,), fromto=(0, 0, -0.03, 0, 0, -l_forearm)),
                   Geom("box", (0.02, 0.04, 0.5 * l_hand),
                        pos=(0.0, 0.0, -l_forearm - 0.5 * l_hand), rgba=(0.9, 0.75, 0.6, 1.0))],
            sites=[Site(f"{p}_hand", tuple(hand_point))],  # type: ignore[arg-type]
        ))

    return Description(
        name="paper_humanoid", bodies=bodies, root_height=root_height, contact=CONTACT,
        keyframes=dict(keyframes or {}),
    )


def seed_configuration(model: pin.Model) -> np.ndarray:
    """Rough standing pose: knees bent 0.3 rad, arms down, slightly abducted, elbows bent."""
    q = pin.neutral(model)
    q[2] = HIP_H * HEIGHT
    values = {
        "hip_pitch": -0.15, "knee": -0.30, "ankle_pitch": -0.15, "elbow": -0.2,
    }
    for side, s in (("left", 1.0), ("right", -1.0)):
        for key, val in values.items():
            q[model.joints[model.getJointId(f"{side}_{key}")].idx_q] = val
        q[model.joints[model.getJointId(f"{side}_shoulder_roll")].idx_q] = 0.1 * s
    return q


def standing_configuration(model: pin.Model) -> np.ndarray:
    """Standing configuration ``(nq,)``: soles flat at ``z = 0``, CoM above the sole centres."""
    legs = {f"{s}_{k}" for s in ("left", "right")
            for k in ("hip_yaw", "hip_roll", "hip_pitch", "knee", "ankle_pitch", "ankle_roll")}
    leg_dofs = {model.joints[model.getJointId(n)].idx_v for n in legs}

    # Base translation (cheap) and leg joints move; the base stays upright, the rest as seeded.
    return solve_standing(model, seed_configuration(model), ("left_foot", "right_foot"),
                          weight=lambda i: 1e-2 if i < 3 else 1.0,
                          active=lambda i: i < 3 or i in leg_dofs)


def capsules() -> tuple[BodyCapsule, ...]:
    """Capsule proxies for distance primitives, attached to body frames.

    The limbs' capsules are the MJCF's capsule geoms (thighs, shanks, upper arms,
    forearms); the pelvis, trunk, head, hands and feet get capsules that enclose
    their visual shapes (a sphere is a capsule with equal endpoints).
    """
    H = HEIGHT
    out = []
    for body in description().bodies:
        for k, geom in enumerate(g for g in body.geoms if g.kind == "capsule"):
            if geom.fromto is None:
                continue
            a = (float(geom.fromto[0]), float(geom.fromto[1]), float(geom.fromto[2]))
            b = (float(geom.fromto[3]), float(geom.fromto[4]), float(geom.fromto[5]))
            out.append(BodyCapsule(f"{body.name}_{k}", body.name, a, b, float(geom.size[0])))
    l_trunk = (SHOULDER_H - HIP_H) * H
    l_lower = TRUNK_RATIOS[0] / sum(TRUNK_RATIOS) * l_trunk
    z_shoulder = l_trunk - l_lower
    hip_y = 0.25 * HIP_W * H
    z_neck = 0.5 * (SHOULDER_H + CHIN_H) * H
    l_head = H - z_neck
    head_com = l_head * (1.0 - DE_LEVA["head"][1])
    l_forearm, l_hand = FOREARM_L * H, HAND_L * H
    l_foot, h_ankle = FOOT_L * H, ANKLE_H * H
    out.append(BodyCapsule("pelvis", "pelvis", (0.0, -hip_y, 0.06), (0.0, hip_y, 0.06), 0.11))
    out.append(BodyCapsule("trunk", "trunk", (0.0, 0.0, 0.1), (0.0, 0.0, z_shoulder - 0.1), 0.15))
    out.append(BodyCapsule("head", "head_link", (0.0, 0.0, head_com), (0.0, 0.0, head_com), 0.1))
    for side in ("left", "right"):
        out.append(BodyCapsule(f"{side}_hand", f"{side}_forearm",
                               (0.0, 0.0, -l_forearm - 0.02),
                               (0.0, 0.0, -l_forearm - l_hand + 0.04), 0.045))
        z = -h_ankle + 0.035
        out.append(BodyCapsule(f"{side}_foot", f"{side}_foot_link",
                               (-0.25 * l_foot + 0.035, 0.0, z),
                               (0.75 * l_foot - 0.035, 0.0, z), 0.035))
    return tuple(out)


def generate() -> tuple[str, str]:
    """(URDF text, MJCF text) of the paper humanoid, the MJCF with a ``standing`` keyframe."""
    urdf = to_urdf(description())
    model = pin.buildModelFromXML(urdf, pin.JointModelFreeFlyer(), ROOT_JOINT)
    q = standing_configuration(model)
    qpos = np.concatenate([q[:3], q[6:7], q[3:6], q[7:]])  # MuJoCo quaternion: w first
    # Rounded to 1e-10 so that solver round-off (1e-16) cannot change the committed file.
    qpos = np.round(qpos, 10) + 0.0
    mjcf = to_mjcf(description({"standing": qpos}, root_height=float(qpos[2])))
    return urdf, mjcf


def main(argv: list[str] | None = None) -> None:
    """Regenerate ``hqp/robots/data/paper_humanoid.{urdf,xml}``."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=DATA_DIR, help="output directory")
    args = parser.parse_args(argv)
    urdf, mjcf = generate()
    write_if_changed(args.out / URDF_PATH.name, urdf)
    write_if_changed(args.out / MJCF_PATH.name, mjcf)


if __name__ == "__main__":
    main()
