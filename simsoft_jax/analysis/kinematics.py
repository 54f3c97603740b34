"""Rod shape between nodes, element deformations and the helix geometry of each element.

* forward kinematics inside an element (the paper's eq. 27, spec S32):
  ``H(s) = H_A exp((s/L) d)`` with ``d = log(H_A^-1 H_B)``;
* inverse kinematics (the paper's eq. 28, spec S33): ``d`` from the two nodal frames;
* curvature and torsion of each element's helix (the paper's eqs. 68-73, spec S50):
  ``kappa = |d_w x d_u| / |d_u|^2``, ``tau = (d_w . d_u) / |d_u|^2``.
Shapes: R (N,3,3), p (N,3) nodal frames of a rod (or of a whole model).
"""
from __future__ import annotations

import jax
import jax.numpy as jnp

from ..physics import element
from ..math import lie


def element_twists(R, p):
    """Inverse kinematics: deformation ``d_e = log(H_e^-1 H_e+1)`` of consecutive frames, (N-1, 6)."""
    return jax.vmap(element.relative_twist)(R[:-1], p[:-1], R[1:], p[1:])


def frame_in_element(RA, pA, d, fraction):
    """Forward kinematics: frame at ``s = fraction * L`` of an element, ``(R (3,3), p (3,))``."""
    return lie.compose_exp(RA, pA, fraction * d)


def sample_shape(R, p, points_per_element: int = 8):
    """Centreline and frames of a chain sampled ``points_per_element`` times per element.

    Returns ``(R_s, p_s)`` with shapes ``(M, 3, 3)`` and ``(M, 3)``,
    ``M = (N - 1) * points_per_element + 1``, following the helical interpolation exactly.
    """
    d = element_twists(R, p)
    fractions = jnp.arange(points_per_element) / points_per_element
    inner = jax.vmap(lambda RA, pA, de: jax.vmap(
        lambda f: frame_in_element(RA, pA, de, f))(fractions))
    R_s, p_s = inner(R[:-1], p[:-1], d)
    R_s = jnp.concatenate([R_s.reshape(-1, 3, 3), R[-1:]])
    p_s = jnp.concatenate([p_s.reshape(-1, 3), p[-1:]])
    return R_s, p_s


def curvature_torsion(d):
    """Curvature (1/m) and torsion (1/m) of the helix of an element with deformation ``d`` (6,).

    Spec S50 (the paper's eqs. 68-73 generalized to ``|d_u| != L``); for the total (Darboux)
    curvature ``sqrt(kappa^2 + tau^2) = |d_w| / |d_u|``.
    """
    du, dw = d[:3], d[3:]
    n2 = jnp.dot(du, du)
    c2 = jnp.sum(jnp.cross(dw, du) ** 2)
    norm_c = jnp.where(c2 > 0, jnp.sqrt(jnp.where(c2 > 0, c2, 1.0)), 0.0)  # safe at 0
    return norm_c / n2, jnp.dot(dw, du) / n2


def rod_slice(model, rod: str) -> slice:
    """Node slice of ``rod`` in a model's arrays."""
    info = model.structure.rod(rod)
    return slice(info.first_node, info.first_node + info.nodes)
