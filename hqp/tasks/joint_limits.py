"""Viable joint position and velocity limits as acceleration bounds.

Following Del Prete, "Joint position and velocity bounds in discrete-time
acceleration/torque control of robot manipulators", IEEE RA-L 2018: with the
control period ``dt`` and the acceleration ``a`` held over the period,

    q+ = q + dt v + dt^2 a / 2,        v+ = v + dt a,

each actuated joint gets ``lb <= a <= ub`` with ``ub`` the smallest of

* the one-step position bound ``q+ <= q_max``, valid both for the exact step
  above and for the semi-implicit Euler step of a simulator
  (``q+ = q + dt v+``, MuJoCo): ``(1 / dt^2) r`` when ``r = q_max - q - dt v``
  is positive (the Euler step moves further), ``(2 / dt^2) r`` when it is
  negative (the exact step brakes less);
* the viability bound: after the step, braking at the deceleration ``A``
  (``braking``, by default ``qdd_max``) must stop the joint before ``q_max``, i.e.
  ``(v+)^2 <= 2 A (q_max - q+)``, a quadratic in ``a``:

      dt^2 a^2 + dt (2 v + A dt) a + v^2 + 2 A (q + dt v - q_max) <= 0,

  whose larger root is the bound (at a state that is not viable, where the
  discriminant is negative or the root asks for more than ``A``, the bound
  brakes: ``-min(A_r, max(A, v^2 / (2 d)))`` with ``d = q_max - q``, the
  deceleration that still stops at the limit when the robot has it, within
  the reserve ``A_r = min(A_max, reserve A)``); with ``approach_time`` ``T_a > 0``
  the bound is also at most ``(v_b - v) / T_a - A v / v_b`` with the braking curve
  ``v_b = sqrt(2 A (q_max - q))``: the discrete bound lets a joint accelerate at
  ``A_max`` until it reaches the curve and then asks ``-A`` in one step (an acceleration
  step of ``A_max + A``, i.e. a torque step, measured 35 rad/s^2 on paper-humanoid's
  shoulder in a conflicting centre-of-mass shift); the approach term makes the bound
  fall continuously over about ``T_a`` as the joint nears the curve, brakes at ``A`` on
  it, and never exceeds the discrete bound, so viability is unchanged;
* the velocity bound ``(v_max - v) / T_v`` with ``T_v = max(dt, velocity_time)``
  (``v+ <= v_max``; with ``T_v = dt`` the joint reaches ``v_max`` in one step
  and its acceleration drops from ``A_max`` to 0 at once, a torque step; a
  longer ``T_v`` approaches ``v_max`` exponentially, continuously in ``v``);
* the acceleration bound ``A_max`` (``qdd_max``; optional:
  ``acceleration_bounds=False`` leaves the accelerations to the torque limits
  of a higher level, ``A_max`` then only bounding the braking);

and ``lb`` the mirror image. Braking at ``-A`` from a viable state keeps the
state viable (the braking distance ``v^2 / (2 A)`` is exact for piecewise
constant accelerations), so ``-A <= ub`` at every viable state: the bounds
never ask for more deceleration than ``A``. If the bounds cross at a state
that is not viable (e.g. ``|v| > v_max`` after a disturbance), both are set to
the braking acceleration ``-A_r sign(v)``.

``A`` must be a deceleration the robot can always produce for the joint,
*with the rest of the stack in force*. Pass it as ``qdd_max`` (scalar or per
joint, constant: the viability argument of the paper assumes constant bounds),
e.g. computed once at a nominal configuration with
:func:`max_acceleration_from_torques`. Without ``qdd_max``, that estimate is
recomputed at every state (state-dependent ``A``: viability then holds only
approximately).

The braking assumption and the acceleration bound may differ: ``braking``
(per joint) sets the ``A`` of the viability bound, ``qdd_max`` the bound
``A_max`` on ``|qdd|``. On a standing robot this matters: a joint whose
braking moves the body about its supports (an ankle: the whole robot about
the sole) can only be braked as fast as the contacts allow (about 1 rad/s^2
where the centre of pressure must stay in the sole), while bounding its
acceleration that low would lock the joint that balance needs. With
``braking = A`` small and ``qdd_max`` large, the joint moves freely far from
its limits, approaches them no faster than ``sqrt(2 A d)`` (``d`` the
distance left), and then needs no more than ``A`` to stop. ``reserve``
bounds what the bounds ask beyond ``A`` when a state is not viable (a
disturbance, an impact, a realised deceleration short of the commanded one):
at most ``A_r = min(A_max, reserve A)``, e.g. ``reserve = 2`` when ``A`` is
half of what the robot can do; a measured velocity spike at an impact then
does not turn into a full-strength braking demand on a joint that can only be
braked through the contacts.

``recovery`` ``A_rec`` (per joint, larger than ``A_r``) is for the other
extreme: a light joint thrown far past its braking curve. A level in conflict
above the joint limits (the servo's torque-rate level, when the contact limits
leave no torque change within its band) pins the torques at its least-squares
optimum for a step, whatever the joint-limit level asks; on g1 that gave the
right wrist roll (4e-4 kg m^2) 0.8 N m, 20 rad/s in one step, and braking at
``A_r <= A_max = 50`` rad/s^2 let it pass its limit by 0.31 rad. With
``A_rec``, where the bounds cross (a state that is not viable, or beyond
``v_max``), the joint brakes at what its bound asks (the deceleration that
stops it at the limit, or returns it under ``v_max``), up to ``A_rec``,
instead of at ``A_r``; viable states are unaffected.
:func:`hqp.control.presets.viable_joint_limits` gives it to the joints that
move their side of the robot alone (arms, wrists, head, a trunk yaw), at what
their torque limit gives that side beyond its weight's largest torque (and no
more than the fixed-base estimate, where the other joints take the reaction):
34117 rad/s^2 for g1's wrist roll, 0 for the legs, whose braking goes through
the soles and keeps the reserve.

A state past a position limit (after a disturbance, or a conflict with a
higher level) is driven back: the bound toward the violated limit becomes
``(v_r - v) / T_v`` with the return velocity ``v_r = -min(v_max, sqrt(2 A e))``
(``e`` the excursion) and the time constant ``T_v`` of the velocity bound,
clipped to ``[-A_r, A_r]`` (the one-step bound would ask for ``2 e / dt^2``,
and the plain viability bound brakes away from the range when the joint is at
rest outside it). With ``T_v = dt`` the return is dead-beat: a joint held on
its limit by a higher level, whose realised acceleration differs from the
commanded one, then sees its bound switch between ``-A_r`` and ``A_r`` from
step to step (a torque chatter); a longer ``T_v`` makes it continuous in
``v``.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin

from hqp.errors import InvalidGain, check_array
from hqp.tasks.base import Category, Rows, Task

if TYPE_CHECKING:
    from hqp.model import RobotModel
    from hqp.model.layout import Layout


def max_acceleration_from_torques(
    model: RobotModel, margin: float = 0.5, supports: Sequence[str] | None = None,
    *, worst_weight: bool = False,
) -> np.ndarray:
    """Estimate, per actuated joint, an acceleration the torque limits can produce at ``model``.

    Two models of "joint ``i`` alone accelerating by ``A_i``":

    * Without ``supports`` (a fixed base, or a floating base with its base
      held): the other accelerations are zero, so the actuated torques are
      ``tau = M_{a,i} A_i + h_a``, and ``A_i`` is the largest value with
      ``|tau_j| <= tau_max_j`` for every actuated ``j``:
      ``A_i = margin * min_j (tau_max_j - |h_j|)_+ / |M_ji|``.
    * With ``supports`` (frames held by the environment, e.g. the soles of a
      standing humanoid): joint ``i`` moves the side of the robot that holds
      no support (the rest of the body about an ankle, the arm about a
      shoulder), so ``A_i = margin * (tau_max_i - |g_side|)_+ / I_side``,
      with ``I_side`` the inertia of the moving side about the joint axis
      [kg m^2] and ``g_side`` the torque of its weight about the axis [N m].
      When both sides hold a support (a hip in double support), the smaller
      of the two values is kept.

    Both ignore several joints braking at once and velocity-dependent forces,
    hence the ``margin``. Compute it once at a nominal configuration and pass
    it as ``JointLimits(qdd_max=...)``.

    Args:
        model: Updated robot model (``M``, ``h``, placements, ``tau_max``).
        margin: Fraction of the estimate kept, in ``(0, 1]``.
        supports: Names of the frames held by the environment (``None``: the
            fixed-base model above).
        worst_weight: With ``supports``: take for ``g_side`` the largest torque of the
            side's weight as the joint turns about its axis, ``m |r_perp| |g_perp|``,
            rather than its torque at ``model`` (a bound that holds in any pose of that
            joint, e.g. the trunk bent forward).

    Returns:
        ``A`` ``(na,)`` [rad/s^2 or m/s^2] (``inf`` for unbounded torques).

    Raises:
        InvalidGain: ``margin`` outside ``(0, 1]``.
        InvalidFrame: A support frame that is not in the model.

    """
    if not (0.0 < margin <= 1.0):
        raise InvalidGain(f"max_acceleration_from_torques: margin must be in (0, 1], got {margin}")
    if supports is not None:
        return margin * _support_acceleration(model, supports, worst_weight)
    act = model.actuated
    Maa = np.abs(model.M[act, act])
    room = np.maximum(model.tau_max - np.abs(model.h[act]), 0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(Maa > 1e-12, room[:, None] / Maa, np.inf)
    return margin * ratio.min(axis=0)


def _support_acceleration(model: RobotModel, supports: Sequence[str],
                          worst_weight: bool = False) -> np.ndarray:
    """``(tau_max_i - |g_side|)_+ / I_side`` of the moving side of each joint (see above).

    ``worst_weight``: ``g_side`` the largest torque of the side's weight as the joint turns
    (``m |r_perp| |g_perp|``: the side's centre of mass at ``r_perp`` from the axis, gravity's
    component normal to it), not the torque at ``model``'s configuration.
    """
    pin_model, data = model.model, model.data
    held = {
        pin_model.frames[model.frame_id(f, "max_acceleration_from_torques")].parentJoint
        for f in supports
    }
    first = pin_model.njoints - model.na
    bodies = [data.oMi[k].act(pin_model.inertias[k]) for k in range(pin_model.njoints)]
    total = pin.Inertia.Zero()
    for Y in bodies[1:]:
        total += Y
    hold = pin.Motion(-model.gravity_vector, np.zeros(3))  # acceleration that holds the weight
    out = np.zeros(model.na)
    for i in range(model.na):
        j = first + i
        J = pin.getJointJacobian(pin_model, data, j, pin.ReferenceFrame.WORLD)
        S = J[:, pin_model.joints[j].idx_v]
        motion = pin.Motion(S)
        subtree = set(pin_model.subtrees[j])
        sub = pin.Inertia.Zero()
        for k in subtree:
            sub += bodies[k]
        sub_held = bool(held & subtree)
        rest_held = bool(held - subtree)
        sides = []
        if not sub_held or rest_held:
            sides.append(sub)  # the subtree moves (arm, swing leg; or both sides held)
        if sub_held:
            sides.append(total - sub)  # the rest of the body moves about the joint
        best = np.inf
        for Y in sides:
            inertia = float(S @ (Y * motion).vector)
            weight = abs(float(S @ (Y * hold).vector))
            if worst_weight:
                w = S[3:]
                n = float(np.linalg.norm(w))
                if n > 1e-12:  # revolute: the axis through w x v / |w|^2, direction w / |w|
                    w = w / n
                    r = Y.lever - np.cross(w, S[:3] / n)
                    r_perp = r - w * float(w @ r)
                    g = model.gravity_vector
                    g_perp = g - w * float(w @ g)
                    weight = Y.mass * float(np.linalg.norm(r_perp) * np.linalg.norm(g_perp))
            if inertia > 1e-12:
                best = min(best, max(model.tau_max[i] - weight, 0.0) / inertia)
        out[i] = best
    return out


def _upper_bounds(
    q: np.ndarray,
    v: np.ndarray,
    q_max: np.ndarray,
    v_max: np.ndarray,
    A: np.ndarray,
    B: np.ndarray,
    cap: np.ndarray,
    rec: np.ndarray,
    dt: float,
    clip: bool,
    v_time: float = 0.0,
    a_time: float = 0.0,
) -> np.ndarray:
    """Upper acceleration bounds toward ``q_max`` (one-step, viability, velocity, acceleration).

    ``A`` ``(k,)``: bound on ``|qdd|`` [rad/s^2] (applied when ``clip``); ``B`` ``(k,)``: the
    braking deceleration of the viability bound; ``cap`` ``(k,)``: the largest deceleration
    asked at a state that is not viable or past the limit (``B <= cap <= A``); ``v_time``:
    time constant of the velocity bound [s] (``dt`` when smaller); ``a_time``: time constant
    of the approach to the braking curve [s] (0: none, the discrete viability root alone);
    ``rec`` ``(k,)``: the recovery deceleration (``>= cap``; ``cap`` for none), the most a
    state that is not viable is asked to brake (module docstring).
    """
    # One-step bound valid for the exact step and for the semi-implicit Euler step of
    # simulators (MuJoCo: q+ = q + dt v+), see the module docstring.
    room = q_max - q - dt * v
    pos = np.minimum(2.0 * room, room) / dt**2
    vel = (v_max - v) / max(dt, v_time)
    via = np.full_like(q, np.inf)
    finite = np.isfinite(B) & np.isfinite(q_max)
    if np.any(finite):
        Bf, Cf, Rf = B[finite], cap[finite], rec[finite]
        qf, vf, qm = q[finite], v[finite], q_max[finite]
        b = dt * (2.0 * vf + Bf * dt)
        c = vf**2 + 2.0 * Bf * (qf + dt * vf - qm)
        disc = b**2 - 4.0 * dt**2 * c
        root = (-b + np.sqrt(np.maximum(disc, 0.0))) / (2.0 * dt**2)
        # Not viable for B: brake with what stops the joint at the limit, within [B, A].
        with np.errstate(divide="ignore", invalid="ignore"):
            needed = np.maximum(vf, 0.0) ** 2 / (2.0 * np.maximum(qm - qf, 1e-12))
        brake = -np.minimum(Rf, np.maximum(Bf, needed))
        # A root below -B is the one-step return to the braking curve of a state that is not
        # viable either: brake gracefully there too.
        if a_time > 0.0:
            root = np.minimum(root, _approach(qf, vf, qm, Bf, Cf, max(dt, a_time)))
        via[finite] = np.where(disc >= 0.0, np.maximum(root, brake), brake)
    bound = np.minimum.reduce([pos, vel, via, A] if clip else [pos, vel, via])
    # Past the limit: return at the speed of the braking curve (see the module docstring).
    out = finite & (q > q_max)
    if np.any(out):
        v_ret = -np.minimum(v_max[out], np.sqrt(2.0 * B[out] * (q[out] - q_max[out])))
        bound[out] = np.clip((v_ret - v[out]) / max(dt, v_time), -cap[out], cap[out])
    return bound


def _approach(q: np.ndarray, v: np.ndarray, q_max: np.ndarray, B: np.ndarray, cap: np.ndarray,
              T: float) -> np.ndarray:
    """Return the bound approaching the braking curve ``v_b = sqrt(2 B (q_max - q))`` over ``T``.

    ``(v_b - v) / T + dv_b/dt`` with ``dv_b/dt = -B v / v_b`` (toward the limit, at most
    ``cap``): on the curve it brakes at ``B``, below it the bound rises continuously with the
    distance to the curve, so a joint accelerating toward its limit is slowed down over ``T``
    instead of switching from ``A`` to ``-B`` in one step (module docstring).
    """
    v_b = np.sqrt(2.0 * B * np.maximum(q_max - q, 0.0))
    toward = np.maximum(v, 0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        ff = np.where(v_b > 0.0, B * toward / v_b, np.where(toward > 0.0, np.inf, 0.0))
    return (v_b - v) / T - np.minimum(cap, ff)


class SupportBraking:
    """Braking decelerations of the viability bound that follow the active contacts.

    A joint between the floating base and a held frame (an ankle, a knee of a leg standing on
    its sole) moves the rest of the body about that support when it brakes, which its torque
    limit does far more slowly than it moves the distal limb once the foot is in the air (the
    knee of paper-humanoid: about 6 rad/s^2 on the floor, 25 in the air). A constant braking
    assumption must take the support value, which then also caps the joint's velocity toward
    a limit in the air: a swing leg or a jumping robot cannot extend its knee faster than
    ``sqrt(2 A d)``. This table holds, for every subset of the contact frames, the braking
    ``min(base, support estimate)`` computed once at a nominal configuration (where the
    support estimate is zero, i.e. the joint's torque limit cannot hold the side it moves in
    the rigid model, ``base`` is kept, as :func:`hqp.controller.standing_stack` does); the
    stack tells :class:`JointLimits` which contacts are active at every step (released contacts
    do not hold, unloading ones still do). The viability argument of the bound assumes a
    constant ``A``; here ``A`` changes only when a contact is made or released, and a release
    only raises it.

    With ``per_contact=False`` there are two values only: all frames held (whenever any
    contact is active) and none (no contact: a robot in the air). A walking robot then keeps
    the double-support braking on its swing leg (see :func:`hqp.controller.standing_stack`).

    Args:
        model: Robot model; updated to ``q`` (then left there).
        frames: The contact frames that may hold the robot (at most 8).
        base: Braking without supports ``(na,)`` or scalar [rad/s^2] (> 0).
        margin: Fraction of the support estimate kept, in ``(0, 1]``.
        q: Nominal configuration ``(nq,)`` (``None``: the model's current one).
        per_contact: One value per subset of active frames (``True``), or all-or-none.

    Raises:
        InvalidGain: Non-positive ``base``, bad ``margin``, more than 8 frames.
        InvalidFrame: A frame that is not in the model.

    """

    def __init__(
        self,
        model: RobotModel,
        frames: Sequence[str],
        base: np.ndarray | float,
        *,
        margin: float = 0.5,
        q: np.ndarray | None = None,
        per_contact: bool = True,
    ) -> None:
        frames = tuple(frames)
        if not (0.0 < margin <= 1.0):
            raise InvalidGain(f"SupportBraking: margin must be in (0, 1], got {margin}")
        if len(frames) > 8:
            raise InvalidGain(f"SupportBraking: at most 8 contact frames, got {len(frames)}")
        base_arr = check_array(np.atleast_1d(base), (None,), "SupportBraking: base",
                               allow_inf=True)
        if np.any(base_arr <= 0) or base_arr.size not in (1, model.na):
            raise InvalidGain(f"SupportBraking: base must be > 0 with 1 or {model.na} entries")
        base_arr = np.broadcast_to(base_arr, (model.na,)).astype(float)
        if q is not None:
            model.update(q, np.zeros(model.nv))
        self.frames = frames
        self.per_contact = bool(per_contact)
        self.table: dict[frozenset[str], np.ndarray] = {}
        masks = range(1 << len(frames)) if per_contact else (0, (1 << len(frames)) - 1)
        for mask in masks:
            held = [f for k, f in enumerate(frames) if mask >> k & 1]
            if not held:
                self.table[frozenset()] = base_arr.copy()
                continue
            support = max_acceleration_from_torques(model, margin=margin, supports=held)
            self.table[frozenset(held)] = np.where(support > 0.0,
                                                   np.minimum(base_arr, support), base_arr)

    def __call__(self, active: Sequence[str]) -> np.ndarray:
        """Braking ``(na,)`` with the contact frames ``active`` holding (others ignored)."""
        held = frozenset(active).intersection(self.frames)
        if not self.per_contact and held:
            held = frozenset(self.frames)
        return self.table[held]


class JointLimits(Task):
    """Viable position, velocity and acceleration bounds on ``qdd`` (JOINT_LIMITS).

    Rows: ``lb <= qdd_a <= ub`` over the actuated joints (``na`` rows), see the
    module docstring for ``lb`` and ``ub``.

    Args:
        name: Task name.
        qdd_max: Maximum acceleration ``A_max`` per actuated joint ``(na,)`` or a
            scalar [rad/s^2] (> 0, ``inf`` allowed); ``None``: estimated at each
            state by :func:`max_acceleration_from_torques` with ``margin`` and
            ``supports``.
        braking: Deceleration ``A`` assumed by the viability bound, per actuated
            joint ``(na,)`` or a scalar [rad/s^2] (> 0, ``inf`` allowed); taken
            as ``min(braking, A_max)``. ``None``: ``A_max``. A :class:`SupportBraking`:
            the value for the contacts active at the step (the stack reports them).
        velocity_time: Time constant ``T_v`` of the velocity bound [s] (>= 0;
            ``dt`` when smaller), see the module docstring.
        approach_time: Time constant ``T_a`` of the approach to the braking curve [s]
            (>= 0; ``dt`` when smaller; 0: the discrete viability bound alone), see the
            module docstring.
        reserve: Factor (>= 1, ``inf`` allowed) on the braking deceleration: the
            bounds ask for at most ``min(A_max, reserve * A)`` at a state that is
            not viable or past a limit (module docstring).
        recovery: Deceleration ``A_rec`` per actuated joint ``(na,)`` or a scalar [rad/s^2]
            (>= 0, ``inf`` allowed) at which a joint moving faster than its bounds allow
            may be braked (module docstring): where larger than the reserve ``A_r``, a state
            that is not viable (or beyond ``v_max``) brakes at what its bound asks, up to
            ``A_rec``, instead of at ``A_r``. ``None`` or 0: ``A_r``. Viable states are
            unaffected.
        margin: Fraction used by the estimate (``qdd_max=None`` only).
        supports: Frames held by the environment, for the estimate
            (``qdd_max=None`` only).
        position_margin: Distance kept from the model's position limits [rad or m] (>= 0).
        velocity_scale: Fraction of the model's velocity limits used, in ``(0, 1]``.
        acceleration_bounds: Also bound ``|qdd_a| <= A`` (the paper's acceleration
            bounds). With ``False``, ``A`` only sets the braking assumption of the
            viability bound and the torque limits alone bound the accelerations
            (useful when ``A`` is a conservative estimate).
        inactive_beyond: Bounds larger in magnitude than this [rad/s^2] are
            returned as ``±inf`` (far from binding; keeps the QP data well
            scaled: the one-step position bound is of order ``1 / dt^2``).
        weight: Weight within its level.

    Raises:
        InvalidGain: Non-positive ``qdd_max``, negative margin, bad scale.

    """

    category = Category.JOINT_LIMITS
    contact_aware = True

    def __init__(
        self,
        name: str = "joint_limits",
        qdd_max: np.ndarray | float | None = None,
        *,
        braking: np.ndarray | float | SupportBraking | None = None,
        reserve: float = np.inf,
        recovery: np.ndarray | float | None = None,
        velocity_time: float = 0.0,
        approach_time: float = 0.0,
        margin: float = 0.5,
        supports: Sequence[str] | None = None,
        position_margin: float = 0.0,
        velocity_scale: float = 1.0,
        acceleration_bounds: bool = True,
        inactive_beyond: float = 1e4,
        weight: float = 1.0,
    ) -> None:
        super().__init__(name, weight)
        w = self.where()
        self.qdd_max: np.ndarray | None = None
        if qdd_max is not None:
            arr = check_array(np.atleast_1d(qdd_max), (None,), f"{w}: qdd_max", allow_inf=True)
            if np.any(arr <= 0):
                raise InvalidGain(f"{w}: qdd_max must be > 0, got {arr}")
            self.qdd_max = arr
        self.braking: np.ndarray | None = None
        self.support_braking: SupportBraking | None = None
        self._active_frames: tuple[str, ...] = ()
        self.airborne_braking = False
        if isinstance(braking, SupportBraking):
            self.support_braking = braking
        elif braking is not None:
            arr = check_array(np.atleast_1d(braking), (None,), f"{w}: braking", allow_inf=True)
            if np.any(arr <= 0):
                raise InvalidGain(f"{w}: braking must be > 0, got {arr}")
            self.braking = arr
        if np.isnan(reserve) or reserve < 1.0:
            raise InvalidGain(f"{w}: reserve must be >= 1, got {reserve}")
        self.reserve = float(reserve)
        self.recovery: np.ndarray | None = None
        if recovery is not None:
            arr = check_array(np.atleast_1d(recovery), (None,), f"{w}: recovery", allow_inf=True)
            if np.any(np.isnan(arr)) or np.any(arr < 0):
                raise InvalidGain(f"{w}: recovery must be >= 0, got {arr}")
            self.recovery = arr
        if not (np.isfinite(velocity_time) and velocity_time >= 0.0):
            raise InvalidGain(f"{w}: velocity_time must be finite and >= 0, got {velocity_time}")
        self.velocity_time = float(velocity_time)
        if not (np.isfinite(approach_time) and approach_time >= 0.0):
            raise InvalidGain(f"{w}: approach_time must be finite and >= 0, got {approach_time}")
        self.approach_time = float(approach_time)
        if not (0.0 < margin <= 1.0):
            raise InvalidGain(f"{w}: margin must be in (0, 1], got {margin}")
        if not (np.isfinite(position_margin) and position_margin >= 0.0):
            raise InvalidGain(f"{w}: position_margin must be finite, >= 0: {position_margin}")
        if not (0.0 < velocity_scale <= 1.0):
            raise InvalidGain(f"{w}: velocity_scale must be in (0, 1], got {velocity_scale}")
        self.margin = float(margin)
        self.supports = None if supports is None else tuple(supports)
        self.position_margin = float(position_margin)
        self.velocity_scale = float(velocity_scale)
        self.acceleration_bounds = bool(acceleration_bounds)
        if np.isnan(inactive_beyond) or inactive_beyond <= 0.0:
            raise InvalidGain(f"{w}: inactive_beyond must be > 0, got {inactive_beyond}")
        self.inactive_beyond = float(inactive_beyond)
        self._violation = np.zeros(0)

    def max_acceleration(self, model: RobotModel) -> np.ndarray:
        """Return the maximum deceleration ``A`` ``(na,)`` used at ``model``.

        Raises:
            InvalidGain: ``qdd_max`` of a size other than 1 or ``na``.

        """
        if self.qdd_max is None:
            return max_acceleration_from_torques(model, self.margin, self.supports)
        if self.qdd_max.size not in (1, model.na):
            raise InvalidGain(
                f"{self.where()}: qdd_max has {self.qdd_max.size} entries, "
                f"robot has {model.na} joints"
            )
        return np.broadcast_to(self.qdd_max, (model.na,)).astype(float)

    def braking_deceleration(self, model: RobotModel) -> np.ndarray:
        """Return the deceleration ``A`` ``(na,)`` of the viability bound at ``model``.

        Raises:
            InvalidGain: ``braking`` or ``qdd_max`` of a size other than 1 or ``na``.

        """
        A = self.max_acceleration(model)
        if self.support_braking is not None:
            braking = self.support_braking(() if self.airborne_braking else self._active_frames)
            if braking.size != model.na:
                raise InvalidGain(f"{self.where()}: braking has {braking.size} entries, "
                                  f"robot has {model.na} joints")
            return np.minimum(braking, A)
        if self.braking is None:
            return A
        if self.braking.size not in (1, model.na):
            raise InvalidGain(
                f"{self.where()}: braking has {self.braking.size} entries, "
                f"robot has {model.na} joints"
            )
        return np.minimum(np.broadcast_to(self.braking, (model.na,)), A)

    def recovery_deceleration(self, model: RobotModel) -> np.ndarray:
        """Return the recovery deceleration ``(na,)`` (0 where none: the reserve alone).

        Raises:
            InvalidGain: ``recovery`` of a size other than 1 or ``na``.

        """
        if self.recovery is None:
            return np.zeros(model.na)
        if self.recovery.size not in (1, model.na):
            raise InvalidGain(f"{self.where()}: recovery has {self.recovery.size} entries, "
                              f"robot has {model.na} joints")
        return np.broadcast_to(self.recovery, (model.na,)).astype(float)

    def set_active_contacts(self, frames: Sequence[str]) -> None:
        """Record the frames of the active contacts (called by the stack at every build).

        Assigned only when they change: an assignment is an edit (``hqp.tasks.base.Edits``).
        """
        frames = tuple(frames)
        if frames != self._active_frames:
            self._active_frames = frames

    def set_airborne_braking(self, airborne: bool) -> None:
        """Assume no support in the braking deceleration, whatever the active contacts.

        For a take-off (a jump's push): a leg extending toward its limit on a unilateral
        contact brakes by leaving the floor (the contact force falls to zero and the joint
        then moves the limb alone), not by pulling the body down. Only meaningful with a
        :class:`SupportBraking`; the behavior that asks for it must release the contacts
        before the joint needs the braking (else it stops against the contacts' rows).
        """
        self.airborne_braking = bool(airborne)

    def bounds(self, model: RobotModel, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """Acceleration bounds ``(lb, ub)``, each ``(na,)``, at ``model`` for the period ``dt``.

        Raises:
            InvalidGain: ``dt`` not positive.

        """
        if not (np.isfinite(dt) and dt > 0.0):
            raise InvalidGain(f"{self.where()}: dt must be > 0, got {dt}")
        q = model.q[model.actuated_q]
        v = model.v[model.actuated]
        q_lo = model.q_lower + self.position_margin
        q_hi = model.q_upper - self.position_margin
        v_max = self.velocity_scale * model.v_max
        A = self.max_acceleration(model)
        B = self.braking_deceleration(model)
        clip = self.acceleration_bounds
        cap = np.minimum(A, self.reserve * B)
        rec = np.maximum(cap, self.recovery_deceleration(model))
        T_v = self.velocity_time
        T_a = self.approach_time
        ub = _upper_bounds(q, v, q_hi, v_max, A, B, cap, rec, dt, clip, T_v, T_a)
        lb = -_upper_bounds(-q, -v, -q_lo, v_max, A, B, cap, rec, dt, clip, T_v, T_a)
        crossed = lb > ub
        if np.any(crossed):
            brake = np.where(v >= 0.0, -cap, cap)
            # With a recovery deceleration: the braking the crossed side asks, within it.
            brake = np.where(rec > cap, np.where(v >= 0.0, np.maximum(ub, -rec),
                                                 np.minimum(lb, rec)), brake)
            brake = np.where(np.isfinite(brake), brake, np.where(v >= 0.0, ub, lb))
            # Past a position limit, the return toward the range wins (module docstring).
            brake = np.where(q > q_hi, ub, np.where(q < q_lo, lb, brake))
            lb = np.where(crossed, brake, lb)
            ub = np.where(crossed, brake, ub)
        ub = np.where(ub > self.inactive_beyond, np.inf, ub)
        lb = np.where(lb < -self.inactive_beyond, -np.inf, lb)
        self.record_error(model)
        return lb, ub

    def rows(self, model: RobotModel, layout: Layout, dt: float, t: float) -> Rows:
        """Inequality rows ``(na, n)``: ``lb <= qdd_a <= ub``."""
        lb, ub = self.bounds(model, dt)
        C = np.zeros((model.na, layout.n))
        C[:, model.actuated] = np.eye(model.na)
        return Rows(C=C, lower=lb, upper=ub)

    def error(self) -> np.ndarray:
        """Excursion past the position limits ``(na,)`` at the last call (0 inside)."""
        self._fetch_error()
        return self._violation

    def record_error(self, model: RobotModel) -> None:
        """Set :meth:`error` at ``model``'s state (also after a native step, which has no rows)."""
        q = model.q[model.actuated_q]
        self._violation = np.maximum(q - model.q_upper, 0.0) + np.maximum(model.q_lower - q, 0.0)
