"""Residual terms: one small module per physical term, each a pure function giving its
contribution to the residual from the local state (an element's two nodal frames and
velocities, or one node), written for one instance and vmapped by the assembly.

Element terms take an :class:`Element` (local state) and :class:`ElementData` (the
element's model arrays) and return nodal forces (12,) ``[node A (6); node B (6)]`` in
the nodal frames, on the residual side (``r = f_int + f_inertia - f_ext``). Node terms
take a node's rotation (3,3) and its load rows and return (6,).

Tangents: :mod:`.autodiff` differentiates the sum of the active terms with ``jax.jacfwd``
in the 12 right perturbations of the two nodal frames (and in the nodal velocities and
accelerations in dynamics): the exact left-invariant tangent for any term. Terms with a
closed-form tangent (elastic, viscous, dead and nodal loads; spec S42-S44) also feed the
faster closed-form path of :mod:`simsoft_jax.assembly`; tests check both paths agree.
Which terms are active is decided from the model's static structure: terms a scene does
not have are not traced.
"""
from __future__ import annotations

from typing import NamedTuple

import jax

from .. import element as _element


class Element(NamedTuple):
    """Local state of one element: RA (3,3) rotation of node A, d (6,) relative twist
    ``log(H_A^-1 H_B)``, P (6,12) strain map ``P(d)``, ve, vde (12,) nodal body
    velocities and accelerations ``[node A; node B]`` (zeros in statics), pA (3,) position
    of node A (m; read by :mod:`.contact`)."""
    RA: jax.Array
    d: jax.Array
    P: jax.Array
    ve: jax.Array
    vde: jax.Array
    pA: jax.Array = None


class ElementData(NamedTuple):
    """An element's model arrays: d0 (6,), length (m), stiffness, inertia (6,) diagonals or
    (6,6) matrices (:mod:`simsoft_jax.sections`), viscosity (6,) diagonal, q_world,
    q_local (3,) distributed loads (N/m), gravity (3,) (m/s^2), maps (G,6,12) and mass
    (12,12) (dynamics; see :mod:`simsoft_jax.inertia`), point_dead, point_follower (6,) a
    point load inside the element at point_xi ()
    (:mod:`.point_in_element`), mass_damping () mass-proportional damping constant (1/s,
    :mod:`.mass_damping`; None in statics), tendon_tension (M,) N (zero for tendons that
    do not pass the element), tendon_offset, tendon_slope (M,Q,2) (:mod:`.tendons`),
    chamber_force (C,) pressure times area (N), chamber_offset (C,2) (:mod:`.chambers`);
    None when the scene has no tendons / chambers; contact: :class:`.contact.ContactData`
    (None in scenes without obstacles); parts: ``{name: slice}`` of the registered terms
    the model has (:func:`.registry.element_parts`; None without any)."""
    d0: jax.Array
    length: jax.Array
    stiffness: jax.Array
    inertia: jax.Array
    viscosity: jax.Array
    q_world: jax.Array
    q_local: jax.Array
    gravity: jax.Array
    maps: jax.Array
    mass: jax.Array
    point_dead: jax.Array
    point_follower: jax.Array
    point_xi: jax.Array
    mass_damping: jax.Array = None
    tendon_tension: jax.Array = None
    tendon_offset: jax.Array = None
    tendon_slope: jax.Array = None
    chamber_force: jax.Array = None
    chamber_offset: jax.Array = None
    contact: tuple = None
    parts: dict = None


def element_state(RA, pA, RB, pB, ve, vde) -> Element:
    """:class:`Element` from the two nodal frames and the nodal velocities/accelerations."""
    d = _element.relative_twist(RA, pA, RB, pB)
    return Element(RA, d, _element.strain_map(d), ve, vde, pA)
