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
closed-form tangent (elastic, viscous, inertial, dead and nodal loads; spec S42-S44) also
feed the faster closed-form path of :mod:`simsoft_jax.physics.assembly`; tests check both paths
agree. The other element terms declare themselves once (:class:`Term`) and are collected
in :mod:`.registry`. Which terms are active is decided from the model's static structure
(or its pytree): terms a scene does not have are not traced.
"""
from __future__ import annotations

from typing import Callable, NamedTuple

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
    (6,6) matrices (:mod:`simsoft_jax.scene.sections`), viscosity (6,) diagonal, q_world,
    q_local (3,) distributed loads (N/m), gravity (3,) (m/s^2), maps (G,6,12) and mass
    (12,12) (dynamics, None in statics; see :mod:`simsoft_jax.physics.inertia`), mass_damping ()
    mass-proportional damping constant (1/s, :mod:`.mass_damping`); viscosity, q_world,
    q_local, gravity and mass_damping are None when the model lacks them
    (:mod:`simsoft_jax.model.parts`: their terms are not traced); contact:
    :class:`.contact.ContactData` (None in scenes without obstacles); parts: ``{name:
    slice}`` of the registered terms the model has (:func:`.registry.element_parts`;
    None without any)."""
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
    mass_damping: jax.Array = None
    contact: tuple = None
    parts: dict = None


def element_state(RA, pA, RB, pB, ve, vde) -> Element:
    """:class:`Element` from the two nodal frames and the nodal velocities/accelerations."""
    d = _element.relative_twist(RA, pA, RB, pB)
    return Element(RA, d, _element.strain_map(d), ve, vde, pA)


class Term(NamedTuple):
    """One element term declared once (collected in :mod:`.registry`):

    - ``name``: its key in :attr:`ElementData.parts`;
    - ``present(model) -> bool``: whether the model has it (static: the structure or the
      pytree decides; nothing of an absent term is traced);
    - ``force(el, part, lam) -> (12,)``: its nodal forces on the residual side for one
      element (:class:`Element`, the element's slice of its data), loads scaled by the load
      level ``lam`` (1 in dynamics);
    - ``per_element(model)``: that slice for all elements (a pytree of (E, ...) arrays);
    - ``load_scale(model)``: the sum of squares (N^2, moments divided by the model's
      ``char_length``) of its full loads, its share of the tolerance's reference;
    - ``at_time(model, t) -> dict`` (optional): the Model fields its time law changes at
      time ``t`` (:func:`simsoft_jax.model.loads.loads_at`);
    - ``added_inertia(model) -> (E,6)`` (optional): section inertia it adds in dynamics;
    - ``velocity``: whether ``force`` reads the nodal velocities (then its tangent is also
      taken in them).
    """
    name: str
    present: Callable
    force: Callable
    per_element: Callable
    load_scale: Callable
    at_time: Callable = None
    added_inertia: Callable = None
    velocity: bool = False

