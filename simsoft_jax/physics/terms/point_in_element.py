"""Point loads inside an element (placed by arc length ``s`` between two nodes), consistent
with the helical interpolation (spec S38, S44).

A force/moment at the material point ``xi = (s - s_A)/L`` acts through the velocity-field
map ``N(xi, d)`` of S38 (``v(xi) = N [v_A; v_B]``, :func:`element.velocity_field_map`):
its nodal load is ``N^T w`` with ``w`` the load as a wrench in the section frame there,
``R(xi) = R_A exp(xi d_w)``: ``w = [R(xi)^T F; R(xi)^T M]`` for a dead (world-frame) load,
``w`` as given for a follower (section-frame) load. This is the point-load limit of the
distributed-load integral of S44.
"""
from typing import NamedTuple

import jax
import jax.numpy as jnp

from .. import element
from ...math import lie
from . import Term


class ElementPointLoad(NamedTuple):
    """One element's slice: dead (6,) world force and moment, follower (6,) section force
    and moment (each None when the scene has no such load), xi () where they act."""
    dead: jax.Array
    follower: jax.Array
    xi: jax.Array


def force(el, part: ElementPointLoad, lam):
    """Nodal forces (12,) ``-lam N(xi, d)^T w`` of the element's point load (residual side)."""
    xi = part.xi
    w = jnp.zeros(6, el.d.dtype)
    if part.dead is not None:
        R = el.RA @ lie.exp_so3(xi * el.d[3:])
        w = w + jnp.concatenate([R.T @ part.dead[:3], R.T @ part.dead[3:]])
    if part.follower is not None:
        w = w + part.follower
    return -lam * element.velocity_field_map(xi, el.d, el.P).T @ w


def per_element(model) -> ElementPointLoad:
    """Every element's slice (E, ...): the kinds of point load the model has (None for
    the others)."""
    return ElementPointLoad(model.element_point_dead, model.element_point_follower,
                            model.element_point_xi)


def load_scale(model):
    """Sum of squares (N^2) of the point forces and moments (divided by ``char_length``)."""
    point = sum(jnp.abs(a) for a in (model.element_point_dead, model.element_point_follower)
                if a is not None)
    return jnp.sum(point[:, :3] ** 2) + jnp.sum((point[:, 3:] / model.char_length) ** 2)


TERM = Term("point_loads",
            lambda model: (model.element_point_dead is not None
                           or model.element_point_follower is not None),
            force, per_element, load_scale)
