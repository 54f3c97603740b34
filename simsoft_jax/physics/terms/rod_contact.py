"""Rod-rod and self contact between element centrelines: a smooth penalty on the gap of
the closest points of pairs of sub-chords, forces and tangents by automatic
differentiation of the pair energy (so Newton's third law holds by construction).

Where. Each element's centreline is the cubic Hermite curve through its two nodes with
the tangents ``L R_A e_1``, ``L R_B e_1`` (``L`` the reference length; it agrees with the
helical interpolation ``H_A exp(xi d)`` of spec S33 to ``O(kappa^3 L^4)`` for unsheared
elements, and its second derivatives in the frames cost far less to compile than those
of the SE(3) logarithm). It is sampled at the ``m + 1`` stations ``xi = j/m``
(``m = [contact] quadrature_points``; the first and last are the nodes): ``m`` straight
sub-chords per element. For two elements e, f (a
candidate pair of :mod:`simsoft_jax.couplings.broad_phase`) every sub-chord pair (i, j) gets the
closest points of the two chords, extended by ``EXTENSION`` of their length at both ends
(parameters ``s, t`` in ``[-beta, 1 + beta]``), at distance ``D_ij``; ``s`` is
regularized towards the projection of the other chord's midpoint (weight
``PARALLEL``), which near-parallel chords (a coil, a fold) take, so their weights do
not jump along the chord (:func:`closest_points`).

Normal contact (penalty). The gap is ``g = D - r_e - r_f`` (``r`` the contact radii,
m), the penetration ``delta = -g``, and the pair energy (J)

    E_ef = sum_ij h(s_ij) h(t_ij) l_ef psi(delta_ij)

with ``psi`` the C2 penalty of :mod:`simsoft_jax.physics.terms.contact` (stiffness
``k_ef = (k_e + k_f)/2`` N/m^2, smoothing width ``eps = SMOOTHING (r_e + r_f)``) and
``l_ef = (L_e + L_f) / (2 m)`` the mean sub-chord length (m): a point contact of
stiffness ``l_ef k_ef`` (N/m) past the smoothing width, so a crossing pressed with a
force F sinks by about ``F / (l k) + eps/2``. ``h`` is a C2 partition of unity on the
chord parameter (a quintic smoothstep ramp over ``[-beta, beta]`` and
``[1 - beta, 1 + beta]``): two collinear neighbouring chords share a crossing at their
common station with weights summing to 1, so a crossing does not count twice (or four
times) where it passes a station or a node (for chords meeting at an angle theta the
sum is ``1 + O(theta r / l)``). At a rod's free ends the chord is not extended and not
ramped.

Forces. The residual of a pair is the derivative of ``E_ef`` in the right perturbations
``H exp(x)`` of its four nodal frames (24,), its tangent the derivative of that residual
(``jax.jacfwd``, 24x24), both in the chart ``lie.compose_exp_quadratic`` (exact to
second order at the current frames: all the residual and its tangent need). The energy
depends only on relative positions, so the forces on the two elements are equal and
opposite and their moments balance exactly.

Limits. Contact is between the sub-chords, not the curve (its sagitta,
``kappa (L/m)^2 / 8``, is an error of the gap). It is made for crossing contacts (point
contacts); along a near-parallel line contact each overlapping pair of sub-chords acts
as one point spring, so the line stiffness ``k`` is met only on average (within a
factor ~2, depending on how the sub-chords overlap). Friction between rods is not
modelled.
"""
from __future__ import annotations

import jax
import jax.numpy as jnp

from ...math import lie
from ..obstacles import safe_norm
from .contact import SMOOTHING, penalty, penalty_slope

EXTENSION = 0.25    # beta: chord extension (fraction of its length) of the partition ramps
PARALLEL = 0.1      # regularization of the closest-point solve (relative to a e: sin^2)


