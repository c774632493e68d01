"""World of obstacles: moving obstacles, MJCF geoms loaded by MuJoCo, bad input."""

from __future__ import annotations

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from hqp import HQPError, InvalidGain, UnknownName
from hqp.model.world import Box, Capsule, Sphere, World


def scene() -> World:
    R = pin.rpy.rpyToMatrix(0.1, -0.2, 0.3)
    return World([
        Sphere("ball", [0.5, 0.1, 1.0], 0.1, velocity=[0.0, 0.2, 0.0]),
        Capsule("pole", [1.0, -0.5, 0.0], [1.0, -0.5, 1.5], 0.05),
        Box("table", [0.8, 0.0, 0.7], [0.4, 0.6, 0.02], rotation=R),
    ])


def test_mjcf_geoms_load_in_mujoco() -> None:
    world = scene()
    xml = "<mujoco><worldbody>" + "".join(world.mjcf_geoms()) + "</worldbody></mujoco>"
    model = mujoco.MjModel.from_xml_string(xml)
    assert model.ngeom == 3
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    ball = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "ball")
    np.testing.assert_allclose(data.geom_xpos[ball], [0.5, 0.1, 1.0], atol=1e-6)
    np.testing.assert_allclose(model.geom_size[ball][0], 0.1)
    pole = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "pole")
    np.testing.assert_allclose(data.geom_xpos[pole], [1.0, -0.5, 0.75], atol=1e-6)
    np.testing.assert_allclose(model.geom_size[pole][:2], [0.05, 0.75], atol=1e-6)
    table = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "table")
    np.testing.assert_allclose(data.geom_xmat[table].reshape(3, 3), world.get("table").rotation,
                               atol=1e-5)
    np.testing.assert_allclose(model.geom_size[table], [0.4, 0.6, 0.02], atol=1e-6)
    assert model.geom_contype[ball] == 0  # visual only by default
    collide = mujoco.MjModel.from_xml_string(
        "<mujoco><worldbody>" + "".join(world.mjcf_geoms(collide=True)) + "</worldbody></mujoco>"
    )
    assert collide.geom_contype[ball] == 1


def test_moving_obstacles() -> None:
    world = scene()
    world.step(0.5)
    np.testing.assert_allclose(world.get("ball").position, [0.5, 0.2, 1.0])
    world.move("pole", position=[0.0, 0.0, 1.0], velocity=[1.0, 0.0, 0.0])
    pole = world.get("pole")
    np.testing.assert_allclose(pole.point_a, [0.0, 0.0, 0.25])
    np.testing.assert_allclose(pole.point_b, [0.0, 0.0, 1.75])
    world.step(0.1)
    np.testing.assert_allclose(pole.position, [0.1, 0.0, 1.0])
    assert world.names == ("ball", "pole", "table")
    world.remove("table")
    assert len(world) == 2


def test_world_errors() -> None:
    world = scene()
    with pytest.raises(UnknownName, match="obstacle 'wall'; valid obstacles: ball, pole, table"):
        world.get("wall")
    with pytest.raises(HQPError, match="duplicate"):
        world.add(Sphere("ball", [0, 0, 0], 0.1))
    with pytest.raises(InvalidGain, match="Sphere 's': radius"):
        Sphere("s", [0, 0, 0], -0.1)
    with pytest.raises(HQPError, match="Capsule 'c': point_b"):
        Capsule("c", [0, 0, 0], [0, np.nan, 0], 0.1)
    with pytest.raises(HQPError, match="rotation"):
        Box("b", [0, 0, 0], [1, 1, 1], rotation=2 * np.eye(3))
    with pytest.raises(HQPError, match="position of 'ball'"):
        world.move("ball", position=[0, 0])
    with pytest.raises(HQPError, match="dt"):
        world.step(-1.0)


def test_mocap_bodies_follow_moving_obstacles() -> None:
    world = scene()
    xml = "<mujoco><worldbody>" + "".join(world.mjcf_bodies()) + "</worldbody></mujoco>"
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    world.step(1.0)
    for name, position in world.positions().items():
        data.mocap_pos[model.body(name).mocapid[0]] = position
    mujoco.mj_forward(model, data)
    ball = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "ball")
    pole = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "pole")
    table = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "table")
    np.testing.assert_allclose(data.geom_xpos[ball], [0.5, 0.3, 1.0], atol=1e-6)
    np.testing.assert_allclose(data.geom_xpos[pole], [1.0, -0.5, 0.75], atol=1e-6)
    np.testing.assert_allclose(data.geom_xpos[table], [0.8, 0.0, 0.7], atol=1e-6)
    np.testing.assert_allclose(data.geom_xmat[table].reshape(3, 3), world.get("table").rotation,
                               atol=1e-5)
