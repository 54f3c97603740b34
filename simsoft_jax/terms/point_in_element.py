"""Point loads inside an element (placed by arc length ``s`` between two nodes), consistent
with the helical interpolation (spec S38, S44).

A force/moment at the material point ``xi = (s - s_A)/L`` acts through the velocity-field
map ``N(xi, d)`` of S38 (``v(xi) = N [v_A; v_B]``, :func:`element.velocity_field_map`):
its nodal load is ``N^T w`` with ``w`` the load as a wrench in the section frame there,
``R(xi) = R_A exp(xi d_w)``: ``w = [R(xi)^T F; R(xi)^T M]`` for a dead (world-frame) load,
``w`` as given for a follower (section-frame) load. This is the point-load limit of the
distributed-load integral of S44.
"""
import jax.numpy as jnp

from .. import element, lie


def force(el, data, lam, with_dead: bool, with_follower: bool):
    """Nodal forces (12,) ``-lam N(xi, d)^T w`` of the element's point load (residual side):
    ``data.point_dead`` (6,) world force and moment, ``data.point_follower`` (6,) section
    force and moment, both at ``data.point_xi``."""
    xi = data.point_xi
    w = jnp.zeros(6, el.d.dtype)
    if with_dead:
        R = el.RA @ lie.exp_so3(xi * el.d[3:])
        w = w + jnp.concatenate([R.T @ data.point_dead[:3], R.T @ data.point_dead[3:]])
    if with_follower:
        w = w + data.point_follower
    return -lam * element.velocity_field_map(xi, el.d, el.P).T @ w
