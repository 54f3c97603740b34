"""Quasi-static friction with rigid obstacles: regularized Coulomb on the slip of each
contact station since the previous converged load level (load stepping).

A static solve with friction walks the loads up in levels ``lam_0 = 0 < lam_1 < ... <
lam_m = 1`` (:mod:`simsoft_jax.solvers.statics`); between two levels a contact station, the
centreline point ``x(xi)`` at a Gauss point ``xi`` of an element
(:func:`simsoft_jax.physics.terms.contact.stations`), moves by the slip ``u = x(xi) - x_prev(xi)``
(m, world), ``x_prev`` the same material point at the previous converged level. Its part
tangent to the obstacle ``u_t = u - (u . n) n`` (``n`` the unit normal at the current
state) meets the line load (N/m, world)

    f_t = -mu f_n u_t / sqrt(|u_t|^2 + u_s^2)                                     (F1)

with ``f_n = psi'(delta)`` the normal line load of the penalty (:mod:`.contact`), ``mu``
the obstacle's Coulomb coefficient and ``u_s`` the slip-displacement scale (m, ``[contact]
slip_displacement``, default :data:`simsoft_jax.scene.scene_contact.SLIP_FRACTION` = 1e-3
times the contact radius). This is the
backward-Euler step in the load parameter of the rate law that :mod:`.contact` uses in
dynamics, with the slip per level in place of the slip velocity. Sticking and sliding
are not switched: where ``|u_t| << u_s`` (F1) is a tangential spring of stiffness
``mu f_n / u_s`` (N/m^2; sticking, the station moves a fraction of ``u_s``), where
``|u_t| >> u_s`` it is Coulomb's ``mu f_n`` against the slip (sliding, relative error
``u_s^2 / (2 |u_t|^2)``). The law forgets the friction of earlier levels: a station
holding a tangential line load ``t mu f_n`` (``t < 1``) while the loads are held creeps
by ``u_s t / sqrt(1 - t^2)`` per level (the same creep as the rate law's at slip
velocities below ``v_s``), so ``u_s`` should be small against the slips of interest.

Nodal forces, as for the normal contact: ``sum_i c_i N_i^T [R_i^T (-f_t); 0]`` (residual
side, ``c_i`` the stations' weights of :func:`simsoft_jax.physics.terms.contact.station_weights`), ``N_i`` the velocity-field map at ``xi_i`` (spec S38), ``R_i`` the section's
rotation; the tangent by ``jax.jacfwd`` (:func:`simsoft_jax.physics.assembly.static_friction_and_tangent`)
in the current frames with the previous stations fixed. (F1) is not the gradient of a
potential: the tangent is not symmetric.
"""
from __future__ import annotations

import jax
import jax.numpy as jnp

from .. import element
from . import contact


def stations(RA, pA, d, n: int):
    """Positions (n+2,3) (m, world) of the contact stations of an element with the frame
    ``(RA, pA)`` of node A and relative twist ``d`` (6,) (its ``n`` Gauss points and two
    nodes, :func:`simsoft_jax.physics.terms.contact.station_points`)."""
    xi = contact.station_points(n)
    return jax.vmap(lambda t: contact.centreline_point(RA, pA, d, t)[1])(jnp.asarray(xi))


def line_load(load, normals, slip, scale, mu):
    """The friction line loads (n,3) N/m of (F1) at n stations: ``load`` (n,K) the normal
    line loads, ``normals`` (n,K,3) the unit normals, ``slip`` (n,3) the slips (m, world),
    ``scale`` () the slip scale ``u_s`` (m), ``mu`` (K,) the Coulomb coefficients."""
    along = jnp.einsum("nki,ni->nk", normals, slip)
    tangential = slip[:, None, :] - along[..., None] * normals              # (n,K,3)
    size = jnp.sqrt(jnp.sum(tangential**2, -1) + scale**2)
    return -jnp.einsum("nk,nki->ni", mu * load / size, tangential)


def force(el, previous, scale, data: contact.ContactData, length, kinds: tuple, n: int):
    """Nodal forces (12,) (residual side) of the friction (F1) of one element (``el`` an
    :class:`~simsoft_jax.physics.terms.Element` with ``el.pA``) against the obstacles ``kinds``:
    ``previous`` (n+2,3) the element's stations at the previous load level (m, world),
    ``scale`` () the slip scale ``u_s`` (m), ``length`` the reference length (m), ``n``
    the Gauss points per element (the stations' weights: the contact's, end caps
    included)."""
    xi = contact.station_points(n)
    _, load, normals, R, x = contact.stations(el.RA, el.pA, el.d, data, kinds, n)
    f = line_load(load, normals, x - previous, scale, data.friction)
    maps = jax.vmap(lambda t: element.velocity_field_map(t, el.d, el.P))(jnp.asarray(xi))
    local = jnp.einsum("nji,nj->ni", R, f)                                  # R^T f
    wrench = jnp.concatenate([local, jnp.zeros_like(local)], axis=1)
    weights = contact.station_weights(length, data.caps, n)
    return -jnp.einsum("n,nji,nj->i", weights, maps, wrench)