def smoothstep(u):
    """Quintic ramp, 0 for u <= 0, 1 for u >= 1, C2; ``S(u) + S(1 - u) = 1``."""
    u = jnp.clip(u, 0.0, 1.0)
    return u**3 * (10.0 - 15.0 * u + 6.0 * u**2)


def stations(RA, pA, RB, pB, length, m: int):
    """Positions (m+1, 3) of the stations ``xi = j/m`` of an element's centreline curve:
    the cubic Hermite curve through the nodes with the tangents ``L R e_1`` (``L`` the
    reference length, m; module docstring)."""
    xi = jnp.linspace(0.0, 1.0, m + 1)[:, None]
    h00, h01 = 1.0 - xi**2 * (3.0 - 2.0 * xi), xi**2 * (3.0 - 2.0 * xi)
    h10, h11 = xi * (1.0 - xi) ** 2, xi**2 * (xi - 1.0)
    return h00 * pA + h01 * pB + length * (h10 * RA[:, 0] + h11 * RB[:, 0])


def closest_points(p1, q1, p2, q2, lo1, hi1, lo2, hi2):
    """Closest points of the chords ``p1 + s (q1 - p1)``, ``s in [lo1, hi1]``, and
    ``p2 + t (q2 - p2)``, ``t in [lo2, hi2]``: ``(s, t, distance)`` (m); ``s`` is
    regularized towards the second chord's midpoint (below), ``t`` the nearest point to
    ``s``."""
    d1, d2, r = q1 - p1, q2 - p2, p1 - p2
    a, e = jnp.dot(d1, d1), jnp.dot(d2, d2)
    b, c, f = jnp.dot(d1, d2), jnp.dot(d1, r), jnp.dot(d2, r)
    # Tikhonov-regularized towards s_mid, where the second chord's midpoint projects:
    # near-parallel chords (a e - b^2 -> 0) take s_mid, well conditioned, instead of a
    # closest point that jumps along the chord; crossing chords keep their closest point
    # up to O(PARALLEL) (exactly when perpendicular), and the distance is stationary there
    s_mid = (0.5 * b - c) / a
    s = jnp.clip((b * f - c * e + PARALLEL * a * e * s_mid)
                 / (a * e - b * b + PARALLEL * a * e), lo1, hi1)
    t = (b * s + f) / e
    s = jnp.where(t < lo2, jnp.clip((b * lo2 - c) / a, lo1, hi1),
                  jnp.where(t > hi2, jnp.clip((b * hi2 - c) / a, lo1, hi1), s))
    t = jnp.clip(t, lo2, hi2)
    return s, t, safe_norm(r + s * d1 - t * d2)


def _bounds(m: int, start, end):
    """Per sub-chord (m,): parameter bounds lo, hi (extended unless at a rod's free end:
    ``start``/``end`` 1.0 for a rod's first/last element, else 0.0)."""
    j = jnp.arange(m)
    lo = jnp.where((j == 0) & (start > 0.5), 0.0, -EXTENSION)
    hi = jnp.where((j == m - 1) & (end > 0.5), 1.0, 1.0 + EXTENSION)
    return lo, hi


def weight(s, lo, hi):
    """Partition-of-unity weight ``h(s)`` of a chord parameter; no ramp on an end that
    is not extended (``lo = 0`` or ``hi = 1``)."""
    width = 2.0 * EXTENSION
    rise = jnp.where(lo < 0.0, smoothstep((s - lo) / width), 1.0)
    fall = jnp.where(hi > 1.0, smoothstep((hi - s) / width), 1.0)
    return rise * fall


