"""One two-node helical SE(3) element (spec algorithm.md section 3), written for a single
element and ``vmap``-ped by :mod:`simsoft_jax.physics.assembly`.

Nodal frames are the cross-section frames themselves (the paper's constant offsets
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

from ..math import lie

# 3-point Gauss-Legendre rule on [0, 1] for the consistent distributed load (spec S44)
_GAUSS_POINTS = 0.5 * (1.0 + np.array([-np.sqrt(0.6), 0.0, np.sqrt(0.6)]))
_GAUSS_WEIGHTS = 0.5 * np.array([5.0, 8.0, 5.0]) / 9.0


def relative_twist(RA, pA, RB, pB):
    """Element deformation ``d = log(H_A^-1 H_B)`` (the paper's eq. 28, spec S33), shape (6,)."""
    return lie.log_se3(lie.relative_pose(RA, pA, RB, pB))


def strain_map(d):
    """``P(d) = [-T^-1(-d), T^-1(d)]`` (6,12): ``d_dot = P(d) [v_A; v_B]`` (paper eqs. 41-42, S37).

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


def section_stress(stiffness, strain):
    """Section stress resultant ``K eps`` (6,) (spec S28, S39) of the strain ``eps`` (6,)
    ``[eps_x, gamma_y, gamma_z, kappa_x, kappa_y, kappa_z]``.

    ``stiffness`` is either the diagonal (6,) ``[EA, GAy, GAz, GJ, EIy, EIz]`` (N, N m^2)
    or a full symmetric positive definite matrix (6,6) with couplings (units N, N m,
    N m^2 by block); which one is a static property of the array's shape, so an uncoupled
    scene traces exactly the diagonal product.
    """
    if stiffness.ndim == 2:
        return stiffness @ strain
    return stiffness * strain


def section_stress_jacobian(stiffness, length):
    """``d stress / d d`` (6,6) of the elastic stress ``K (d - d0)/L``: ``K / L`` for a
    (6,6) ``stiffness``, ``diag(K) / L`` for a diagonal (6,); ``length`` in m."""
    if stiffness.ndim == 2:
        return stiffness / length
    return jnp.diag(stiffness / length)


def strain_energy(d, d0, length, stiffness):
    """Element strain energy ``(L/2) eps^T K eps`` (J) with ``eps = (d - d0)/L`` (S36)."""
    strain = (d - d0) / length
    return 0.5 * length * jnp.dot(strain, section_stress(stiffness, strain))


def internal_force(P, d, d0, length, stiffness):
    """Elastic nodal forces ``P(d)^T K (d - d0)/L`` (12,) (the paper's eq. 48, spec S36, S39).

    ``P = strain_map(d)`` is passed in so that callers computing it once can share it.
    ``stiffness``: the diagonal (6,) or the full symmetric matrix (6,6)
    (:func:`section_stress`), ``length`` in m. The result is the exact gradient of the
    element energy ``(L/2) eps^T K eps`` (:func:`strain_energy`) under right perturbations
    of the two nodal frames.
    """
    return P.T @ section_stress(stiffness, (d - d0) / length)


def _w2(w, a):
    """``W^2 a = w (w . a) - |w|^2 a`` with ``W = skew(w)``."""
    return w * jnp.dot(w, a) - jnp.dot(w, w) * a


def _w2_jacobian(w, a):
    """Derivative of ``W^2 a`` with respect to ``w``: ``(w . a) I + w a^T - 2 a w^T``."""
    return jnp.dot(w, a) * jnp.eye(3, dtype=w.dtype) + jnp.outer(w, a) - 2.0 * jnp.outer(a, w)


def _inverse_tangent_transpose_jacobian(d, stress, coefficients):
    """Derivative (6,6) of ``T_SE3^-T(d) stress`` with respect to ``d`` at fixed stress.

    With ``T^-T(d) s = [A^T s_u; B^T s_u + A^T s_w]``, ``A^T = I - W/2 + g2 W^2`` and
    ``B^T = -V/2 + g2 (V W + W V) + (w . u) g4 W^2`` (spec S18-S19; ``u, w`` the linear and
    angular parts of d, ``V, W`` their skew matrices), differentiated term by term; the
    coefficients ``g2, g4`` of ``x = |w|^2`` and their x-derivatives come from
    ``coefficients``, the value of :func:`lie.inverse_coefficients_and_derivatives` at
    ``w`` (``d`` and ``-d`` share it). Checked against ``jax.jacfwd``.
    """
    u, w, su, sw = d[:3], d[3:], stress[:3], stress[3:]
    (g2, g4), (g2x, g4x) = coefficients
    wu = jnp.dot(w, u)
    w2su, w2sw = _w2(w, su), _w2(w, sw)
    cross_su = jnp.cross(u, jnp.cross(w, su)) + jnp.cross(w, jnp.cross(u, su))
    Su = lie.skew(su)
    du_u = jnp.zeros((3, 3), d.dtype)
    du_w = 0.5 * Su + g2 * _w2_jacobian(w, su) + 2.0 * g2x * jnp.outer(w2su, w)
    dw_u = (0.5 * Su - g2 * (lie.skew(jnp.cross(w, su)) + lie.skew(w) @ Su)
            + g4 * jnp.outer(w2su, w))
    dw_w = (0.5 * lie.skew(sw) + g2 * _w2_jacobian(w, sw) + 2.0 * g2x * jnp.outer(w2sw, w)
            - g2 * (lie.skew(u) @ Su + lie.skew(jnp.cross(u, su)))
            + 2.0 * g2x * jnp.outer(cross_su, w)
            + g4 * jnp.outer(w2su, u) + wu * g4 * _w2_jacobian(w, su)
            + 2.0 * wu * g4x * jnp.outer(w2su, w))
    return jnp.block([[du_u, du_w], [dw_u, dw_w]])


def stress_force_and_tangent(P, d, stress, stress_jacobian):
    """Nodal forces ``P(d)^T stress`` (12,) of a section stress resultant (6,) (spec S39,
    S41) and their left-invariant tangent (12,12) (spec S42).

    ``stress_jacobian`` (6,6) is ``d stress / d d`` (``K/L`` for elastic stress). With
    ``P^T s = [-T^-T(-d) s; T^-T(d) s]`` the derivative in d is the geometric stiffness
    ``[G(-d, s); G(d, s)]`` (G from :func:`_inverse_tangent_transpose_jacobian`) plus
    ``P^T d stress/d d``; the chart ``d + P x`` of the nodal perturbations x (spec S37)
    then multiplies it by ``P`` on the right. ``P = strain_map(d)`` (6,12).
    """
    coefficients = lie.inverse_coefficients_and_derivatives(d[3:])
    geometric = jnp.concatenate([_inverse_tangent_transpose_jacobian(-d, stress, coefficients),
                                 _inverse_tangent_transpose_jacobian(d, stress, coefficients)])
    return P.T @ stress, (geometric + P.T @ stress_jacobian) @ P


def _translation_potential(h, a):
    """``phi(h) = a . p(h)`` for the translation ``p(h) = V(h_w) h_u`` of ``exp_se3(h)``
    (spec S14) and a fixed vector a (3,): ``p`` (3,), its Jacobian ``J = dp/dh`` (3,6), and
    the Hessian of ``phi`` (6,6), in closed form from ``V = I + c1 W + c2 W^2`` written with
    dot and cross products (``x = |w|^2``, primes are x-derivatives,
    :func:`lie.translation_coefficients`):
    ``phi = a.u + c1 w.(u x a) + c2 ((w.a)(w.u) - x a.u)``.
    """
    u, w = h[:3], h[3:]
    (c1, c2), (c1p, c2p), (c1pp, c2pp) = lie.translation_coefficients(w)
    eye = jnp.eye(3, dtype=h.dtype)
    wu, wa, au, x = jnp.dot(w, u), jnp.dot(w, a), jnp.dot(a, u), jnp.dot(w, w)
    p = u + c1 * jnp.cross(w, u) + c2 * (w * wu - x * u)
    jac_w = (-c1 * lie.skew(u) + 2.0 * c1p * jnp.outer(jnp.cross(w, u), w)
             + c2 * (wu * eye + jnp.outer(w, u) - 2.0 * jnp.outer(u, w))
             + 2.0 * c2p * jnp.outer(w * wu - x * u, w))
    jac_u = eye + c1 * lie.skew(w) + c2 * (jnp.outer(w, w) - x * eye)
    # d(grad_u phi)/dw with grad_u phi = V^T a = a + c1 a x w + c2 ((w.a) w - x a)
    h_uw = (c1 * lie.skew(a) + 2.0 * c1p * jnp.outer(jnp.cross(a, w), w)
            + c2 * (jnp.outer(w, a) + wa * eye - 2.0 * jnp.outer(a, w))
            + 2.0 * c2p * jnp.outer(wa * w - x * a, w))
    # d(grad_w phi)/dw, grad_w phi = c1 (u x a) + 2 c1' s1 w + c2 q + 2 c2' s2 w
    ua = jnp.cross(u, a)
    s1, s2 = jnp.dot(w, ua), wa * wu - x * au
    q = a * wu + u * wa - 2.0 * w * au
    h_ww = (2.0 * c1p * (jnp.outer(ua, w) + jnp.outer(w, ua))
            + 2.0 * c2p * (jnp.outer(q, w) + jnp.outer(w, q))
            + 2.0 * (c1p * s1 + c2p * s2) * eye
            + 4.0 * (c1pp * s1 + c2pp * s2) * jnp.outer(w, w)
            + c2 * (jnp.outer(a, u) + jnp.outer(u, a) - 2.0 * au * eye))
    hessian = jnp.block([[jnp.zeros((3, 3), h.dtype), h_uw], [h_uw.T, h_ww]])
    return p, jnp.concatenate([jac_u, jac_w], axis=1), hessian


def dead_load_terms(RA, d, P, length, force):
    """Consistent nodal forces of a dead (world-fixed) force per unit length ``force`` (3,)
    (N/m: gravity ``rhoA g`` and world-frame distributed loads; spec S44) and the pieces of
    their left-invariant tangent, in closed form.

    The load is the gradient of the potential ``int_0^L force . p(s) ds`` with
    ``p(s) = p_A + R_A p(xi d)`` (``xi = s/L``, 3-point Gauss-Legendre): with
    ``a = R_A^T force`` and ``phi_k = a . p(xi_k d)`` (:func:`_translation_potential`),
    ``f = P^T s + f_direct``, ``s = L sum_k w_k xi_k grad phi_k`` and
    ``f_direct = L sum_k w_k [a; p_k x a; 0]`` (the rigid motion of node A), the same as
    ``int N^T [R(s)^T force; 0] ds`` of S44. In the chart ``d + P x``, ``a + skew(a) x_thetaA``
    (S37) its tangent is ``(G(s) + P^T S) P + K_direct`` with the stress-like
    ``S = L sum w_k xi_k^2 Hess phi_k`` and ``G`` the geometric term of
    :func:`stress_force_and_tangent`, so ``s, S`` add to the elastic stress and its
    Jacobian. Returns ``(s (6,), S (6,6), f_direct (12,), K_direct (12,12))``;
    ``P = strain_map(d)`` (6,12), ``RA`` (3,3), ``length`` (m).
    """
    a = RA.T @ force
    xi = jnp.asarray(_GAUSS_POINTS)
    weights = jnp.asarray(_GAUSS_WEIGHTS) * length
    p, J, H = jax.vmap(lambda x: _translation_potential(x * d, a))(xi)
    s = jnp.einsum("k,k,kij,i->j", weights, xi, J, a)
    S = jnp.einsum("k,kij->ij", weights * xi * xi, H)
    A = lie.skew(a)
    f_direct = jnp.concatenate([length * a, jnp.cross(weights @ p, a), jnp.zeros(6, d.dtype)])
    weighted_J = jnp.einsum("k,kij->ij", weights * xi, J)          # sum w_k xi_k J_k (3,6)
    K = jnp.zeros((12, 12), d.dtype)
    K = K.at[3:6].add(-A @ weighted_J @ P)                          # d(p_k x a)/dd
    K = K.at[:, 3:6].add(P.T @ weighted_J.T @ A)                    # d s / d a
    K = K.at[0:3, 3:6].add(length * A)                              # d a / d theta_A
    K = K.at[3:6, 3:6].add(lie.skew(weights @ p) @ A)               # p_k x d a
    return s, S, f_direct, K


def follower_distributed_force(d, P, length, local_force):
    """Consistent nodal forces of a follower force per unit length ``local_force`` (3,)
    (N/m in the section frame, turning with it; spec S44):
    ``f = int_0^L N(s, d)^T [local_force; 0] ds`` (3-point Gauss-Legendre), with
    ``N = [Ad_{exp(-xi d)}, 0] + xi T(xi d) P(d)`` (S38, rewritten with S22). Only the force
    rows of ``N`` act, so with ``exp(xi d) = (R_xi, p_xi)``, ``f_a = R_xi local_force``
    (node A's frame) the integrand is
    ``[f_a; p_xi x f_a; 0] + xi P^T [T_SO3(xi d_w)^T q; T_+(xi d)^T q]``, ``q = local_force``.
    ``P = strain_map(d)`` (6,12). Returns (12,). Independent of the node frames themselves.
    """
    def integrand(xi, weight):
        h = xi * d
        R_xi = lie.exp_so3(h[3:])
        T = lie.tangent_so3(h[3:])
        f_a = R_xi @ local_force
        direct = jnp.concatenate([f_a, jnp.cross(T.T @ h[:3], f_a), jnp.zeros(6, d.dtype)])
        through_d = xi * (P.T @ jnp.concatenate(
            [T.T @ local_force, lie.tangent_plus(h[:3], h[3:]).T @ local_force]))
        return (weight * length) * (direct + through_d)

    return jnp.sum(jax.vmap(integrand)(_GAUSS_POINTS, _GAUSS_WEIGHTS), axis=0)


def velocity_field_map(xi, d, P):
    """``N(s, d)`` (6,12) with ``v(s) = N [v_A; v_B]`` at ``xi = s/L`` (paper eqs. 36, 40; S38).

    Written as ``N = [Ad_{exp(-xi d)}, 0] + xi T(xi d) P(d)`` (the same as S38 by S22),
    reusing the element's strain map ``P = strain_map(d)`` (6,12).
    """
    left = lie.adjoint_se3(lie.exp_se3(-xi * d))
    return (jnp.concatenate([left, jnp.zeros_like(left)], axis=1)
            + xi * lie.tangent_se3(xi * d) @ P)


def viscous_force(P, velocities, length, viscosity):
    """Kelvin-Voigt forces ``P^T Upsilon P v_e / L`` (12,) (the paper's eq. 8, spec S40).

    ``velocities`` (12,) are the nodal body velocities ``[v_A; v_B]``; ``viscosity`` the
    diagonal ``mu [3A, A, A, J_t, 3Iy, 3Iz]`` (spec S28).
    """
    strain_rate = P @ velocities / length
    return P.T @ (viscosity * strain_rate)
