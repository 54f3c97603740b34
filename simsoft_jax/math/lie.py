"""SO(3) and SE(3) kernels: hat/vee, exponential, logarithm, tangent operators, adjoints.

Conventions (spec ``algorithm.md`` section 0): twists are ordered ``[linear; angular]``,
poses are 4x4 homogeneous matrices ``[[R, p], [0, 1]]``, perturbations act on the right
(body frame): ``H <- H @ exp_se3(xi)``. The tangent operator ``T`` is the body (right)
Jacobian of the exponential: ``exp(x + dx) = exp(x) exp(T(x) dx) + O(dx^2)`` (spec S20).

Every coefficient function is an even analytic function of the angle ``phi``, evaluated as
a power series in ``x = phi^2`` below ``x = 1`` (10 Taylor terms, spec section 1.5) and in
closed form above, with the "double where" (S24), so values, ``jacfwd``, ``jacrev`` and
``hessian`` are finite and accurate (~1e-14) everywhere, including exactly at 0.
All functions accept and return ``jnp`` arrays, work under ``jit`` and ``vmap`` and need
float64 (enabled when ``simsoft_jax`` is imported).
"""
from __future__ import annotations

import functools
from fractions import Fraction

import jax
import jax.numpy as jnp
import numpy as np

_SERIES_SWITCH = 1.0  # series in x = phi^2 for x < 1 (phi < 1 rad), spec (S24)


def _coefficients(*terms) -> tuple[float, ...]:
    return tuple(float(Fraction(t)) for t in terms)


# Taylor coefficients c_k of each function in powers of x = phi^2 (spec section 1.5 table).
_SERIES = {
    "alpha": _coefficients(1, "-1/6", "1/120", "-1/5040", "1/362880", "-1/39916800",
                           "1/6227020800", "-1/1307674368000", "1/355687428096000",
                           "-1/121645100408832000"),
    "beta": _coefficients(1, "-1/12", "1/360", "-1/20160", "1/1814400", "-1/239500800",
                          "1/43589145600", "-1/10461394944000", "1/3201186852864000",
                          "-1/1216451004088320000"),
    "a2": _coefficients("1/6", "-1/120", "1/5040", "-1/362880", "1/39916800",
                        "-1/6227020800", "1/1307674368000", "-1/355687428096000",
                        "1/121645100408832000", "-1/51090942171709440000"),
    "c3": _coefficients("1/12", "-1/180", "1/6720", "-1/453600", "1/47900160",
                        "-1/7264857600", "1/1494484992000", "-1/400148356608000",
                        "1/135161222676480000", "-1/56200036388880384000"),
    "c4": _coefficients("-1/60", "1/1260", "-1/60480", "1/4989600", "-1/622702080",
                        "1/108972864000", "-1/25406244864000", "1/7602818775552000",
                        "-1/2838385676206080000", "1/1292600836944248832000"),
    "g2": _coefficients("1/12", "1/720", "1/30240", "1/1209600", "1/47900160",
                        "691/1307674368000", "1/74724249600", "3617/10670622842880000",
                        "43867/5109094217170944000", "174611/802857662698291200000"),
    "g4": _coefficients("1/360", "1/7560", "1/201600", "1/5987520", "691/130767436800",
                        "1/6227020800", "3617/762187345920000", "43867/319318388573184000",
                        "174611/44603203483238400000", "77683/705055001969590272000"),
}


_FORWARD = ("alpha", "beta", "a2", "c3", "c4")   # exp and T (spec S7, S8, S14, S16-S17)
_INVERSE = ("g2", "g4")                          # T^-1 (spec S9, S18-S19)
_SERIES_TABLE = {group: np.array([_SERIES[n] for n in group]) for group in (_FORWARD, _INVERSE)}


def _closed_forms(group, phi):
    """Closed forms of spec (S6) for ``group``, valid away from phi = 0, stacked (k,)."""
    half = 0.5 * phi
    x = phi * phi
    alpha = jnp.sin(phi) / phi
    beta = (jnp.sin(half) / half) ** 2  # half-angle form, no cancellation
    if group == _FORWARD:
        a2 = (1.0 - alpha) / x
        return jnp.stack([alpha, beta, a2, (beta - alpha) / x, (0.5 * beta - 3.0 * a2) / x])
    gamma = half * jnp.cos(half) / jnp.sin(half)
    return jnp.stack([(1.0 - gamma) / x, (1.0 / beta + gamma - 2.0) / (x * x)])


