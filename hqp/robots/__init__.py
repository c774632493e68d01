"""Robots: ``hqp.robots.load(name_or_file)``, ``hqp.robots.from_urdf(urdf, feet=, hands=)``.

``load`` takes a bundled name (``paper-humanoid``, ``g1``, ``talos``) or the path of a
robot TOML file (``urdf``, ``feet``, ``hands`` and options, see :mod:`hqp.robots.urdf`).
``g1`` and ``talos`` are such files (``hqp/robots/data/<name>.toml``), built by
:func:`from_urdf` like any user's humanoid; ``paper-humanoid`` is generated from its own
description (:mod:`hqp.robots.paper_humanoid`).

Every robot gives the same frame names for the common roles: ``left_foot``,
``right_foot`` (sole centres on the sole surface, z normal to the sole),
``left_hand``, ``right_hand``, ``trunk`` (the chest, after the torso joints),
``pelvis`` (the floating base) and ``head`` where the robot has one; the same
points are sites of the same names in the MuJoCo model.
"""

from __future__ import annotations

import functools
from pathlib import Path

from hqp.errors import UnknownName
from hqp.robots.robot import BodyCapsule, ContactSurface, Robot
from hqp.robots.urdf import OPTIONS, RobotDescriptionError, from_urdf, load_file

DATA_DIR = Path(__file__).resolve().parent / "data"
"""Folder of the bundled robot files."""

NAMES = ("paper-humanoid", "g1", "talos")
"""Bundled robot names accepted by :func:`load`."""


def is_robot_file(source: str | Path) -> bool:
    """Whether ``source`` names a robot TOML file rather than a bundled robot."""
    return str(source).endswith(".toml") or Path(source).is_file()


def check(source: str | Path) -> None:
    """Check that ``source`` can be loaded, cheaply: a bundled name or an existing file.

    Raises:
        UnknownName: Neither (lists the bundled names).
        RobotDescriptionError: A ``.toml`` path that does not exist.

    """
    if is_robot_file(source):
        if not Path(source).is_file():
            raise RobotDescriptionError(f"{source}: no such robot file")
        return
    if source not in NAMES:
        error = UnknownName("robot", str(source), NAMES)
        error.args = (f"{error.args[0]}, or a robot TOML file (path/to/robot.toml)",)
        raise error


def load(source: str | Path) -> Robot:
    """Return a bundled robot by name, or the robot of a robot TOML file.

    Robots are immutable records, cached per name (per file and modification time);
    :meth:`Robot.model` and :meth:`Robot.mujoco_model` return fresh models on every call.

    Raises:
        UnknownName: Neither a bundled name (lists them) nor a ``.toml`` file.
        RobotDescriptionError: The robot file is wrong (one line: the file and what is wrong).
        hqp.errors.InvalidFrame: The file names a frame the URDF does not have.

    """
    check(source)
    if is_robot_file(source):
        path = Path(source).resolve()
        return _load_file(str(path), path.stat().st_mtime_ns)
    return _load_name(str(source))


@functools.lru_cache(maxsize=None)
def _load_name(name: str) -> Robot:
    if name == "paper-humanoid":
        from hqp.robots import _paper

        return _paper.robot()
    return load_file(DATA_DIR / f"{name}.toml")


@functools.lru_cache(maxsize=None)
def _load_file(path: str, mtime_ns: int) -> Robot:
    del mtime_ns  # part of the cache key
    return load_file(path)


__all__ = ["NAMES", "OPTIONS", "BodyCapsule", "ContactSurface", "Robot",
           "RobotDescriptionError", "check", "from_urdf", "is_robot_file", "load"]
