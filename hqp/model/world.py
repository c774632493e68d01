"""A world description of obstacles, shared by collision primitives and MuJoCo scenes.

Obstacles are spheres, capsules (a segment swept by a sphere) and boxes, each
with a name, a pose and a size, in world coordinates [m]. Positions are
mutable (moving obstacles): :meth:`World.move` places an obstacle,
:meth:`World.step` advances every obstacle by its linear velocity. The
collision primitives (:mod:`hqp.tasks.collision`) read spheres and capsules
(analytic distances with smooth Jacobians); boxes are for scenes (tables,
walls) and are not used by the distance rows. :meth:`World.mjcf_geoms` writes
the obstacles as MJCF ``<geom>`` elements for a MuJoCo ``<worldbody>``;
:meth:`World.mjcf_bodies` writes them as mocap bodies (one per obstacle, named
like it) whose positions a simulator updates from :meth:`World.positions`.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass, field

import numpy as np

from hqp.errors import InvalidGain, InvalidInput, UnknownName, check_array
from hqp.tasks.base import edited


def _size(value: float, what: str, where: str) -> float:
    v = float(value)
    if not np.isfinite(v) or v < 0.0:
        raise InvalidGain(f"{where}: {what} must be finite and >= 0, got {value}")
    return v


def _fmt(values: Iterable[float]) -> str:
    return " ".join(f"{float(v):.6g}" for v in values)


@dataclass
class Sphere:
    """A sphere obstacle.

    Attributes:
        name: Unique name in its world.
        position: Centre ``(3,)`` [m].
        radius: Radius [m] (>= 0).
        velocity: Linear velocity ``(3,)`` [m/s] (moving obstacles; constant).
        rgba: Colour for scenes.

    """

    name: str
    position: np.ndarray
    radius: float
    velocity: np.ndarray = field(default_factory=lambda: np.zeros(3))
    rgba: tuple[float, float, float, float] = (0.8, 0.2, 0.2, 0.6)

    def __post_init__(self) -> None:
        where = f"Sphere {self.name!r}"
        self.position = check_array(self.position, (3,), f"{where}: position")
        self.velocity = check_array(self.velocity, (3,), f"{where}: velocity")
        self.radius = _size(self.radius, "radius", where)

    @property
    def segment(self) -> tuple[np.ndarray, np.ndarray]:
        """The core segment ``(a, b)`` (a point for a sphere), world [m]."""
        return self.position, self.position

    def translate(self, offset: np.ndarray) -> None:
        """Move by ``offset`` ``(3,)`` [m]."""
        self.position = self.position + offset

    def mjcf(self, collide: bool, origin: np.ndarray | None = None) -> str:
        """MJCF geom element (positions relative to ``origin``, default the world's)."""
        o = np.zeros(3) if origin is None else origin
        return (
            f'<geom name="{self.name}" type="sphere" pos="{_fmt(self.position - o)}" '
            f'size="{self.radius:.6g}" rgba="{_fmt(self.rgba)}"{_contact_attrs(collide)}/>'
        )


@dataclass
class Capsule:
    """A capsule obstacle: the points within ``radius`` of the segment ``[point_a, point_b]``.

    Attributes:
        name: Unique name in its world.
        point_a: First end of the core segment ``(3,)`` [m].
        point_b: Second end of the core segment ``(3,)`` [m].
        radius: Radius [m] (>= 0).
        velocity: Linear velocity ``(3,)`` [m/s] (translation only).
        rgba: Colour for scenes.

    """

    name: str
    point_a: np.ndarray
    point_b: np.ndarray
    radius: float
    velocity: np.ndarray = field(default_factory=lambda: np.zeros(3))
    rgba: tuple[float, float, float, float] = (0.8, 0.2, 0.2, 0.6)

    def __post_init__(self) -> None:
        where = f"Capsule {self.name!r}"
        self.point_a = check_array(self.point_a, (3,), f"{where}: point_a")
        self.point_b = check_array(self.point_b, (3,), f"{where}: point_b")
        self.velocity = check_array(self.velocity, (3,), f"{where}: velocity")
        self.radius = _size(self.radius, "radius", where)

    @property
    def position(self) -> np.ndarray:
        """Centre of the segment ``(3,)`` [m]."""
        return 0.5 * (self.point_a + self.point_b)

    @property
    def segment(self) -> tuple[np.ndarray, np.ndarray]:
        """The core segment ``(a, b)``, world [m]."""
        return self.point_a, self.point_b

    def translate(self, offset: np.ndarray) -> None:
        """Move by ``offset`` ``(3,)`` [m]."""
        self.point_a = self.point_a + offset
        self.point_b = self.point_b + offset

    def mjcf(self, collide: bool, origin: np.ndarray | None = None) -> str:
        """MJCF geom element (positions relative to ``origin``, default the world's)."""
        o = np.zeros(3) if origin is None else origin
        return (
            f'<geom name="{self.name}" type="capsule" '
            f'fromto="{_fmt(self.point_a - o)} {_fmt(self.point_b - o)}" size="{self.radius:.6g}" '
            f'rgba="{_fmt(self.rgba)}"{_contact_attrs(collide)}/>'
        )


@dataclass
class Box:
    """A box obstacle (scenes only; not read by the distance rows).

    Attributes:
        name: Unique name in its world.
        position: Centre ``(3,)`` [m].
        half_extents: Half sizes along the box axes ``(3,)`` [m] (>= 0).
        rotation: ``R_world_box`` ``(3, 3)``.
        velocity: Linear velocity ``(3,)`` [m/s].
        rgba: Colour for scenes.

    """

    name: str
    position: np.ndarray
    half_extents: np.ndarray
    rotation: np.ndarray = field(default_factory=lambda: np.eye(3))
    velocity: np.ndarray = field(default_factory=lambda: np.zeros(3))
    rgba: tuple[float, float, float, float] = (0.6, 0.6, 0.6, 1.0)

    def __post_init__(self) -> None:
        where = f"Box {self.name!r}"
        self.position = check_array(self.position, (3,), f"{where}: position")
        self.half_extents = check_array(self.half_extents, (3,), f"{where}: half_extents")
        if np.any(self.half_extents < 0):
            raise InvalidGain(f"{where}: half_extents must be >= 0, got {self.half_extents}")
        self.rotation = check_array(self.rotation, (3, 3), f"{where}: rotation")
        if not np.allclose(self.rotation.T @ self.rotation, np.eye(3), atol=1e-6):
            raise InvalidInput(f"{where}: rotation is not a rotation matrix")
        self.velocity = check_array(self.velocity, (3,), f"{where}: velocity")

    def translate(self, offset: np.ndarray) -> None:
        """Move by ``offset`` ``(3,)`` [m]."""
        self.position = self.position + offset

    def mjcf(self, collide: bool, origin: np.ndarray | None = None) -> str:
        """MJCF geom element (orientation as ``xyaxes``; position relative to ``origin``)."""
        R = self.rotation
        o = np.zeros(3) if origin is None else origin
        return (
            f'<geom name="{self.name}" type="box" pos="{_fmt(self.position - o)}" '
            f'size="{_fmt(self.half_extents)}" xyaxes="{_fmt(R[:, 0])} {_fmt(R[:, 1])}" '
            f'rgba="{_fmt(self.rgba)}"{_contact_attrs(collide)}/>'
        )


Obstacle = Sphere | Capsule | Box
"""Any obstacle of a :class:`World`."""


def _contact_attrs(collide: bool) -> str:
    return "" if collide else ' contype="0" conaffinity="0"'


class World:
    """Named obstacles, in insertion order.

    Args:
        obstacles: Initial obstacles (unique names).

    Raises:
        InvalidInput: Duplicate names.

    """

    def __init__(self, obstacles: Sequence[Obstacle] = ()) -> None:
        self._obstacles: dict[str, Obstacle] = {}
        for obstacle in obstacles:
            self.add(obstacle)

    def add(self, obstacle: Obstacle) -> None:
        """Add an obstacle.

        Raises:
            InvalidInput: Not an obstacle, or its name is taken.

        """
        if not isinstance(obstacle, (Sphere, Capsule, Box)):
            raise InvalidInput(f"World: not an obstacle: {obstacle!r}")
        if obstacle.name in self._obstacles:
            raise InvalidInput(f"World: duplicate obstacle name {obstacle.name!r}")
        self._obstacles[obstacle.name] = obstacle
        edited()  # the native step's distance kernels hold the obstacle pairs

    def remove(self, name: str) -> None:
        """Remove an obstacle by name.

        Raises:
            UnknownName: No obstacle of that name.

        """
        self.get(name)
        del self._obstacles[name]
        edited()

    def get(self, name: str) -> Obstacle:
        """Return the obstacle of that name.

        Raises:
            UnknownName: No obstacle of that name (lists the names).

        """
        try:
            return self._obstacles[name]
        except KeyError:
            raise UnknownName("obstacle", name, self._obstacles) from None

    @property
    def names(self) -> tuple[str, ...]:
        """Obstacle names in insertion order."""
        return tuple(self._obstacles)

    def __iter__(self) -> Iterator[Obstacle]:
        return iter(list(self._obstacles.values()))

    def __len__(self) -> int:
        return len(self._obstacles)

    def move(
        self, name: str, position: np.ndarray | None = None, velocity: np.ndarray | None = None
    ) -> None:
        """Place an obstacle (its centre at ``position``) and/or set its velocity.

        Raises:
            UnknownName: No obstacle of that name.
            InvalidInput: Position or velocity not a finite ``(3,)`` array.

        """
        obstacle = self.get(name)
        if position is not None:
            p = check_array(position, (3,), f"World: position of {name!r}")
            obstacle.translate(p - obstacle.position)
        if velocity is not None:
            obstacle.velocity = check_array(velocity, (3,), f"World: velocity of {name!r}")

    def step(self, dt: float) -> None:
        """Advance every obstacle by ``velocity * dt`` [s].

        Raises:
            InvalidInput: ``dt`` negative or not finite.

        """
        if not (np.isfinite(dt) and dt >= 0.0):
            raise InvalidInput(f"World: dt must be finite and >= 0, got {dt}")
        for obstacle in self._obstacles.values():
            obstacle.translate(obstacle.velocity * dt)

    def mjcf_geoms(self, collide: bool = False) -> list[str]:
        """MJCF ``<geom>`` strings of the obstacles, for a ``<worldbody>``.

        Args:
            collide: Whether MuJoCo collides with them (default: visual only,
                ``contype="0" conaffinity="0"``).

        """
        return [obstacle.mjcf(collide) for obstacle in self._obstacles.values()]

    def mjcf_bodies(self, collide: bool = False) -> list[str]:
        """MJCF mocap ``<body>`` strings (one per obstacle, named like it), for moving obstacles.

        Each body sits at the obstacle's centre and holds its geom; a simulator
        moves it by writing :meth:`positions` into ``MjData.mocap_pos``.

        Args:
            collide: Whether MuJoCo collides with them (default: visual only).

        """
        return [
            f'<body name="{o.name}" mocap="true" pos="{_fmt(o.position)}">'
            f"{o.mjcf(collide, origin=o.position)}</body>"
            for o in self._obstacles.values()
        ]

    def positions(self) -> dict[str, np.ndarray]:
        """Centre ``(3,)`` [m] of every obstacle by name (for mocap bodies)."""
        return {name: o.position.copy() for name, o in self._obstacles.items()}
