"""Rigid obstacles as signed distances of a point: positive in the free space where the rod
may be, zero on the obstacle's surface, negative inside the obstacle (m).

Each obstacle is its kind (static structure) and a parameter row (7,) of floats (traced,
differentiable; :func:`simsoft_jax.scene_contact.parameter_row`), laid out per kind:

==========  ==========================  =====================================================
kind        row ``[0:3] | [3:6] | [6]`` signed distance of ``x``
==========  ==========================  =====================================================
plane       point, normal, -            ``(x - point) . n``, ``n = normal/|normal|``
sphere      center, -, radius           ``|x - center| - radius``
capsule     a, b, radius                ``|x - c(x)| - radius``, c(x) the nearest point of ab
cylinder    axis_point, axis, radius    ``rho(x) - radius`` (rod outside an infinite cylinder)
tube        axis_point, axis, radius    ``radius - rho(x)`` (rod inside: a vessel, a channel)
==========  ==========================  =====================================================

``rho(x)`` is the distance of ``x`` from the axis line. Every formula is differentiable
everywhere in ``x`` and in the parameters: the norms are "safe" (value 0 and gradient 0
at the origin, :func:`safe_norm`), so a point exactly on an axis or at a centre gives a
finite (zero) gradient instead of NaN.
"""
from __future__ import annotations

import jax.numpy as jnp

from .scene_contact import KINDS


def safe_norm(v):
    """``|v|`` with value and gradient 0 at ``v = 0`` (no NaN from ``sqrt`` at 0)."""
    s = jnp.dot(v, v)
    positive = s > 0.0
    return jnp.where(positive, jnp.sqrt(jnp.where(positive, s, 1.0)), 0.0)


def _unit(v):
    return v / safe_norm(v)


def _axis_distance(x, point, axis):
    """Distance (m) of ``x`` from the line through ``point`` along ``axis`` (3,)."""
    e = _unit(axis)
    r = x - point
    return safe_norm(r - jnp.dot(r, e) * e)


def signed_distance(kind: str, params, x):
    """Signed distance (m) of the point ``x`` (3,) from an obstacle of ``kind`` with the
    parameter row ``params`` (7,) (module docstring)."""
    a, b, radius = params[:3], params[3:6], params[6]
    if kind == "plane":
        return jnp.dot(x - a, _unit(b))
    if kind == "sphere":
        return safe_norm(x - a) - radius
    if kind == "capsule":
        ab = b - a
        t = jnp.clip(jnp.dot(x - a, ab) / jnp.dot(ab, ab), 0.0, 1.0)
        return safe_norm(x - a - t * ab) - radius
    if kind == "cylinder":
        return _axis_distance(x, a, b) - radius
    if kind == "tube":
        return radius - _axis_distance(x, a, b)
    raise ValueError(f"obstacles: unknown kind {kind!r} (known: {KINDS})")
