"""Whether a time step resolves the contact of the rods with rigid obstacles.

The penalty of :mod:`simsoft_jax.physics.terms.contact` is a spring of stiffness ``k`` (N/m^2)
per unit length under a rod of line density ``rhoA`` (kg/m): an impact lasts half its
period, the contact time ``t_c = pi sqrt(rhoA / k)`` (s). A step much longer than
``t_c`` cannot follow the impact: the rod sinks deep in one step and the stiff penalty
throws it back with more energy than it came with (a rod dropped 0.05 m at dt = 1e-2
on k = 1e9 climbed to 0.5 m). A step is *unresolved* when it is longer than
``t_c / RESOLUTION`` and a contact station (:func:`~simsoft_jax.physics.terms.contact.stations`)
touching an obstacle at its start or end moves along the obstacle's normal, at the
speed it has at either end, by more than half the penalty's smoothing width
``eps`` in the step (an impact or a rebound; a rod resting or sliding on an obstacle
does not move along the normal and is not affected). The station's velocity is
interpolated linearly between the element's two nodes (the rotation's part across the
section is left out). The
dynamics refuse such a step: it is sub-stepped (:func:`~.newton.advance`), and where
the smallest sub-step is still too long the run fails with the cause
``CONTACT_UNRESOLVED``.

With the normal contact damping (``[contact] damping_ratio``, (D1) of
:mod:`simsoft_jax.physics.terms.contact`) a long step is refused only when it throws a
station back: a touching station that ends the step leaving the obstacle (``v_n > 0``)
faster than it moved along the normal at the step's start, by more than the same
``eps / (2 h)``, and whose normal energy per unit length grew over the step,

    rhoA (v_n1^2 - v_n0^2) / 2 + psi(delta_1) - psi(delta_0) > 0                (T1)

(``psi`` the penalty energy, ``rhoA`` the element's line density). The penalty is
conservative and the damping dissipates, so the obstacle alone cannot raise that energy:
a step that does (the rebound of an unresolved, too stiff impact, which sinks a station
far deeper than its loads can press it and throws it back) is sub-stepped as before. A
station released from a deeper penetration than it ends with (a rope pressed into the
floor by its own weight or by a pushed column, springing back as it folds away) turns
penalty energy into speed and the step stands: the implicit step over a damped release it
does not resolve gives back no more than the penalty held. A station that keeps moving
into or along the obstacle is no rebound.
"""
from __future__ import annotations

import jax
import jax.numpy as jnp

from ...physics import element
from ...physics.assembly import contact_data, element_poses
from ...physics.inertia import line_density
from ...model.loads import loads_at
from ...physics.terms import contact

# Steps per contact time a step must take during an impact.
RESOLUTION = 10.0


def contact_time(model) -> jax.Array:
    """The shortest contact time ``pi sqrt(rhoA / k)`` (s) over the rod elements."""
    rho_a = jax.vmap(line_density)(model.inertia)
    return jnp.pi * jnp.sqrt(jnp.min(rho_a / model.contact_stiffness))


def stations(model, state):
    """Penetration (E,S,K) m of every element's S contact stations into the K obstacles
    (placed at the state's time; negative: a gap) and the stations' speeds along the
    obstacles' normals (E,S,K) m/s at the :class:`~.scheme.State` ``state``."""
    data = contact_data(loads_at(model, state.t))
    s = model.structure
    xi = jnp.asarray(contact.station_points(s.contact_points))
    world = jnp.einsum("nij,nj->ni", state.R, state.v[:, :3])     # linear velocities
    a = jnp.asarray(s.element_nodes)

    def one(RA, pA, RB, pB, c, vA, vB):
        d = element.relative_twist(RA, pA, RB, pB)
        pen, _, normals, _, _ = contact.stations(RA, pA, d, c, s.obstacle_kinds,
                                                 s.contact_points)
        v = (1.0 - xi)[:, None] * vA + xi[:, None] * vB            # (S,3)
        return pen, jnp.einsum("ski,si->sk", normals, v)

    return jax.vmap(one)(*element_poses(model, state.R, state.p), data, world[a],
                         world[a + 1])


def thrown(model, pen0, vn0, pen1, vn1, h, eps) -> jax.Array:
    """Whether contact stations (E,S,K) were thrown back by the obstacle in a step of
    ``h`` (s) (module docstring, (T1)): penetrations pen0, pen1 (m) and normal speeds
    vn0, vn1 (m/s, positive leaving) at the step's start and end; ``eps`` (E,1,1) m the
    penalty's smoothing width."""
    rho_a = jax.vmap(line_density)(model.inertia)[:, None, None]
    k = model.contact_stiffness[:, None, None]
    gained = 0.5 * rho_a * (vn1**2 - vn0**2) + (contact.penalty(pen1, k, eps)
                                                 - contact.penalty(pen0, k, eps))
    return ((vn1 - jnp.abs(vn0)) * h > 0.5 * eps) & (gained > 0.0)


def unresolved(model, before, after, h) -> jax.Array:
    """Whether the step of size ``h`` (s) from the state ``before`` to ``after``
    (:class:`~.scheme.State`) is an impact too fast for the step (with contact damping:
    a rebound, module docstring);
    False without obstacles. The stations are evaluated only for a step longer than
    ``t_c / RESOLUTION``."""
    if not model.structure.obstacle_kinds:
        return jnp.array(False)

    def impact():
        (pen0, vn0), (pen1, vn1) = stations(model, before), stations(model, after)
        eps = contact.SMOOTHING * model.contact_radius[:, None, None]
        touching = jnp.maximum(pen0, pen1) > 0.0
        if model.contact_damping is not None:   # only a rebound is refused
            return jnp.any(touching & thrown(model, pen0, vn0, pen1, vn1, h, eps))
        moving = jnp.maximum(jnp.abs(vn0), jnp.abs(vn1)) * h > 0.5 * eps
        return jnp.any(touching & moving)

    # the stations are looked at only when the step is too long for the contact time
    return jax.lax.cond(h * RESOLUTION > contact_time(model), impact, lambda: False)
