"""Metrics of a scenario run, computed from its recorded trace.

The definitions are those of the command-line contract (docs/reference/contracts.md,
the JSON sections):

- ``cog_error_max_mm``: the largest horizontal distance of the centre of
  gravity from its goal over the run [mm];
- ``cog_error_final_mm``: the mean of that distance over the last 0.5 s [mm];
- ``hand_final_distance_cm``: the distance of the right hand to its target at
  the end of the run [cm];
- ``joint_limit_violation_max_rad``: the largest excursion of an actuated
  joint past a position limit of the controller's model over the run
  (0 when none) [rad];
- ``step_time_median_ms``: the median wall-clock time of a control step [ms];
- ``fell``: the pelvis went below 0.6 x its standing height, or anything but
  a foot touched the floor;
- ``realtime_factor``: simulated seconds per wall-clock second of the closed
  loop, MuJoCo and logging included;
- ``contacts``: ``"unilateral"`` (MuJoCo's contacts, the default) or
  ``"welded"`` (the papers' rigid feet).

Per-axis centre-of-gravity errors (``cog_error_x_*``, ``cog_error_y_*``) and
the number of clipped torque entries (``torque_clipping_count``) and of
control steps where the controller's solve failed and it sent its safe
command (``safe_mode_steps``) are added, and with the commanded torques the
largest per-step torque change (``max_torque_jump_nm``, ``max_torque_jump_t``)
and the actuator held nearest its limit over the last 0.5 s
(``torque_ratio_final_max``: the mean of ``|tau| / tau_max`` there, 1 when
held at saturation; ``torque_ratio_final_joint``).

From the support wrenches MuJoCo exerts on the feet (the floor contacts, or the
welds of ``"welded"`` mode), when the trace has them:

- ``cop_outside_sole_max_mm``: the largest distance of a foot's centre of
  pressure outside its sole rectangle over the run (0: always inside) [mm];
- ``cop_outside_sole_s``: the first time a foot's centre of pressure left its
  sole (by more than :data:`COP_TOLERANCE`), or its normal force was at most 1 %
  of the weight (``None``: never) [s];
- ``normal_force_min_n``: the smallest normal force on a foot (negative: the
  weld pulled the foot down, which no floor can do) [N];
- ``commanded_cop_outside_support_max_mm``: the largest distance outside the
  soles' convex hull of the centre of pressure of the contact wrenches the
  controller commanded (its own model's support; ``None`` when it reports
  none, as PlaCo) [mm];
- ``commanded_cop_outside_support_s``: the first time that commanded centre of
  pressure left the hull, or the commanded support pulled (``None``: never) [s].

With welded feet these say whether the motion could have been made on a floor
that only pushes: a centre of pressure outside the sole is a foot that would
have tipped.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from hqp.errors import InvalidInput, check_array

FINAL_WINDOW_S = 0.5
"""Length of the final window over which ``*_final_*`` errors are averaged [s]."""

FALL_HEIGHT_RATIO = 0.6
"""The robot fell when its pelvis goes below this fraction of its standing height."""

SUPPORT_SETTLE_S = 0.05
"""Support metrics start at this time [s] (the soft contacts engage during the first steps)."""

COP_TOLERANCE = 1e-3
"""A centre of pressure has left its sole (or the support) when it is more than this
outside [m] (MuJoCo's soft contacts and welds overshoot by fractions of a millimetre)."""


@dataclass
class Trace:
    """What a scenario records at every logged control step of one run.

    All quantities are computed with the controller's model from the
    simulated state (pinocchio convention), except ``floor_contacts``, read
    from MuJoCo (which bodies touch the floor).

    Attributes:
        t: Times ``(N,)`` [s].
        q: Actuated joint positions ``(N, na)`` [rad].
        q_lower: Lower position limits of the controller's model ``(na,)`` [rad].
        q_upper: Upper position limits of the controller's model ``(na,)`` [rad].
        joint_names: Names of the actuated joints ``(na,)``.
        com: Centre of gravity ``(N, 3)`` [m].
        com_goal: Horizontal goal of the centre of gravity ``(N, 2)`` [m].
        pelvis_z: Height of the floating base ``(N,)`` [m].
        standing_height: Height of the floating base when standing [m].
        hand: Position of the tracked hand ``(N, 3)`` [m] (``None``: no hand task).
        hand_goal: Its target ``(N, 3)`` [m] (``None``: no hand task).
        non_foot_floor_contact: Whether a body other than a foot touched the
            floor at each step ``(N,)``.
        torque_clipped: Number of torque entries clipped by the simulator at
            each step ``(N,)``.
        step_ms: Wall-clock time of each control step ``(N,)`` [ms].
        fell_at: Time of a fall the simulator detected after the last logged
            sample (the run stops there) [s] (``None``: none).
        safe_mode: Whether the controller sent its safe command (its solve failed)
            at each step ``(N,)``.
        realtime_factor: Simulated seconds per wall-clock second of the closed loop,
            MuJoCo included (``None``: not measured).
        contacts: How the feet touched the floor: ``"unilateral"`` (MuJoCo's contacts) or
            ``"welded"`` (the papers' rigid feet).
        foot_wrench: Wrench of the world on each foot ``(N, nfeet, 6)`` (force, torque about
            the foot site) [N, N m] (``None``: not recorded).
        sole_cop: Centre of pressure of each foot in its sole frame ``(N, nfeet, 2)`` [m]
            (``nan`` where the normal force is at most 1 % of the weight).
        sole_half: Half length and half width of each sole ``(nfeet, 2)`` [m].
        commanded_margin: Signed distance of the commanded support's centre of pressure
            inside the soles' hull ``(N,)`` [m] (``nan``: pulling; ``None``: not reported).
        tau: Commanded joint torques ``(N, na)`` [N m] (``None``: not recorded); the largest
            change between consecutive steps is the JSON's ``max_torque_jump_nm``.
        tau_max: The torque limits the run's motors had ``(na,)`` [N m] (``None``: not
            recorded); with ``tau``, the JSON's ``torque_ratio_final_max``.
        extra: Further named series ``(N, ...)`` for plots (e.g. obstacle distance).

    """

    t: np.ndarray
    q: np.ndarray
    q_lower: np.ndarray
    q_upper: np.ndarray
    joint_names: tuple[str, ...]
    com: np.ndarray
    com_goal: np.ndarray
    pelvis_z: np.ndarray
    standing_height: float
    hand: np.ndarray | None = None
    hand_goal: np.ndarray | None = None
    non_foot_floor_contact: np.ndarray | None = None
    torque_clipped: np.ndarray | None = None
    step_ms: np.ndarray | None = None
    safe_mode: np.ndarray | None = None
    fell_at: float | None = None
    realtime_factor: float | None = None
    contacts: str = "unilateral"
    foot_wrench: np.ndarray | None = None
    sole_cop: np.ndarray | None = None
    sole_half: np.ndarray | None = None
    commanded_margin: np.ndarray | None = None
    tau: np.ndarray | None = None
    tau_max: np.ndarray | None = None
    extra: dict[str, np.ndarray] = field(default_factory=dict)

    def __post_init__(self) -> None:
        """Convert and check shapes (raises :class:`InvalidInput`)."""
        self.t = check_array(self.t, (None,), "Trace: t")
        n = self.t.shape[0]
        if n == 0:
            raise InvalidInput("Trace: no samples")
        na = len(self.joint_names)
        self.q = check_array(self.q, (n, na), "Trace: q")
        self.q_lower = check_array(self.q_lower, (na,), "Trace: q_lower", allow_inf=True)
        self.q_upper = check_array(self.q_upper, (na,), "Trace: q_upper", allow_inf=True)
        self.com = check_array(self.com, (n, 3), "Trace: com")
        self.com_goal = check_array(self.com_goal, (n, 2), "Trace: com_goal")
        self.pelvis_z = check_array(self.pelvis_z, (n,), "Trace: pelvis_z")
        if self.hand is not None:
            self.hand = check_array(self.hand, (n, 3), "Trace: hand")
            self.hand_goal = check_array(self.hand_goal, (n, 3), "Trace: hand_goal")
        if self.non_foot_floor_contact is not None:
            self.non_foot_floor_contact = np.asarray(self.non_foot_floor_contact, dtype=bool)
            if self.non_foot_floor_contact.shape != (n,):
                raise InvalidInput("Trace: non_foot_floor_contact must have shape (N,)")
        if self.tau_max is not None:
            self.tau_max = check_array(self.tau_max, (na,), "Trace: tau_max", allow_inf=True)
        if self.torque_clipped is not None:
            self.torque_clipped = check_array(self.torque_clipped, (n,), "Trace: torque_clipped")
        if self.step_ms is not None:
            self.step_ms = check_array(self.step_ms, (None,), "Trace: step_ms")
        if self.foot_wrench is not None:
            self.foot_wrench = check_array(self.foot_wrench, (n, None, 6), "Trace: foot_wrench")
            nfeet = self.foot_wrench.shape[1]
            self.sole_cop = np.asarray(self.sole_cop, dtype=float)  # nan: no positive force
            if self.sole_cop.shape != (n, nfeet, 2):
                raise InvalidInput(f"Trace: sole_cop must have shape ({n}, {nfeet}, 2), "
                                   f"got {self.sole_cop.shape}")
            self.sole_half = check_array(self.sole_half, (nfeet, 2), "Trace: sole_half")

    @property
    def cog_error(self) -> np.ndarray:
        """Horizontal centre-of-gravity error ``com_xy - goal`` ``(N, 2)`` [m]."""
        return self.com[:, :2] - self.com_goal

    def joint(self, name: str) -> np.ndarray:
        """Position of one actuated joint over the run ``(N,)`` [rad].

        Raises:
            InvalidInput: Unknown joint (the message lists the joints).

        """
        if name not in self.joint_names:
            joints = ", ".join(self.joint_names)
            raise InvalidInput(f"Trace: unknown joint {name!r}; joints: {joints}")
        return self.q[:, self.joint_names.index(name)]


def final_window(t: np.ndarray, window: float = FINAL_WINDOW_S) -> np.ndarray:
    """Boolean mask of the samples in the last ``window`` seconds (at least one sample)."""
    mask = t >= t[-1] - window
    mask[-1] = True
    return mask


def joint_limit_violation(q: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> float:
    """Largest excursion past a position limit ``max(lower - q, q - upper, 0)`` [rad].

    Args:
        q: Joint positions ``(N, na)`` [rad].
        lower: Lower limits ``(na,)`` (``-inf`` allowed) [rad].
        upper: Upper limits ``(na,)`` (``+inf`` allowed) [rad].

    """
    below = np.where(np.isfinite(lower), lower - q, -np.inf)
    above = np.where(np.isfinite(upper), q - upper, -np.inf)
    return float(max(0.0, np.max(below), np.max(above)))


def fell(trace: Trace) -> bool:
    """Tell whether the pelvis fell below 0.6 x standing height or a non-foot body hit the floor."""
    low = bool(np.any(trace.pelvis_z < FALL_HEIGHT_RATIO * trace.standing_height))
    touched = bool(trace.non_foot_floor_contact is not None and trace.non_foot_floor_contact.any())
    return low or touched or trace.fell_at is not None


def support_metrics(trace: Trace) -> dict[str, float | None]:
    """Centre-of-pressure and normal-force metrics of the support wrenches (module docstring).

    Empty when the trace has no support wrenches.
    """
    if trace.foot_wrench is None or trace.sole_cop is None or trace.sole_half is None:
        return {}
    keep = trace.t >= SUPPORT_SETTLE_S
    if not keep.any():
        keep[:] = True
    t = trace.t[keep]
    cop = trace.sole_cop[keep]
    fz = trace.foot_wrench[keep][:, :, 2]
    outside = np.maximum(np.abs(cop) - trace.sole_half[None], 0.0)
    dist = np.linalg.norm(np.nan_to_num(outside, nan=0.0), axis=2)  # (N, nfeet)
    bad = (dist > COP_TOLERANCE).any(axis=1) | np.isnan(cop).any(axis=(1, 2))
    first = np.flatnonzero(bad)
    out: dict[str, float | None] = {
        "cop_outside_sole_max_mm": 1e3 * float(dist.max()),
        "cop_outside_sole_s": float(t[first[0]]) if first.size else None,
        "normal_force_min_n": float(fz.min()),
        "commanded_cop_outside_support_max_mm": None,
        "commanded_cop_outside_support_s": None,
    }
    if trace.commanded_margin is not None:
        m = np.asarray(trace.commanded_margin)[keep]
        outside = np.flatnonzero(~(m >= -COP_TOLERANCE))  # nan (pulling) counts as outside
        finite = m[np.isfinite(m)]
        out["commanded_cop_outside_support_max_mm"] = (
            1e3 * float(max(0.0, -finite.min())) if finite.size else None)
        out["commanded_cop_outside_support_s"] = float(t[outside[0]]) if outside.size else None
    return out


def saturation_metrics(trace: Trace, last: np.ndarray) -> dict[str, float | str | None]:
    """Whether an actuator is held at its limit at the end of the run.

    ``torque_ratio_final_max``: the largest, over the joints, of the mean of ``|tau| / tau_max``
    over the final window (1: held at saturation the whole window), and its joint
    ``torque_ratio_final_joint`` (``None`` without torques or limits).
    """
    out: dict[str, float | str | None] = {"torque_ratio_final_max": None,
                                          "torque_ratio_final_joint": None}
    if trace.tau is None or trace.tau_max is None:
        return out
    tau = np.abs(np.asarray(trace.tau, dtype=float)[last])
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(trace.tau_max > 0, tau / trace.tau_max, 0.0).mean(axis=0)
    j = int(np.argmax(ratio))
    out["torque_ratio_final_max"] = float(ratio[j])
    out["torque_ratio_final_joint"] = trace.joint_names[j]
    return out


def run_metrics(trace: Trace) -> dict[str, float | int | bool | None]:
    """Return the metrics of one run (module docstring), as JSON-ready Python scalars."""
    err = trace.cog_error
    dist = np.linalg.norm(err, axis=1)
    last = final_window(trace.t)
    out: dict[str, float | int | bool | None] = {
        "cog_error_max_mm": 1e3 * float(dist.max()),
        "cog_error_final_mm": 1e3 * float(dist[last].mean()),
        "cog_error_x_max_mm": 1e3 * float(np.abs(err[:, 0]).max()),
        "cog_error_y_max_mm": 1e3 * float(np.abs(err[:, 1]).max()),
        "cog_error_x_final_mm": 1e3 * float(err[last, 0].mean()),
        "cog_error_y_final_mm": 1e3 * float(err[last, 1].mean()),
        "hand_final_distance_cm": None,
        "joint_limit_violation_max_rad": joint_limit_violation(
            trace.q, trace.q_lower, trace.q_upper
        ),
        "step_time_median_ms": (
            float(np.median(trace.step_ms))
            if trace.step_ms is not None and trace.step_ms.size
            else None
        ),
        "torque_clipping_count": (
            int(trace.torque_clipped.sum()) if trace.torque_clipped is not None else 0
        ),
        "safe_mode_steps": (
            int(np.count_nonzero(trace.safe_mode)) if trace.safe_mode is not None else 0
        ),
        "fell": fell(trace),
        "max_torque_jump_nm": None,
        "max_torque_jump_t": None,
        "realtime_factor": trace.realtime_factor,
        "contacts": trace.contacts,
    }
    if trace.tau is not None and len(trace.tau) > 1:
        jumps = np.abs(np.diff(trace.tau, axis=0)).max(axis=1)
        k = int(np.argmax(jumps))
        out["max_torque_jump_nm"] = float(jumps[k])
        out["max_torque_jump_t"] = float(trace.t[k + 1])
    out.update(saturation_metrics(trace, last))
    if trace.hand is not None and trace.hand_goal is not None:
        out["hand_final_distance_cm"] = 1e2 * float(
            np.linalg.norm(trace.hand[-1] - trace.hand_goal[-1])
        )
    out.update(support_metrics(trace))
    return out