@functools.partial(jax.jit, static_argnums=0)
def _coefficients_of(group, x):
    """Coefficients of ``group`` as functions of ``x = phi^2``, safe at 0 (spec S24), (k,)."""
    small = x < _SERIES_SWITCH
    x_safe = jnp.where(small, _SERIES_SWITCH, x)
    table = _SERIES_TABLE[group]
    # x broadcast once: under vmap a scalar factor is broadcast anew at every product
    xs = jnp.broadcast_to(x, table.shape[:1])
    series = jnp.asarray(table[:, -1])
    for k in range(table.shape[1] - 2, -1, -1):  # Horner, all functions at once
        series = series * xs + table[:, k]
    return jnp.where(small, series, _closed_forms(group, jnp.sqrt(x_safe)))


def _forward_coefficients(w):
    alpha, beta, a2, c3, c4 = _coefficients_of(_FORWARD, jnp.dot(w, w))
    return alpha, beta, a2, c3, c4


def inverse_coefficients(w):
    """Coefficients ``(g2, g4)`` of the inverse tangents at rotation vector ``w`` (spec S6)."""
    g2, g4 = _coefficients_of(_INVERSE, jnp.dot(w, w))
    return g2, g4


def _coefficients_and_slopes(group, w):
    """Coefficients of ``group`` at rotation vector ``w`` and their derivatives with respect
    to ``x = |w|^2`` (forward mode, safe at 0; spec S24), each stacked (k,)."""
    return jax.jvp(lambda x: _coefficients_of(group, x), (jnp.dot(w, w),),
                   (jnp.ones((), w.dtype),))


def inverse_coefficients_and_derivatives(w):
    """``(g2, g4)`` at rotation vector ``w`` and their derivatives with respect to
    ``x = |w|^2``, ``((g2, g4), (dg2/dx, dg4/dx))`` (forward mode, safe at 0; spec S24)."""
    values, slopes = _coefficients_and_slopes(_INVERSE, w)
    return (values[0], values[1]), (slopes[0], slopes[1])


def translation_coefficients(w):
    """Coefficients of ``V(w) = T_SO3(w)^T = I + c1 W + c2 W^2`` (``W = skew(w)``), the map
    that gives the translation ``V(w) U`` of ``exp_se3([U; w])`` (spec S14), and their first
    and second derivatives with respect to ``x = |w|^2``:
    ``((c1, c2), (c1', c2'), (c1'', c2''))``. With the spec's coefficients (S6)
    ``c1 = beta/2``, ``c2 = a2``, and differentiating their closed forms gives
    ``c1' = -c3/2``, ``c2' = c4/2``; the second derivatives come from one forward-mode
    derivative of ``c3, c4`` (safe at 0, spec S24).
    """
    values, slopes = _coefficients_and_slopes(_FORWARD, w)
    _, beta, a2, c3, c4 = values
    return (0.5 * beta, a2), (-0.5 * c3, 0.5 * c4), (-0.5 * slopes[3], 0.5 * slopes[4])


# --------------------------------------------------------------------------------------
# hat / vee / adjoints (spec S1-S4)
# --------------------------------------------------------------------------------------

# skew(w)_ij = -eps_ijk w_k (Levi-Civita symbol eps): the skew matrix as one product and
# sum (a few operations in a compiled program instead of some twenty per call)
_SKEW_BASIS = -np.array([[[float(np.linalg.det(np.eye(3)[[i, j, k]])) for k in range(3)]
                          for j in range(3)] for i in range(3)])


def skew(w):
    """3x3 skew matrix with ``skew(w) @ y = w x y`` (the paper's eq. 115, spec S1); ``w`` (3,)
    or (3, ...) gives (3, 3, ...)."""
    w = jnp.asarray(w)
    basis = _SKEW_BASIS.reshape((3, 3, 3) + (1,) * (w.ndim - 1))
    return jnp.sum(basis * w, axis=2)


def vee_so3(W):
    """Inverse of :func:`skew`: the axial vector of a skew 3x3 matrix, shape (3,)."""
    return jnp.array([W[2, 1], W[0, 2], W[1, 0]])


def spatial_inertia(mass, offset, inertia):
    """Spatial inertia (6,6) about a body-fixed point, ordered ``[linear; angular]``:
    ``[[m I, -m C], [m C, J_c - m C C]]`` with ``C = skew(c)`` (e.g. Murray, Li & Sastry
    1994, ch. 4), for a mass ``m`` (kg, or kg/m per length) with its centre at ``c`` (3,)
    (m, body frame) and the inertia ``J_c`` (3,3) about that centre (kg m^2, or kg m per
    length); kinetic energy ``V^T M V / 2`` of the body twist ``V = [v; w]``."""
    offset = jnp.asarray(offset)
    C = skew(offset)
    eye = jnp.eye(3, dtype=C.dtype)
    return jnp.block([[mass * eye, -mass * C], [mass * C, inertia - mass * C @ C]])


