"""Element inertia for dynamics (spec algorithm.md section 3.5).

Both options use the velocity field of the reference shape, ``v(s) = N0(s) v_e`` with
``N0(s) = N(s, d0)`` (spec S38 at the stress-free twist), integrated by a quadrature rule:

* ``"consistent"`` (I2, frozen consistent): 4-point Gauss-Legendre. Exact for straight
  elements (the integrands are polynomials of degree <= 6 in s) and O(L^8)-accurate for
  curved ones. Keeps the Hermite-like coupling of the exact field.
* ``"lumped"`` (I4): the trapezoid rule at the two nodes, ``N0(0) = [I, 0]``,
  ``N0(L) = [0, I]``: ``M_i = sum (L/2) M`` and nodal gyroscopic forces.

Mass matrix ``M_e = sum_g w_g L N0_g^T M N0_g`` (12,12), constant. Gyroscopic forces:
lumped, ``-ad_{v_i}^T M_i v_i`` per node (S46); consistent, the Euler-Poincare term of the
discrete kinetic energy ``1/2 v_e^T M_e v_e``, ``-ad_{v_i}^T (M_e v_e)_i`` per node, which
conserves energy and the momentum map of the semi-discrete system (the frozen-field form
``-int N0^T ad_u^T M u`` of spec I2 lets momentum drift by O(strain) on soft rods). Both
are exact for rigid motion of a straight element; neither depends on the configuration,
so inertia adds ``M beta'`` and ``C_gyr gamma'`` to the iteration matrix only.

The section inertia ``M`` is the diagonal (6,) ``[rhoA, rhoA, rhoA, rhoJ, rhoIy, rhoIz]`` or
the full (6,6) spatial inertia per length about the rod's axis with an offset centre of
mass (:func:`simsoft_jax.scene.sections.inertia_matrix`); all of the above holds for either.
"""
from __future__ import annotations

from functools import partial

import jax
import jax.numpy as jnp
import numpy as np

from . import element
from ..math import lie

_GAUSS4_X, _GAUSS4_W = np.polynomial.legendre.leggauss(4)
RULES = {
    "consistent": (0.5 * (_GAUSS4_X + 1.0), 0.5 * _GAUSS4_W),
    "lumped": (np.array([0.0, 1.0]), np.array([0.5, 0.5])),
}


def field_maps(d0, kind: str):
    """``N0`` at the quadrature points of rule ``kind`` for one element: (G, 6, 12)."""
    points, _ = RULES[kind]
    P = element.strain_map(d0)
    # vmapped over the points (a Python loop would trace the map once per point)
    return jax.vmap(lambda x: element.velocity_field_map(x, d0, P))(jnp.asarray(points))


def line_density(inertia):
    """``rhoA`` (kg/m) of a section inertia: the diagonal (6,) or the matrix (6,6)."""
    return inertia[0, 0] if inertia.ndim == 2 else inertia[0]


def centre_of_mass(inertia):
    """Centre of mass ``c`` (3,) (m, section frame) of a section inertia (6,6)
    ``[[rhoA I, -rhoA C], [rhoA C, ...]]``, ``C = skew(c)``: ``vee(M[3:6, 0:3]) / rhoA``
    (:func:`simsoft_jax.scene.sections.inertia_matrix`)."""
    return lie.vee_so3(inertia[3:, :3]) / inertia[0, 0]


def section_momentum(inertia, u):
    """``M u`` (..., 6) of section velocities ``u`` (..., 6) for the diagonal (6,) or the
    full (6,6) section inertia (which one is static: the array's shape)."""
    return u @ inertia.T if inertia.ndim == 2 else inertia * u


def mass_matrix(maps, length, inertia, kind: str):
    """Constant element mass matrix (12,12) ``sum_g w_g L N0_g^T M N0_g`` from the field
    maps (spec I2 / I4); ``inertia`` the diagonal (6,) or the full (6,6) section inertia
    (kg/m, kg, kg m by block; a diagonal traces exactly the diagonal product)."""
    weights = jnp.asarray(RULES[kind][1]) * length
    if inertia.ndim == 2:
        return jnp.einsum("g,gai,ab,gbj->ij", weights, maps, inertia, maps)
    return jnp.einsum("g,gai,a,gaj->ij", weights, maps, inertia, maps)


def gyroscopic_force(maps, length, inertia, velocities, kind: str, mass=None):
    """Gyroscopic element force (12,).

    ``"lumped"``: ``-sum w L N0^T ad_u^T M u`` at the two nodes (spec I4, S46).
    ``"consistent"``: the Euler-Poincare term of the discrete kinetic energy
    ``1/2 v_e^T M_e v_e`` on SE(3) x SE(3): ``[-ad_{v_A}^T (M_e v_e)_A; -ad_{v_B}^T (M_e v_e)_B]``
    (needs ``mass = M_e``). Assembled, it gives ``-ad_{v_i}^T (M v)_i`` per node, which keeps
    the energy and the momentum map of the discrete system (the frozen-field form
    ``-int N0^T ad_u^T M u`` of spec I2 does not: its momentum drifts by O(strain)).
    """
    if kind == "consistent":
        mv = (mass @ velocities).reshape(2, 6)
        v = velocities.reshape(2, 6)
        lin = jnp.cross(mv[:, :3], v[:, 3:])
        ang = jnp.cross(mv[:, :3], v[:, :3]) + jnp.cross(mv[:, 3:], v[:, 3:])
        return -jnp.concatenate([lin, ang], axis=1).reshape(12)
    weights = jnp.asarray(RULES[kind][1]) * length
    u = maps @ velocities                      # (G, 6) section velocities
    mu = section_momentum(inertia, u)
    g = -jnp.concatenate([jnp.cross(mu[:, :3], u[:, 3:]),
                          jnp.cross(mu[:, :3], u[:, :3]) + jnp.cross(mu[:, 3:], u[:, 3:])],
                         axis=1)
    return jnp.einsum("g,gai,ga->i", weights, maps, g)


@partial(jax.jit, static_argnames="kind")
def element_inertia(d0, length, inertia, kind: str):
    """Field maps (E, G, 6, 12) and mass matrices (E, 12, 12) of all elements (vmapped,
    compiled once per mesh size: evaluated eagerly it dispatched ~90 small kernels)."""
    maps = jax.vmap(lambda d: field_maps(d, kind))(d0)
    masses = jax.vmap(lambda N, L, m: mass_matrix(N, L, m, kind))(maps, length, inertia)
    return maps, masses
