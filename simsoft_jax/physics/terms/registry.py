"""The term registry: the element terms declared once (:class:`~simsoft_jax.physics.terms.Term`),
read by every solver the same way.

Each term module declares its ``TERM``: when it is present, its per-instance force, the
per-element data it reads, its share of the tolerance's load scale and, optionally, its
time law and the section inertia it adds. The assembler (:mod:`simsoft_jax.physics.assembly`)
sums the present terms into the residual (:func:`forces`) and differentiates them with
``jax.jacfwd`` in the 12 right perturbations of the two nodal frames (and, for terms that
read them, the 12 nodal velocities) on both tangent paths, in statics and dynamics;
:func:`simsoft_jax.solvers.statics.newton.load_scale`, :func:`simsoft_jax.model.loads.loads_at` and the
dynamic section inertia read the other declarations. Adding a term = its module, one line
in :data:`TERMS`, its scene keys and its model builder.

The elastic, viscous, inertial and distributed-load terms, which have closed-form
tangents, and contact (its own broad phase and friction state) are assembled by
:mod:`simsoft_jax.physics.assembly` directly.
"""
from __future__ import annotations

import jax.numpy as jnp

from . import chambers, fluid, magnetic, offset_gravity, point_in_element, tendons

TERMS = (point_in_element.TERM, offset_gravity.TERM, tendons.TERM, chambers.TERM,
         magnetic.TERM, fluid.TERM)
_BY_NAME = {term.name: term for term in TERMS}


def active(model) -> tuple:
    """The registered terms ``model`` has (static)."""
    return tuple(term for term in TERMS if term.present(model))


def element_parts(model, velocity: bool | None = None) -> dict | None:
    """``{name: per-element slice}`` of the active terms (all, or only those whose
    ``velocity`` flag equals ``velocity``), None when there are none."""
    terms = [t for t in active(model) if velocity is None or t.velocity == velocity]
    return {t.name: t.per_element(model) for t in terms} or None


def forces(el, parts: dict | None, lam):
    """Sum (12,) of the forces of the terms in ``parts`` (one element's slices of
    :func:`element_parts`) on one element, or None without any."""
    if not parts:
        return None
    total = jnp.zeros(12, el.d.dtype)
    for name, part in parts.items():
        total = total + _BY_NAME[name].force(el, part, lam)
    return total


def load_scale_squared(model):
    """Sum of the active terms' load scales (N^2); 0.0 without any."""
    return sum((t.load_scale(model) for t in active(model)), 0.0)


def at_time(model, t) -> dict:
    """The Model fields the active terms' time laws change at time ``t`` (s)."""
    changes = {}
    for term in active(model):
        if term.at_time is not None:
            changes.update(term.at_time(model, t))
    return changes


def section_inertia(model):
    """``model.inertia`` (E,6) or (E,6,6) plus the inertia the active terms add
    (diagonals (E,6)); the model's own array when none do."""
    inertia = model.inertia
    for term in active(model):
        if term.added_inertia is None:
            continue
        extra = term.added_inertia(model)
        inertia = (inertia + jnp.einsum("ei,ij->eij", extra, jnp.eye(6, dtype=extra.dtype))
                   if inertia.ndim == 3 else inertia + extra)
    return inertia
