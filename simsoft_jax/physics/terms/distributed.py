"""Distributed loads on an element, consistent with the helical interpolation (spec S44):
dead loads (world-fixed: gravity ``rhoA g`` and world-frame distributed forces) and
follower loads (turning with the section)."""
import jax.numpy as jnp

from .. import element
from ..inertia import line_density


def dead_force(el, data, lam):
    """Nodal forces (12,) of ``-lam (q_world + rhoA g)`` per unit length (N/m), on the
    residual side, integrated along the deformed element (:func:`element.dead_load_terms`);
    ``data.q_world``, ``data.gravity`` None when the model lacks them."""
    q = jnp.zeros(3, el.d.dtype)
    if data.q_world is not None:
        q = q + data.q_world
    if data.gravity is not None:
        q = q + line_density(data.inertia) * data.gravity
    stress, _, direct, _ = element.dead_load_terms(el.RA, el.d, el.P, data.length, -lam * q)
    return el.P.T @ stress + direct


def follower_force(el, data, lam):
    """Nodal forces (12,) of ``-lam q_local`` per unit length (N/m, section frame)."""
    return -lam * element.follower_distributed_force(el.d, el.P, data.length, data.q_local)