def pair_points(Xe, Xf, ends_e, ends_f):
    """Per sub-chord pair (m, m): weights ``h(s) h(t)`` and distances (m) of the
    stations ``Xe``, ``Xf`` (m+1, 3) of two elements; ``ends_*`` (2,) their rod-end flags
    (:func:`_bounds`)."""
    m = Xe.shape[0] - 1
    lo_e, hi_e = _bounds(m, *ends_e)
    lo_f, hi_f = _bounds(m, *ends_f)

    def one(i, j):
        s, t, dist = closest_points(Xe[i], Xe[i + 1], Xf[j], Xf[j + 1], lo_e[i], hi_e[i],
                                    lo_f[j], hi_f[j])
        return weight(s, lo_e[i], hi_e[i]) * weight(t, lo_f[j], hi_f[j]), dist

    i, j = jnp.meshgrid(jnp.arange(m), jnp.arange(m), indexing="ij")
    return jax.vmap(jax.vmap(one))(i, j)


def _penetrations(frames, radius, stiffness, length, ends, m: int):
    """Weights and penetrations (m, m) (m) of one pair, its point stiffness ``l k``
    (N/m) and smoothing width ``eps`` (m) (arguments of :func:`pair_energy`)."""
    R, p = frames
    Xe = stations(R[0], p[0], R[1], p[1], length[0], m)
    Xf = stations(R[2], p[2], R[3], p[3], length[1], m)
    w, dist = pair_points(Xe, Xf, ends[0], ends[1])
    rsum = radius[0] + radius[1]
    scale = 0.25 * (length[0] + length[1]) * (stiffness[0] + stiffness[1]) / m
    return w, rsum - dist, scale, SMOOTHING * rsum


def pair_energy(frames, radius, stiffness, length, ends, m: int):
    """Penalty energy (J) of one element pair (module docstring). ``frames``: the four
    nodal frames ``(R, p)`` (4,3,3), (4,3) (e's A, B, then f's A, B); ``radius``,
    ``stiffness``, ``length`` (2,) of e and f (m, N/m^2, m); ``ends`` (2,2) rod-end flags."""
    w, delta, scale, eps = _penetrations(frames, radius, stiffness, length, ends, m)
    return jnp.sum(w * penalty(delta, scale, eps))


def pair_summary(frames, radius, stiffness, length, ends, m: int):
    """Normal force magnitude (N, ``sum h h l psi'``), force on element e (3,) N (world;
    f gets its opposite) and largest penetration (m, 0 if none) of one pair."""
    R, p = frames

    def energy_of_e(shift):
        return pair_energy((R, p.at[:2].add(shift)), radius, stiffness, length, ends, m)

    w, delta, scale, eps = _penetrations(frames, radius, stiffness, length, ends, m)
    normal = jnp.sum(w * penalty_slope(delta, scale, eps))
    force = -jax.grad(energy_of_e)(jnp.zeros(3, p.dtype))     # rigid shift of e
    return normal, force, jnp.maximum(jnp.max(jnp.where(w > 0.0, delta, 0.0)), 0.0)


def pair_residual(frames, radius, stiffness, length, ends, m: int):
    """Residual (24,) of one pair: the derivative of :func:`pair_energy` in the right
    perturbations ``H exp(x)`` of its four nodal frames ``[x_eA, x_eB, x_fA, x_fB]``."""
    R, p = frames

    def energy(z):
        Rz, pz = jax.vmap(lie.compose_exp_quadratic)(R, p, z.reshape(4, 6))
        return pair_energy((Rz, pz), radius, stiffness, length, ends, m)

    return jax.grad(energy)(jnp.zeros(24, p.dtype))


def pair_residual_and_tangent(frames, radius, stiffness, length, ends, m: int):
    """:func:`pair_residual` (24,) and its tangent (24,24): its derivative at the
    perturbed frames ``H exp(y)`` in ``y`` (the left-invariant tangent, spec S70)."""
    R, p = frames

    def residual(y):
        moved = jax.vmap(lie.compose_exp_quadratic)(R, p, y.reshape(4, 6))
        value = pair_residual(moved, radius, stiffness, length, ends, m)
        return value, value

    jac, value = jax.jacfwd(residual, has_aux=True)(jnp.zeros(24, p.dtype))
    return value, jac
