"""Gravity on a section whose centre of mass is off the rod's axis (a full section inertia
with an offset, :func:`simsoft_jax.scene.sections.inertia_matrix`): the weight per unit length
``rhoA g`` acts at ``p(s) + R(s) c``, not on the axis.

Its potential is ``-int_0^L rhoA g . (p(s) + R(s) c) ds``; the ``p(s)`` part is the
distributed dead load of :mod:`.distributed` (spec S44), this module adds the ``R(s) c``
part, a distributed moment ``c x R(s)^T (rhoA g)`` (section frame) that turns with the
section. Under the right perturbations of the nodal frames the section at ``xi = s/L``
moves by ``N(xi, d) x`` (the velocity-field map of spec S38,
:func:`simsoft_jax.physics.element.velocity_field_map`), with ``R(s) = R_A exp(xi d_w)``, so the
gradient of the potential, on the residual side, is
``-lam int_0^L N(xi, d)^T [0; c x R(s)^T (rhoA g)] ds`` (12,) (the point-load form of
:mod:`.point_in_element` and :mod:`.offset_loads` integrated along the element). Gauss-
Legendre with ``QUADRATURE`` = 3 points (exact for integrands of degree <= 5 in s, like
the other distributed loads); tangent by ``jax.jacfwd`` on both tangent paths.
"""
from typing import NamedTuple

import jax
import jax.numpy as jnp

from .. import element
from ...math import lie
from ...math.quadrature import gauss_rule
from ..inertia import centre_of_mass, line_density
from . import Term

QUADRATURE = 3


class ElementWeight(NamedTuple):
    """One element's slice: inertia (6,6) the section inertia (rhoA kg/m, centre of mass c
    m), gravity (3,) m/s^2, length () m."""
    inertia: jax.Array
    gravity: jax.Array
    length: jax.Array


def force(el, data: ElementWeight, lam):
    """Nodal forces (12,) ``-lam int N^T [0; c x R(s)^T (rhoA g)] ds`` of one element
    (residual side)."""
    c = centre_of_mass(data.inertia)
    weight = line_density(data.inertia) * data.gravity          # N/m, world frame
    points, weights = gauss_rule(QUADRATURE)
    zero = jnp.zeros(3, el.d.dtype)

    def at(xi, w):
        R = el.RA @ lie.exp_so3(xi * el.d[3:])
        wrench = jnp.concatenate([zero, jnp.cross(c, R.T @ weight)])
        return w * element.velocity_field_map(xi, el.d, el.P).T @ wrench

    return -lam * data.length * jnp.sum(jax.vmap(at)(jnp.asarray(points),
                                                    jnp.asarray(weights)), axis=0)


def per_element(model) -> ElementWeight:
    """Every element's slice (E, ...)."""
    n = model.length.shape[0]
    return ElementWeight(model.inertia, jnp.broadcast_to(model.gravity, (n, 3)), model.length)


def load_scale(model):
    """Sum of squares (N^2) of the weight's moments about the axis, ``L rhoA |c| |g|``
    divided by ``char_length``."""
    rho_a = jax.vmap(line_density)(model.inertia)
    arm = jnp.linalg.norm(jax.vmap(centre_of_mass)(model.inertia), axis=1)
    return jnp.sum((model.length * rho_a * arm / model.char_length) ** 2
                   * jnp.sum(model.gravity ** 2))


TERM = Term("offset_gravity",
            lambda model: model.gravity is not None and model.structure.inertia_offset,
            force, per_element, load_scale)
