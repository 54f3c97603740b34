"""Element inertia for dynamics (spec algorithm.md section 3.5).

Both options use the velocity field of the reference shape, ``v(s) = N0(s) v_e`` with
``N0(s) = N(s, d0)`` (spec S38 at the stress-free twist), integrated by a quadrature rule:

* ``"consistent"`` (I2, frozen consistent): 4-point Gauss-Legendre. Exact for straight
  elements (the integrands are polynomials of degree <= 6 in s) and O(L^8)-accurate for
  curved ones. Keeps the Hermite-like coupling of the exact field.
* ``"lumped"`` (I4): the trapezoid rule at the two nodes, ``N0(0) = [I, 0]``,
  ``N0(L) = [0, I]``: ``M_i = sum (L/2) M`` and nodal gyroscopic forces.

Mass matrix ``M_e = sum_g w_g L N0_g^T M N0_g`` (12,12), constant; gyroscopic force
``g_e(v_e) = -sum_g w_g L N0_g^T ad_{u_g}^T M u_g``, ``u_g = N0_g v_e`` (spec I2, S46).
Both are exact for rigid motion of a straight element; neither depends on the
configuration, so inertia adds ``M beta'`` and ``C_gyr gamma'`` to the iteration matrix only.
"""
from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from . import element

_GAUSS4_X, _GAUSS4_W = np.polynomial.legendre.leggauss(4)
RULES = {
    "consistent": (0.5 * (_GAUSS4_X + 1.0), 0.5 * _GAUSS4_W),
    "lumped": (np.array([0.0, 1.0]), np.array([0.5, 0.5])),
}


def field_maps(d0, kind: str):
    """``N0`` at the quadrature points of rule ``kind`` for one element: (G, 6, 12)."""
    points, _ = RULES[kind]
    P = element.strain_map(d0)
    return jnp.stack([element.velocity_field_map(float(x), d0, P) for x in points])


def mass_matrix(maps, length, inertia, kind: str):
    """Constant element mass matrix (12,12) from the field maps (spec I2 / I4)."""
    weights = jnp.asarray(RULES[kind][1]) * length
    return jnp.einsum("g,gai,a,gaj->ij", weights, maps, inertia, maps)


def gyroscopic_force(maps, length, inertia, velocities, kind: str):
    """Gyroscopic element force (12,) ``-sum w L N0^T ad_u^T M u`` (spec S46 per point).

    For diagonal ``M``: ``-ad_u^T M u = [m w x v; w x (J w)]`` (spec S46)."""
    weights = jnp.asarray(RULES[kind][1]) * length
    u = maps @ velocities                      # (G, 6) section velocities
    mu = inertia * u
    g = -jnp.concatenate([jnp.cross(mu[:, :3], u[:, 3:]),
                          jnp.cross(mu[:, :3], u[:, :3]) + jnp.cross(mu[:, 3:], u[:, 3:])],
                         axis=1)
    return jnp.einsum("g,gai,ga->i", weights, maps, g)


def element_inertia(d0, length, inertia, kind: str):
    """Field maps (E, G, 6, 12) and mass matrices (E, 12, 12) of all elements (vmapped)."""
    maps = jax.vmap(lambda d: field_maps(d, kind))(d0)
    masses = jax.vmap(lambda N, L, m: mass_matrix(N, L, m, kind))(maps, length, inertia)
    return maps, masses
