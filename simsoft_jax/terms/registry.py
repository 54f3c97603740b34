"""The term registry: each physical term declared once, read by every solver the same way.

A registered term owns one part of the :class:`~simsoft_jax.model.Model` (the field named
``Term.name``, ``None`` when the scene lacks the term, so the term's presence is the
pytree itself and nothing of it is traced otherwise) and declares, in one
:class:`Term`:

- ``force(el, part_e, lam)``: its nodal forces (12,) on the residual side for one element
  (:class:`~simsoft_jax.terms.Element`, the element's slice of the part), the loads scaled
  by the load level ``lam`` (1 in dynamics);
- ``per_element(model, part)``: that slice for all elements (a pytree of (E, ...) arrays);
- ``load_scale(model, part)``: the sum of squares (N^2, moments divided by the model's
  ``char_length``) of its full loads, its share of the tolerance's reference
  (:func:`simsoft_jax.statics.newton.load_scale`);
- ``at_time(part, t)`` (optional): the part at time ``t`` (its time law), as
  :func:`simsoft_jax.loads.loads_at` gives the other loads;
- ``added_inertia(model, part)`` (optional): section inertia (E,6) added to the model's
  in dynamics (e.g. a fluid's added mass).

Tangents need no declaration: the assembler (:mod:`simsoft_jax.assembly`,
:mod:`simsoft_jax.dynamics.residual`) differentiates ``force`` with ``jax.jacfwd`` in the
12 right perturbations of the two nodal frames and, in dynamics, the 12 nodal velocities,
on both tangent paths. Adding a term = its module, one line in :data:`TERMS`, its scene
keys and its model builder.
"""
from __future__ import annotations

from typing import Callable, NamedTuple

import jax.numpy as jnp

from . import fluid, magnetic


class Term(NamedTuple):
    """One registered term (see the module docstring)."""
    name: str
    force: Callable
    per_element: Callable
    load_scale: Callable
    at_time: Callable | None = None
    added_inertia: Callable | None = None


TERMS = (
    Term("magnetic", magnetic.force, magnetic.per_element, magnetic.load_scale,
         at_time=magnetic.at_time),
    Term("fluid", fluid.force, fluid.per_element, fluid.load_scale,
         added_inertia=fluid.added_inertia),
)
_BY_NAME = {term.name: term for term in TERMS}


def active(model) -> tuple:
    """The registered terms whose part ``model`` holds (static: decided by the pytree)."""
    return tuple(term for term in TERMS if getattr(model, term.name, None) is not None)


def element_parts(model) -> dict | None:
    """``{name: per-element slice}`` of the active terms (the ``parts`` of
    :class:`~simsoft_jax.terms.ElementData`), None when there are none."""
    terms = active(model)
    if not terms:
        return None
    return {t.name: t.per_element(model, getattr(model, t.name)) for t in terms}


def forces(el, parts: dict | None, lam):
    """Sum (12,) of the forces of the active terms on one element (``parts``: that
    element's slice of :func:`element_parts`), or None without any."""
    if not parts:
        return None
    total = jnp.zeros(12, el.d.dtype)
    for name, part in parts.items():
        total = total + _BY_NAME[name].force(el, part, lam)
    return total


def load_scale_squared(model):
    """Sum of the active terms' :attr:`Term.load_scale` (N^2); 0.0 without any."""
    return sum((t.load_scale(model, getattr(model, t.name)) for t in active(model)), 0.0)


def at_time(model, t) -> dict:
    """``{name: part at time t}`` for the active terms with a time law."""
    return {term.name: term.at_time(getattr(model, term.name), t)
            for term in active(model) if term.at_time is not None}


def section_inertia(model):
    """``model.inertia`` (E,6) or (E,6,6) plus the inertia the active terms add
    (:attr:`Term.added_inertia`, diagonals (E,6)); the model's own array when none do."""
    inertia = model.inertia
    for term in active(model):
        if term.added_inertia is None:
            continue
        extra = term.added_inertia(model, getattr(model, term.name))
        inertia = (inertia + jnp.einsum("ei,ij->eij", extra, jnp.eye(6, dtype=extra.dtype))
                   if inertia.ndim == 3 else inertia + extra)
    return inertia
