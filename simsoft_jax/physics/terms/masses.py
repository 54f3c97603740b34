"""A rigid mass attached to a node: its weight (a dead force at its centre of mass, which
is offset from the node and turns with the section) and, in dynamics, its inertia with
the offset's gyroscopic terms.

The mass ``m`` (kg) has its centre at ``c`` (3,) (m, section frame) and the inertia
tensor ``J_c`` (3,3) (kg m^2, section frame, about the centre). With the node's body
velocity ``V = [v; w]`` (section frame, spec S31), the centre moves with
``v + w x c``; its momentum about the node is ``h = M6 V`` with the spatial inertia
``M6 = [[m I, -m C], [m C, J_c - m C C]]`` (``C = skew(c)``; kinetic energy
``V^T M6 V / 2``; :func:`simsoft_jax.math.lie.spatial_inertia`). The Newton-Euler equations
in the moving section frame (rate of momentum plus its transport, e.g. Murray, Li &
Sastry 1994, ch. 4) give the inertial force
``M6 Vdot + [w x h_lin; w x h_ang + v x h_lin]``; the weight enters as
:func:`simsoft_jax.physics.terms.offset_loads.force` of ``m g``. Residual side, (6,) per mass.
"""
import jax.numpy as jnp

from ...math import lie
from . import offset_loads


def inertial_force(V, Vdot, mass, offset, inertia):
    """``M6 Vdot + gyroscopic force`` (6,) of the mass at its node's body velocity ``V``
    (6,) and acceleration ``Vdot`` (6,)."""
    M6 = lie.spatial_inertia(mass, offset, inertia)
    h = M6 @ V
    v, w = V[:3], V[3:]
    gyro = jnp.concatenate([jnp.cross(w, h[:3]), jnp.cross(w, h[3:]) + jnp.cross(v, h[:3])])
    return M6 @ Vdot + gyro


def force(R, V, Vdot, mass, offset, inertia, gravity, lam, with_gravity: bool,
          dynamic: bool):
    """Residual (6,) of one mass at a node with rotation ``R`` (3,3): its weight
    ``-lam [R^T m g; c x R^T m g]`` when ``with_gravity`` (``gravity`` (3,) m/s^2), plus
    :func:`inertial_force` when ``dynamic``."""
    r = jnp.zeros(6, R.dtype)
    if with_gravity:
        r = r + offset_loads.force(R, mass * gravity, offset, lam)
    if dynamic:
        r = r + inertial_force(V, Vdot, mass, offset, inertia)
    return r
