"""One two-node helical SE(3) element (spec algorithm.md section 3), written for a single
element and ``vmap``-ped by :mod:`simsoft_jax.assembly`.

Nodal frames are the cross-section frames themselves (the seed's constant offsets
``H_A0, H_B0`` of eqs. 26-30 are absorbed into the nodal reference frames, so
``G_A = G_B = I`` in spec S33-S38; both elements sharing a node then share its section
frame, which is the continuity condition the offsets must satisfy anyway).

Shapes: rotations (3,3), positions (3,), twists (6,) ordered ``[linear; angular]``,
element vectors (12,) ordered ``[node A (6); node B (6)]``, all in the nodal (local) frames.
"""
from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from . import lie

# 3-point Gauss-Legendre rule on [0, 1] for the consistent distributed load (spec S44)
_GAUSS_POINTS = 0.5 * (1.0 + np.array([-np.sqrt(0.6), 0.0, np.sqrt(0.6)]))
_GAUSS_WEIGHTS = 0.5 * np.array([5.0, 8.0, 5.0]) / 9.0


def relative_twist(RA, pA, RB, pB):
    """Element deformation ``d = log(H_A^-1 H_B)`` (seed eq. 28, spec S33), shape (6,)."""
    return lie.log_se3(lie.relative_pose(RA, pA, RB, pB))


def strain_map(d):
    """``P(d) = [-T^-1(-d), T^-1(d)]`` (6,12): ``d_dot = P(d) [v_A; v_B]`` (seed eqs. 41-42, S37).

    Both inverse tangents share their coefficients: with ``W = skew(d_w)``, ``V = skew(d_u)``,
    ``T^-1(+-d) = [[I +- W/2 + g2 W^2, +-V/2 + C], [0, I +- W/2 + g2 W^2]]`` where
    ``C = g2 (W V + V W) + (d_w . d_u) g4 W^2`` (spec S18-S19).
    """
    W, V = lie.skew(d[3:]), lie.skew(d[:3])
    g2, g4 = lie.inverse_coefficients(d[3:])
    W2 = W @ W
    eye = jnp.eye(3, dtype=d.dtype)
    common = g2 * (W @ V + V @ W) + jnp.dot(d[3:], d[:3]) * g4 * W2
    zero = jnp.zeros((3, 3), d.dtype)
    plus_rot, minus_rot = eye + 0.5 * W + g2 * W2, eye - 0.5 * W + g2 * W2
    return jnp.block([[-minus_rot, 0.5 * V - common, plus_rot, 0.5 * V + common],
                      [zero, -minus_rot, zero, plus_rot]])


def internal_force(P, d, d0, length, stiffness):
    """Elastic nodal forces ``P(d)^T K (d - d0)/L`` (12,) (seed eq. 48, spec S36, S39).

    ``P = strain_map(d)`` is passed in so that callers computing it once can share it.
    ``stiffness`` is the diagonal ``[EA, GAy, GAz, GJ, EIy, EIz]`` (N, N m^2), ``length`` in m.
    The result is the exact gradient of the element energy ``(L/2) eps^T K eps`` under
    right perturbations of the two nodal frames.
    """
    strain = (d - d0) / length
    return P.T @ (stiffness * strain)


def distributed_force(RA, d, P, length, world_force, local_force):
    """Consistent nodal forces of a distributed force per unit length (N/m) (spec S44).

    ``world_force`` (3,) is fixed in space (dead: gravity ``rhoA g`` and world-frame
    distributed loads); ``local_force`` (3,) turns with the section (follower). The force
    acts on the reference line: ``f = int_0^L N(s, d)^T [R(s)^T f_world + f_local; 0] ds``
    (3-point Gauss-Legendre), with ``N = [Ad_{exp(-xi d)}, 0] + xi T(xi d) P(d)`` (S38,
    rewritten with S22). Only the force rows of ``N`` act, so with ``exp(xi d) = (R_xi,
    p_xi)`` and ``g = R(s)^T f`` the integrand is
    ``[R_xi g; p_xi x R_xi g; 0] + xi P^T [T_SO3(xi d_w)^T g; T_+(xi d)^T g]``.
    ``P = strain_map(d)`` (6,12). Returns (12,).
    """
    def integrand(xi, weight):
        h = xi * d
        R_xi = lie.exp_so3(h[3:])
        T = lie.tangent_so3(h[3:])
        p_xi = T.T @ h[:3]
        f_a = RA.T @ world_force + R_xi @ local_force   # R_xi g, in node A's frame
        g = R_xi.T @ f_a
        direct = jnp.concatenate([f_a, jnp.cross(p_xi, f_a), jnp.zeros(6, d.dtype)])
        through_d = xi * (P.T @ jnp.concatenate([T.T @ g, lie.tangent_plus(h[:3], h[3:]).T @ g]))
        return (weight * length) * (direct + through_d)

    return jnp.sum(jax.vmap(integrand)(_GAUSS_POINTS, _GAUSS_WEIGHTS), axis=0)


def velocity_field_map(xi, d, P):
    """``N(s, d)`` (6,12) with ``v(s) = N [v_A; v_B]`` at ``xi = s/L`` (seed eqs. 36, 40; S38).

    Written as ``N = [Ad_{exp(-xi d)}, 0] + xi T(xi d) P(d)`` (the same as S38 by S22),
    reusing the element's strain map ``P = strain_map(d)`` (6,12).
    """
    left = lie.adjoint_se3(lie.exp_se3(-xi * d))
    return (jnp.concatenate([left, jnp.zeros_like(left)], axis=1)
            + xi * lie.tangent_se3(xi * d) @ P)


def viscous_force(P, velocities, length, viscosity):
    """Kelvin-Voigt forces ``P^T Upsilon P v_e / L`` (12,) (seed eq. 8, spec S40).

    ``velocities`` (12,) are the nodal body velocities ``[v_A; v_B]``; ``viscosity`` the
    diagonal ``mu [3A, A, A, J_t, 3Iy, 3Iz]`` (spec S28).
    """
    strain_rate = P @ velocities / length
    return P.T @ (viscosity * strain_rate)
