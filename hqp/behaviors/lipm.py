"""Centre-of-mass planning by ZMP preview control of the cart-table model (Kajita et al. 2003).

The linear inverted pendulum at constant height ``h`` (the cart-table model) relates the
horizontal centre of mass ``c`` to the zero-moment point ``p``::

    p = c - c_ddot / omega^2,        omega = sqrt(g / h)

Per horizontal axis, with the jerk ``u`` as input held over a period ``T``, the state
``x = (c, c_dot, c_ddot)`` follows exactly::

    x[k+1] = A x[k] + B u[k],   A = [[1, T, T^2/2], [0, 1, T], [0, 0, 1]],
                                B = [T^3/6, T^2/2, T]^T,
    p[k]   = C x[k],            C = [1, 0, -1/omega^2].

Preview control (Kajita et al., "Biped walking pattern generation by using preview control
of zero-moment point", ICRA 2003, after Katayama et al. 1985) minimises::

    J = sum_k  Q_e e[k]^2 + R du[k]^2,        e = p - p_ref,  du[k] = u[k] - u[k-1]

over the increments. The augmented state ``X = (e, dx)``, ``dx[k] = x[k] - x[k-1]``, obeys::

    X[k+1] = At X[k] + Bt du[k] + Et dp_ref[k+1],
    At = [[1, C A], [0, A]],  Bt = [C B; B],  Et = [-1; 0],

so with ``P`` the solution of the discrete algebraic Riccati equation of
``(At, Bt, diag(Q_e, 0, 0, 0), R)`` and ``H = (R + Bt^T P Bt)^-1``, the optimal increment is::

    du[k] = -K X[k] - sum_{j=1..N} f_j dp_ref[k+j],
    K = H Bt^T P At,   f_j = H Bt^T (At - Bt K)^T^(j-1) P Et,

a state feedback (``K``: the integral of the ZMP error and the state) and a preview of the
reference's next ``N`` changes. Between samples the jerk is constant, so the centre of mass
is a piecewise cubic: continuous in position, velocity and acceleration.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import solve_discrete_are

from hqp.errors import HQPError

GRAVITY = 9.81
"""Gravity [m/s^2] of the cart-table model (MuJoCo's default ``9.81``)."""


def lipm_omega(height: float) -> float:
    """Natural frequency ``omega = sqrt(g / h)`` [1/s] of the pendulum of height ``h`` [m].

    Raises:
        HQPError: A height that is not positive.

    """
    if not height > 0.0:
        raise HQPError(f"LIPM: the centre-of-mass height must be positive, got {height!r}")
    return float(np.sqrt(GRAVITY / height))


def cart_table(omega: float, dt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Return ``A (3, 3)``, ``B (3,)`` and ``C (3,)`` of the cart-table model (module docstring)."""
    A = np.array([[1.0, dt, 0.5 * dt * dt], [0.0, 1.0, dt], [0.0, 0.0, 1.0]])
    B = np.array([dt**3 / 6.0, 0.5 * dt * dt, dt])
    C = np.array([1.0, 0.0, -1.0 / omega**2])
    return A, B, C


@dataclass(frozen=True)
class PreviewGains:
    """Gains of the ZMP preview controller (module docstring).

    Attributes:
        K: State feedback on ``X = (e, dx)`` ``(4,)``.
        f: Preview gains ``f_1 .. f_N`` on the reference's changes ``(N,)``.
        A: Cart-table state matrix ``(3, 3)``.
        B: Cart-table input vector ``(3,)``.
        C: ZMP output vector ``(3,)``.
        dt: Sampling period [s].

    """

    K: np.ndarray
    f: np.ndarray
    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    dt: float


def preview_gains(omega: float, dt: float, horizon: int, *, q_e: float = 1.0,
                  r: float = 1e-6) -> PreviewGains:
    """Solve the Riccati equation of the augmented cart-table model for the preview gains.

    Args:
        omega: LIPM natural frequency [1/s].
        dt: Sampling period [s].
        horizon: Number ``N`` of previewed samples.
        q_e: Weight of the ZMP error [1/m^2].
        r: Weight of the jerk increment [s^6/m^2].

    Raises:
        HQPError: A non-positive period, weight or horizon.

    """
    if not (dt > 0.0 and q_e > 0.0 and r > 0.0 and horizon >= 1):
        raise HQPError(f"ZMP preview: expected dt, q_e, r > 0 and horizon >= 1, got dt={dt!r}, "
                       f"q_e={q_e!r}, r={r!r}, horizon={horizon!r}")
    A, B, C = cart_table(omega, dt)
    At = np.zeros((4, 4))
    At[0, 0] = 1.0
    At[0, 1:] = C @ A
    At[1:, 1:] = A
    Bt = np.concatenate(([C @ B], B))[:, None]
    Et = np.array([-1.0, 0.0, 0.0, 0.0])
    Q = np.diag([q_e, 0.0, 0.0, 0.0])
    P = solve_discrete_are(At, Bt, Q, np.array([[r]]))
    H = 1.0 / (r + float(Bt[:, 0] @ P @ Bt[:, 0]))
    K = H * (Bt[:, 0] @ P @ At)
    Ac_T = (At - Bt @ K[None, :]).T
    f = np.empty(horizon)
    g = P @ Et  # (Ac^T)^(j-1) P Et
    for j in range(horizon):
        f[j] = H * float(Bt[:, 0] @ g)
        g = Ac_T @ g
    return PreviewGains(K=K, f=f, A=A, B=B, C=C, dt=float(dt))


def preview_com(x0: np.ndarray, zmp_ref: np.ndarray, gains: PreviewGains) -> tuple[np.ndarray,
                                                                                   np.ndarray]:
    """Run the preview controller along a ZMP reference, from rest-consistent state ``x0``.

    Args:
        x0: Initial state ``(3, d)``: position, velocity and acceleration of each of ``d``
            horizontal axes [m, m/s, m/s^2].
        zmp_ref: ZMP reference at each sample ``(n, d)`` [m]; held at its last value beyond.
        gains: From :func:`preview_gains`.

    Returns:
        The states ``(n + 1, 3, d)`` at the samples and the jerks ``(n, d)`` [m/s^3] held
        between them.

    """
    x0 = np.asarray(x0, dtype=float)
    ref = np.asarray(zmp_ref, dtype=float)
    n, d = ref.shape
    N = gains.f.size
    A, B, C = gains.A, gains.B, gains.C
    # reference changes dp_ref[k] = ref[k] - ref[k-1] (0 for k = 0 and beyond the end)
    padded = np.vstack((ref, np.repeat(ref[-1:], N + 1, axis=0)))
    dref = np.diff(padded, axis=0, prepend=padded[:1])
    states = np.empty((n + 1, 3, d))
    jerks = np.empty((n, d))
    states[0] = x0
    x = x0.copy()
    dx = np.zeros((3, d))
    u = np.zeros(d)
    e = C @ x - ref[0]
    Ke, Kx = gains.K[0], gains.K[1:]
    for k in range(n):
        du = -Ke * e - Kx @ dx - gains.f @ dref[k + 1:k + 1 + N]
        u = u + du
        x_next = A @ x + np.outer(B, u)
        dx = x_next - x
        x = x_next
        e = C @ x - (ref[k + 1] if k + 1 < n else ref[-1])
        states[k + 1] = x
        jerks[k] = u
    return states, jerks
