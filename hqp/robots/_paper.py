"""The :class:`~hqp.robots.robot.Robot` record of the paper humanoid (committed files)."""

from __future__ import annotations

import pinocchio as pin

from hqp.model.layout import ContactType
from hqp.robots import paper_humanoid as ph
from hqp.robots.robot import ContactSurface, Robot, build_pinocchio_model


def robot() -> Robot:
    """Return the paper humanoid, loaded from ``hqp/robots/data``."""
    model = build_pinocchio_model(ph.URDF_PATH)
    q = ph.standing_configuration(model)
    data = model.createData()
    pin.framesForwardKinematics(model, data, q)
    half_length = 0.5 * ph.FOOT_L * ph.HEIGHT
    half_width = 0.5 * ph.FOOT_W * ph.HEIGHT
    contacts = tuple(
        ContactSurface(f, f, ContactType.SURFACE, half_length, half_width, ph.FRICTION)
        for f in ("left_foot", "right_foot")
    )
    q.setflags(write=False)
    return Robot(
        name=ph.NAME,
        urdf_path=ph.URDF_PATH,
        mjcf_path=ph.MJCF_PATH,
        contacts=contacts,
        hands=("left_hand", "right_hand"),
        feet=("left_foot", "right_foot"),
        base_frame="pelvis",
        head_frame="head",
        q_standing=q,
        standing_height=float(data.oMf[model.getFrameId("pelvis")].translation[2]),
        capsules=ph.capsules(),
    )


__all__ = ["robot"]
