"""Distance constraints: obstacle avoidance and self-collision between capsules.

Robot links are approximated by capsules (:class:`CapsuleProxy`: a segment
fixed in a robot frame, swept by a sphere); obstacles are the spheres and
capsules of a :class:`~hqp.model.world.World`. The distance between two capsules
is the distance between their core segments minus both radii, computed in
closed form (closest points ``p1 = a1 + s u1``, ``p2 = a2 + t u2``), so its
Jacobian is smooth wherever the closest points are unique:

    d = ||p1 - p2|| - r1 - r2,     n = (p1 - p2) / ||p1 - p2||,
    d_dot = J_d v = n^T (J_p1 - J_p2) v,

with ``J_p`` the Jacobian of the body-fixed point at ``p`` (the closest
points move along the segments, but ``n`` is normal to a segment wherever the
parameter is interior, so this term drops out). The drift of ``d_ddot = J_d
qdd + drift`` keeps every second-order term:

    drift = n^T (a_p1 - a_p2) + 2 s_dot n^T u1_dot - 2 t_dot n^T u2_dot
            + (||r_dot||^2 - (n^T r_dot)^2) / ||p1 - p2||,

with ``a_p`` the acceleration of the body-fixed points at ``qdd = 0``,
``r_dot`` the velocity of ``p1 - p2`` and ``s_dot``, ``t_dot`` the rates of
the closest-point parameters (zero when clamped to an end of its segment).
Obstacles move with constant linear velocity (no rotation).

The rows are the velocity damper of Faverjon and Tournassoud (used in the
HQP literature, e.g. Kanoun et al. 2011), stated at the acceleration level:

    d_dot >= -xi (d - d_safe) / (d_influence - d_safe)     when d < d_influence,

required of the velocity after one period of gain ``kv`` (``kv = 1 / dt`` by
default: ``d_dot + dt d_ddot``), that is

    J_d qdd >= kv (-xi (d - d_safe) / (d_influence - d_safe) - d_dot) - drift.

At ``d = d_safe`` the distance may no longer decrease; below it, the rows push
the bodies apart. One row per pair, with a ``-inf`` bound when
``d >= d_influence``, so the row count does not depend on the state.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from hqp.errors import InvalidGain, InvalidInput, check_array
from hqp.model.geometry import cross3
from hqp.model.world import Box, Capsule, Sphere, World
from hqp.tasks.base import Category, Rows, Task

if TYPE_CHECKING:
    from hqp.model import RobotModel
    from hqp.model.layout import Layout

_EPS = 1e-12


@dataclass(frozen=True)
class CapsuleProxy:
    """A capsule fixed in a robot frame.

    Attributes:
        name: Proxy name (used in row names and reports).
        frame: Robot frame carrying the capsule.
        point_a: First end of the core segment in the frame ``(3,)`` [m].
        point_b: Second end of the core segment in the frame ``(3,)`` [m].
        radius: Radius [m] (>= 0).

    """

    name: str
    frame: str
    point_a: np.ndarray
    point_b: np.ndarray
    radius: float

    def __post_init__(self) -> None:
        where = f"CapsuleProxy {self.name!r}"
        object.__setattr__(self, "point_a", check_array(self.point_a, (3,), f"{where}: point_a"))
        object.__setattr__(self, "point_b", check_array(self.point_b, (3,), f"{where}: point_b"))
        r = float(self.radius)
        if not np.isfinite(r) or r < 0.0:
            raise InvalidGain(f"{where}: radius must be finite and >= 0, got {self.radius}")
        object.__setattr__(self, "radius", r)

    @classmethod
    def of(cls, capsule: object) -> CapsuleProxy:
        """Convert a capsule record (``name, frame, a, b, radius``, e.g. a robot's capsules).

        A :class:`CapsuleProxy` is returned unchanged.

        Raises:
            InvalidInput: The record lacks one of those attributes.

        """
        if isinstance(capsule, CapsuleProxy):
            return capsule
        try:
            fields = [getattr(capsule, k) for k in ("name", "frame", "a", "b", "radius")]
        except AttributeError as exc:
            raise InvalidInput(f"CapsuleProxy: not a capsule record: {exc}") from None
        return cls(*fields)


@dataclass(frozen=True)
class _Segment:
    """A moving segment: ends, Jacobians and accelerations of its body-fixed points."""

    a: np.ndarray
    u: np.ndarray
    u_dot: np.ndarray
    radius: float
    origin: np.ndarray | None  # frame origin (None: world obstacle)
    J6: np.ndarray | None  # LWA frame Jacobian (6, nv)
    v6: np.ndarray  # LWA frame velocity (6,) or [velocity, 0]
    a6: np.ndarray  # LWA classical drift (6,) or zeros

    def point(self, s: float) -> np.ndarray:
        return self.a + s * self.u

    def jacobian(self, p: np.ndarray, nv: int) -> np.ndarray:
        if self.J6 is None or self.origin is None:
            return np.zeros((3, nv))
        r = p - self.origin
        return self.J6[:3] - _skew(r) @ self.J6[3:]

    def velocity(self, p: np.ndarray) -> np.ndarray:
        if self.origin is None:
            return self.v6[:3]
        w = self.v6[3:]
        return self.v6[:3] + cross3(w, p - self.origin)

    def drift(self, p: np.ndarray) -> np.ndarray:
        if self.origin is None:
            return np.zeros(3)
        r = p - self.origin
        w = self.v6[3:]
        return self.a6[:3] + cross3(self.a6[3:], r) + cross3(w, cross3(w, r))


def _skew(r: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -r[2], r[1]], [r[2], 0.0, -r[0]], [-r[1], r[0], 0.0]])


def closest_parameters(
    a1: np.ndarray, u1: np.ndarray, a2: np.ndarray, u2: np.ndarray
) -> tuple[float, float]:
    """Parameters ``(s, t)`` in ``[0, 1]`` of the closest points of two segments.

    Segments ``a1 + s u1`` and ``a2 + t u2`` (a zero ``u`` is a point). For
    parallel segments, ``s = 0`` is chosen.
    """
    r = a1 - a2
    a = float(u1 @ u1)
    e = float(u2 @ u2)
    f = float(u2 @ r)
    if a <= _EPS and e <= _EPS:
        return 0.0, 0.0
    if a <= _EPS:
        return 0.0, float(np.clip(f / e, 0.0, 1.0))
    c = float(u1 @ r)
    if e <= _EPS:
        return float(np.clip(-c / a, 0.0, 1.0)), 0.0
    b = float(u1 @ u2)
    denom = a * e - b * b
    s = float(np.clip((b * f - c * e) / denom, 0.0, 1.0)) if denom > 1e-12 * a * e else 0.0
    t = (b * s + f) / e
    if t < 0.0:
        t = 0.0
        s = float(np.clip(-c / a, 0.0, 1.0))
    elif t > 1.0:
        t = 1.0
        s = float(np.clip((b - c) / a, 0.0, 1.0))
    return s, float(t)


@dataclass(frozen=True)
class Distance:
    """Distance between two capsules and its time derivatives.

    Attributes:
        d: Distance between the surfaces [m] (negative when penetrating).
        jacobian: ``J_d`` ``(nv,)``: ``d_dot = J_d v``.
        d_dot: Rate of the distance [m/s] (includes obstacle velocities).
        drift: ``d_ddot`` at ``qdd = 0`` [m/s^2].
        p1: Closest point on the first core segment ``(3,)`` [m].
        p2: Closest point on the second core segment ``(3,)`` [m].

    """

    d: float
    jacobian: np.ndarray
    d_dot: float
    drift: float
    p1: np.ndarray
    p2: np.ndarray


def _distance(s1: _Segment, s2: _Segment, nv: int) -> Distance:
    s, t = closest_parameters(s1.a, s1.u, s2.a, s2.u)
    p1, p2 = s1.point(s), s2.point(t)
    r = p1 - p2
    dist = float(np.linalg.norm(r))
    n = r / dist if dist > 1e-9 else np.array([0.0, 0.0, 1.0])
    J = n @ (s1.jacobian(p1, nv) - s2.jacobian(p2, nv))
    w = s1.velocity(p1) - s2.velocity(p2)
    # Rates of the interior closest-point parameters (derivative of r.u1 = 0, r.u2 = 0).
    free1 = 0.0 < s < 1.0 and s1.u @ s1.u > _EPS
    free2 = 0.0 < t < 1.0 and s2.u @ s2.u > _EPS
    uu1, uu2, u12 = s1.u @ s1.u, s2.u @ s2.u, s1.u @ s2.u
    g1 = -(w @ s1.u + r @ s1.u_dot)
    g2 = -(w @ s2.u + r @ s2.u_dot)
    s_dot = t_dot = 0.0
    if free1 and free2:
        K = np.array([[uu1, -u12], [u12, -uu2]])
        if abs(np.linalg.det(K)) > 1e-12 * uu1 * uu2:
            s_dot, t_dot = np.linalg.solve(K, np.array([g1, g2]))
    elif free1:
        s_dot = g1 / uu1
    elif free2:
        t_dot = -g2 / uu2
    r_dot = w + s_dot * s1.u - t_dot * s2.u
    n_rdot = float(n @ r_dot)
    drift = float(n @ (s1.drift(p1) - s2.drift(p2)))
    drift += 2.0 * s_dot * float(n @ s1.u_dot) - 2.0 * t_dot * float(n @ s2.u_dot)
    if dist > 1e-9:
        drift += (float(r_dot @ r_dot) - n_rdot**2) / dist
    return Distance(dist - s1.radius - s2.radius, J, n_rdot, drift, p1, p2)


def _robot_segment(model: RobotModel, proxy: CapsuleProxy, where: str) -> _Segment:
    model.frame_id(proxy.frame, where)
    T = model.frame_placement(proxy.frame)
    R, o = T.rotation, T.translation
    a = o + R @ proxy.point_a
    u = R @ (proxy.point_b - proxy.point_a)
    v6 = model.frame_velocity(proxy.frame)
    return _Segment(
        a=a,
        u=u,
        u_dot=cross3(v6[3:], u),
        radius=proxy.radius,
        origin=o.copy(),
        J6=model.frame_jacobian(proxy.frame),
        v6=v6.copy(),
        a6=model.frame_drift(proxy.frame).copy(),
    )


def _obstacle_segment(obstacle: Sphere | Capsule) -> _Segment:
    a, b = obstacle.segment
    return _Segment(
        a=a.copy(),
        u=b - a,
        u_dot=np.zeros(3),
        radius=obstacle.radius,
        origin=None,
        J6=None,
        v6=np.concatenate([obstacle.velocity, np.zeros(3)]),
        a6=np.zeros(6),
    )


class _DistanceTask(Task):
    """Shared parameters and rows of the distance constraints."""

    category = Category.COLLISION

    def __init__(
        self,
        name: str,
        d_safe: float,
        d_influence: float,
        xi: float,
        kv: float | None,
        weight: float,
    ) -> None:
        super().__init__(name, weight)
        w = self.where()
        if not (np.isfinite(d_safe) and d_safe >= 0.0):
            raise InvalidGain(f"{w}: d_safe must be finite and >= 0, got {d_safe}")
        if not (np.isfinite(d_influence) and d_influence > d_safe):
            raise InvalidGain(f"{w}: d_influence must be finite and > d_safe, got {d_influence}")
        if not (np.isfinite(xi) and xi > 0.0):
            raise InvalidGain(f"{w}: xi must be finite and > 0, got {xi}")
        if kv is not None and not (np.isfinite(kv) and kv > 0.0):
            raise InvalidGain(f"{w}: kv must be finite and > 0, got {kv}")
        self.d_safe = float(d_safe)
        self.d_influence = float(d_influence)
        self.xi = float(xi)
        self.kv = None if kv is None else float(kv)
        self._margins = np.zeros(0)
        self.pair_names: tuple[str, ...] = ()
        """Names ``"<a>|<b>"`` of the rows' pairs at the last :meth:`rows`."""

    def _pairs(self, model: RobotModel) -> list[tuple[str, _Segment, _Segment]]:
        raise NotImplementedError

    @staticmethod
    def pair_name(first: str, second: str) -> str:
        """Return the name ``"<first>|<second>"`` of a pair's row."""
        return f"{first}|{second}"

    def record_error(self, margins: np.ndarray, pair_names: Sequence[str]) -> None:
        """Record ``d - d_safe`` per pair of a step whose rows were computed elsewhere.

        The native step computes the rows in its kernel; this keeps :meth:`error` and
        :attr:`pair_names` those of the last step.
        """
        self._margins = np.array(margins, dtype=float)
        self.pair_names = tuple(pair_names)

    def distances(self, model: RobotModel) -> list[Distance]:
        """Distances of the pairs at ``model`` (order of the rows)."""
        return [_distance(s1, s2, model.nv) for _, s1, s2 in self._pairs(model)]

    def rows(self, model: RobotModel, layout: Layout, dt: float, t: float) -> Rows:
        """One inequality row per pair: ``J_d qdd >= kv (d_dot_min - d_dot) - drift``.

        Raises:
            InvalidFrame: A proxy frame is not in the model (names the primitive).
            InvalidGain: ``dt`` not positive when ``kv`` is ``None``.

        """
        pairs = self._pairs(model)
        if self.kv is None and not (np.isfinite(dt) and dt > 0.0):
            raise InvalidGain(f"{self.where()}: dt must be > 0, got {dt}")
        kv = 1.0 / dt if self.kv is None else self.kv
        m = len(pairs)
        C = np.zeros((m, layout.n))
        lower = np.full(m, -np.inf)
        margins = np.zeros(m)
        for i, (_, s1, s2) in enumerate(pairs):
            dist = _distance(s1, s2, model.nv)
            C[i, : model.nv] = dist.jacobian
            margins[i] = dist.d - self.d_safe
            if dist.d < self.d_influence:
                d_dot_min = -self.xi * (dist.d - self.d_safe) / (self.d_influence - self.d_safe)
                lower[i] = kv * (d_dot_min - dist.d_dot) - dist.drift
        self._margins = margins
        self.pair_names = tuple(name for name, _, _ in pairs)
        if m == 0:
            return Rows()
        return Rows(C=C, lower=lower, upper=np.full(m, np.inf))

    def error(self) -> np.ndarray:
        """``d - d_safe`` per pair at the last :meth:`rows` (negative: too close)."""
        return self._margins


class ObstacleAvoidance(_DistanceTask):
    """Keep robot capsules at least ``d_safe`` from world obstacles (COLLISION).

    One row per (proxy, obstacle) pair; see the module docstring for the rows.

    Args:
        name: Task name.
        world: World holding the obstacles (read at each step: moving obstacles).
        proxies: Robot capsules (:class:`CapsuleProxy` or records accepted by
            :meth:`CapsuleProxy.of`, e.g. ``robot.capsules``).
        obstacles: Names of the obstacles to avoid (default: every obstacle of
            the world at each step; spheres and capsules only).
        d_safe: Safety distance [m] (>= 0).
        d_influence: Distance below which the rows act [m] (> ``d_safe``).
        xi: Approach speed allowed at ``d_influence`` [m/s] (> 0).
        kv: Convergence rate of ``d_dot`` to the damper [1/s] (default ``1/dt``).
        weight: Weight within its level.

    Raises:
        InvalidGain: Bad distances or gains.
        InvalidInput: No proxies, or a named obstacle that is a box.
        UnknownName: A named obstacle that is not in the world.

    """

    def __init__(
        self,
        name: str,
        world: World,
        proxies: Sequence[CapsuleProxy],
        obstacles: Sequence[str] | None = None,
        *,
        d_safe: float = 0.05,
        d_influence: float = 0.2,
        xi: float = 0.3,
        kv: float | None = None,
        weight: float = 1.0,
    ) -> None:
        super().__init__(name, d_safe, d_influence, xi, kv, weight)
        if not proxies:
            raise InvalidInput(f"{self.where()}: no capsule proxies")
        self.world = world
        self.proxies = tuple(CapsuleProxy.of(p) for p in proxies)
        self.obstacles = None if obstacles is None else tuple(obstacles)
        for obstacle_name in self.obstacles or ():
            self._obstacle(obstacle_name)

    def _obstacle(self, name: str) -> Sphere | Capsule:
        obstacle = self.world.get(name)
        if isinstance(obstacle, Box):
            raise InvalidInput(
                f"{self.where()}: obstacle {name!r} is a box; "
                "distance rows use spheres and capsules"
            )
        return obstacle

    def selected_obstacles(self) -> list[Sphere | Capsule]:
        """Return the obstacles avoided now (the named ones, or every sphere and capsule).

        Raises:
            UnknownName: A named obstacle that is no longer in the world.
            InvalidInput: A named obstacle that is a box.

        """
        if self.obstacles is None:
            return [o for o in self.world if not isinstance(o, Box)]
        return [self._obstacle(n) for n in self.obstacles]

    def _pairs(self, model: RobotModel) -> list[tuple[str, _Segment, _Segment]]:
        selected = self.selected_obstacles()
        robot = [(p, _robot_segment(model, p, self.where())) for p in self.proxies]
        return [
            (self.pair_name(p.name, o.name), seg, _obstacle_segment(o))
            for p, seg in robot for o in selected
        ]


class SelfCollision(_DistanceTask):
    """Keep chosen pairs of robot capsules at least ``d_safe`` apart (COLLISION).

    Args:
        name: Task name.
        pairs: Pairs of robot capsules (:class:`CapsuleProxy` or records
            accepted by :meth:`CapsuleProxy.of`).
        d_safe: Safety distance [m] (>= 0).
        d_influence: Distance below which the rows act [m] (> ``d_safe``).
        xi: Approach speed allowed at ``d_influence`` [m/s] (> 0).
        kv: Convergence rate of ``d_dot`` to the damper [1/s] (default ``1/dt``).
        weight: Weight within its level.

    Raises:
        InvalidGain: Bad distances or gains.
        InvalidInput: No pairs, or a pair of two capsules on the same frame.

    """

    def __init__(
        self,
        name: str,
        pairs: Sequence[tuple[CapsuleProxy, CapsuleProxy]],
        *,
        d_safe: float = 0.02,
        d_influence: float = 0.1,
        xi: float = 0.3,
        kv: float | None = None,
        weight: float = 1.0,
    ) -> None:
        super().__init__(name, d_safe, d_influence, xi, kv, weight)
        if not pairs:
            raise InvalidInput(f"{self.where()}: no capsule pairs")
        pairs = [(CapsuleProxy.of(a), CapsuleProxy.of(b)) for a, b in pairs]
        for a, b in pairs:
            if a.frame == b.frame:
                raise InvalidInput(
                    f"{self.where()}: capsules {a.name!r} and {b.name!r} are on the same frame"
                )
        self.pairs = tuple(pairs)

    def _pairs(self, model: RobotModel) -> list[tuple[str, _Segment, _Segment]]:
        return [
            (
                self.pair_name(a.name, b.name),
                _robot_segment(model, a, self.where()),
                _robot_segment(model, b, self.where()),
            )
            for a, b in self.pairs
        ]