def hat_se3(xi):
    """4x4 matrix of the twist ``xi = [U; Omega]`` (the paper's eq. 114, spec S2)."""
    xi = jnp.asarray(xi)
    top = jnp.concatenate([skew(xi[3:]), xi[:3, None]], axis=1)
    return jnp.concatenate([top, jnp.zeros((1, 4), xi.dtype)], axis=0)


def vee_se3(X):
    """Inverse of :func:`hat_se3`: twist ``[U; Omega]`` (6,) of a 4x4 se(3) matrix."""
    return jnp.concatenate([X[:3, 3], vee_so3(X[:3, :3])])


def ad_se3(xi):
    """6x6 adjoint of the Lie algebra, ``ad_a b = [a, b]`` (the paper's eq. 121, spec S3)."""
    U, W = skew(xi[:3]), skew(xi[3:])
    Z = jnp.zeros((3, 3), W.dtype)
    return jnp.block([[W, U], [Z, W]])


def adjoint_se3(H):
    """6x6 group adjoint ``Ad_H`` with ``H hat(y) H^-1 = hat(Ad_H y)`` (the paper's eq. 118, S4)."""
    R, p = H[:3, :3], H[:3, 3]
    Z = jnp.zeros((3, 3), R.dtype)
    return jnp.block([[R, skew(p) @ R], [Z, R]])


# --------------------------------------------------------------------------------------
# SO(3)
# --------------------------------------------------------------------------------------

def exp_so3(w):
    """Rotation matrix ``exp(skew(w))`` (Rodrigues, the paper's eq. 124, spec S7), shape (3,3)."""
    alpha, beta, *_ = _forward_coefficients(w)
    W = skew(w)
    return jnp.eye(3, dtype=W.dtype) + alpha * W + 0.5 * beta * (W @ W)


def tangent_so3(w):
    """Body tangent ``T_SO3(w) = I - (beta/2) W + a2 W^2`` (the paper's eq. 130, spec S8)."""
    _, beta, a2, _, _ = _forward_coefficients(w)
    W = skew(w)
    return jnp.eye(3, dtype=W.dtype) - 0.5 * beta * W + a2 * (W @ W)


def tangent_so3_inv(w):
    """Inverse body tangent ``I + W/2 + g2 W^2`` (spec S9; the paper's eq. 133 is its transpose)."""
    g2, _ = inverse_coefficients(w)
    W = skew(w)
    return jnp.eye(3, dtype=W.dtype) + 0.5 * W + g2 * (W @ W)


def _tangent_so3_inv_transpose(w):
    """``T_SO3^-T(w) = I - W/2 + g2 W^2`` (spec S15)."""
    g2, _ = inverse_coefficients(w)
    W = skew(w)
    return jnp.eye(3, dtype=W.dtype) - 0.5 * W + g2 * (W @ W)


def _quaternion_from_matrix(R):
    """Unit quaternion ``[q0, qv]`` with ``q0 >= 0`` by Shepperd's method (spec S13)."""
    tr = jnp.trace(R)
    candidates = jnp.array([
        [1.0 + tr, R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]],
        [R[2, 1] - R[1, 2], 1.0 + 2 * R[0, 0] - tr, R[0, 1] + R[1, 0], R[0, 2] + R[2, 0]],
        [R[0, 2] - R[2, 0], R[0, 1] + R[1, 0], 1.0 + 2 * R[1, 1] - tr, R[1, 2] + R[2, 1]],
        [R[1, 0] - R[0, 1], R[0, 2] + R[2, 0], R[1, 2] + R[2, 1], 1.0 + 2 * R[2, 2] - tr],
    ])
    big = jnp.array([tr, R[0, 0], R[1, 1], R[2, 2]])
    one_hot = (jnp.arange(4) == jnp.argmax(big)).astype(R.dtype)
    q = one_hot @ candidates  # selection without a gather (cheaper to compile and differentiate)
    q = q / jnp.linalg.norm(q)
    return jnp.where(q[0] < 0, -q, q)


def log_so3(R):
    """Rotation vector of ``R`` (angle in [0, pi]) through the quaternion (spec S13), (3,).

    Accurate near 0 and near pi; at exactly pi either of the two branches is returned.
    """
    q = _quaternion_from_matrix(R)
    q0, qv = q[0], q[1:]
    s2 = jnp.dot(qv, qv)
    # 2 atan2(s, q0) / s: series in y = s^2/q0^2 where s is small relative to q0 (spec S13)
    small = s2 < 0.01 * q0 * q0  # |s/q0| < 0.1: 12 terms reach 1e-24
    y = jnp.where(small, s2 / jnp.where(small, q0 * q0, 1.0), 0.0)
    series = jnp.zeros_like(y)
    for k in reversed(range(12)):
        series = series * y + (-1.0) ** k / (2 * k + 1)
    s_safe = jnp.sqrt(jnp.where(small, 1.0, s2))
    factor = jnp.where(small, 2.0 / jnp.where(small, q0, 1.0) * series,
                       2.0 * jnp.arctan2(s_safe, q0) / s_safe)
    return factor * qv


# --------------------------------------------------------------------------------------
# SE(3)
# --------------------------------------------------------------------------------------

def exp_se3(xi):
    """Pose ``exp(hat(xi))`` = ``(exp_SO3(Omega), T_SO3^T(Omega) U)`` (paper eq. 123, S14), (4,4)."""
    xi = jnp.asarray(xi)
    U, w = xi[:3], xi[3:]
    R = exp_so3(w)
    p = tangent_so3(w).T @ U
    top = jnp.concatenate([R, p[:, None]], axis=1)
    return jnp.concatenate([top, jnp.array([[0.0, 0.0, 0.0, 1.0]], R.dtype)], axis=0)


def log_se3(H):
    """Twist ``[T_SO3^-T(Omega) p; Omega]`` with ``Omega = log_so3(R)`` (paper eq. 126, S15), (6,)."""
    w = log_so3(H[:3, :3])
    return jnp.concatenate([_tangent_so3_inv_transpose(w) @ H[:3, 3], w])


def tangent_plus(U, w):
    """Off-diagonal block ``T_+(U, Omega)`` of ``T_SE3`` (spec S17, paper eq. 131 corrected)."""
    _, beta, a2, c3, c4 = _forward_coefficients(w)
    Us, W = skew(U), skew(w)
    return (-0.5 * beta * Us + a2 * (Us @ W + W @ Us)
            + jnp.dot(w, U) * (c3 * W + c4 * (W @ W)))


def _tangent_minus(U, w):
    """Off-diagonal block ``T_-(U, Omega)`` of ``T_SE3^-1`` (spec S19, paper eq. 135 corrected)."""
    g2, g4 = inverse_coefficients(w)
    Us, W = skew(U), skew(w)
    return 0.5 * Us + g2 * (W @ Us + Us @ W) + jnp.dot(w, U) * g4 * (W @ W)


def tangent_se3(xi):
    """Body tangent ``T_SE3(xi)`` (6,6), block upper-triangular (the paper's eq. 129, spec S16)."""
    U, w = xi[:3], xi[3:]
    T = tangent_so3(w)
    return jnp.block([[T, tangent_plus(U, w)], [jnp.zeros((3, 3), T.dtype), T]])


def tangent_se3_inv(xi):
    """Inverse body tangent ``T_SE3^-1(xi)`` (6,6) (the paper's eq. 132, spec S18-S19)."""
    U, w = xi[:3], xi[3:]
    Ti = tangent_so3_inv(w)
    return jnp.block([[Ti, _tangent_minus(U, w)], [jnp.zeros((3, 3), Ti.dtype), Ti]])


# --------------------------------------------------------------------------------------
# Pose helpers on (R, p) pairs (used by the element kernels; cheaper than 4x4 products)
# --------------------------------------------------------------------------------------

def pose(R, p):
    """4x4 homogeneous matrix of rotation ``R`` (3,3) and position ``p`` (3,)."""
    top = jnp.concatenate([R, p[:, None]], axis=1)
    return jnp.concatenate([top, jnp.array([[0.0, 0.0, 0.0, 1.0]], R.dtype)], axis=0)


def relative_pose(RA, pA, RB, pB):
    """``H_A^-1 H_B`` as a 4x4 matrix, from the rotations and positions of A and B."""
    return pose(RA.T @ RB, RA.T @ (pB - pA))


def compose_exp(R, p, xi):
    """``(R, p) @ exp_se3(xi)`` returned as ``(R', p')`` (right/body update, spec S54, S71)."""
    E = exp_se3(xi)
    return R @ E[:3, :3], p + R @ E[:3, 3]


def compose_exp_quadratic(R, p, xi):
    """``(R, p) @ exp_se3(xi)`` to second order in ``xi = [u; w]``:
    ``(R (I + W + W^2/2), p + R (u + w x u / 2))`` (the series of the paper's eq. 123 cut after
    the quadratic terms). Its value, first and second derivatives at ``xi = 0`` equal
    those of :func:`compose_exp`, at a fraction of the cost of differentiating the full
    exponential twice: for Hessians at the current iterate (joint Lagrangians)."""
    W = skew(xi[3:])
    eye = jnp.eye(3, dtype=R.dtype)
    return R @ (eye + W + 0.5 * W @ W), p + R @ (xi[:3] + 0.5 * jnp.cross(xi[3:], xi[:3]))
