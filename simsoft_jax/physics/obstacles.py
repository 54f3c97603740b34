"""Rigid obstacles as signed distances of a point: positive in the free space where the rod
may be, zero on the obstacle's surface, negative inside the obstacle (m).

Each obstacle is its kind (static structure) and a parameter row (ROW,) = (11,) of floats
(traced, differentiable; :func:`simsoft_jax.scene.scene_contact.parameter_row`), laid out per
kind (unused slots are 0):

===========  =========================================  ===========================================
kind         row ``[0:3] | [3:6] | [6] | [7:10] | [10]``  signed distance of ``x``
===========  =========================================  ===========================================
plane        point, normal                               ``(x - point) . n``, ``n = normal/|normal|``
sphere       center, -, radius                           ``|x - center| - radius``
capsule      a, b, radius                                ``|x - c(x)| - radius``, c(x) nearest on ab
cylinder     axis_point, axis, radius                    ``rho(x) - radius`` (rod outside)
tube         axis_point, axis, radius                    ``radius - rho(x)`` (rod inside)
curved_tube  center, normal, radius, start, angle        ``radius - rho_c(x)`` (rod inside)
===========  =========================================  ===========================================

``rho(x)`` is the distance of ``x`` from the axis line. A ``curved_tube`` is a tube (rod
inside) around a centreline of constant curvature ``1/R``: the arc of the circle about
``center`` in the plane normal to ``normal``, from ``start`` (``R = |start - center|``,
``start - center`` normal to ``normal``) turning by ``angle`` (rad, right-handed about
``normal``), continued at both ends by straight half-lines along its end tangents (the
centreline is C1: an inlet, the bend, an outlet). ``rho_c(x)`` is the distance of ``x``
from that centreline: the smallest of its distances from the inlet half-line, from the
bend (``sqrt((|u| - R)^2 + h^2)``, ``u`` the in-plane part of ``x - center`` and ``h`` the
height above the plane, used where the polar angle of ``u`` lies within the bend) and
from the outlet half-line.

Every formula is differentiable everywhere in ``x`` and in the parameters: the norms are
"safe" (value 0 and gradient 0 at the origin, :func:`safe_norm`), so a point exactly on an
axis or at a centre gives a finite (zero) gradient instead of NaN; the curved tube's
choice of piece is a comparison (no derivative) and its distance is C1 across the pieces
(equal values and gradients where inlet or outlet meet the bend).

Motion (:func:`translate`): an obstacle moved rigidly by ``shift`` (3,) has its points
(``point``, ``center``, ``a``, ``b``, ``axis_point``, ``start``) moved and its directions
kept.
"""
from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from ..scene.scene_contact import KINDS, ROW

# which row slots are points (moved by a translation), per kind
_POINT_SLOTS = {"plane": (0,), "sphere": (0,), "capsule": (0, 3), "cylinder": (0,),
                "tube": (0,), "curved_tube": (0, 7)}


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


def _half_line_distance(x, origin, direction):
    """Distance (m) of ``x`` from the half-line ``origin + s direction``, s >= 0 (unit
    ``direction``)."""
    q = x - origin
    return safe_norm(q - jnp.maximum(jnp.dot(q, direction), 0.0) * direction)


def _centreline_distance(x, center, normal, start, angle):
    """``rho_c(x)`` (m): distance of ``x`` from the curved tube's centreline (module
    docstring)."""
    n = _unit(normal)
    r0 = start - center
    r0 = r0 - jnp.dot(r0, n) * n                  # in-plane radius vector to the start
    R = safe_norm(r0)
    e1 = r0 / R
    t0 = jnp.cross(n, e1)                         # tangent at the start
    c, s = jnp.cos(angle), jnp.sin(angle)
    end = center + R * (c * e1 + s * t0)
    t1 = c * t0 - s * e1                          # tangent at the end
    q = x - center
    h = jnp.dot(q, n)
    u = q - h * n
    bend = safe_norm(jnp.stack([safe_norm(u) - R, h]))
    # polar angle of u from e1 in [0, 2 pi): which piece is nearest is a comparison
    ug = jax.lax.stop_gradient(u)
    polar = jnp.mod(jnp.arctan2(jnp.dot(ug, jax.lax.stop_gradient(t0)),
                                jnp.dot(ug, jax.lax.stop_gradient(e1))), 2.0 * jnp.pi)
    within = polar <= jax.lax.stop_gradient(angle)
    inlet = _half_line_distance(x, start, -t0)
    outlet = _half_line_distance(x, end, t1)
    straight = jnp.minimum(inlet, outlet)
    return jnp.where(within, jnp.minimum(bend, straight), straight)


def signed_distance(kind: str, params, x):
    """Signed distance (m) of the point ``x`` (3,) from an obstacle of ``kind`` with the
    parameter row ``params`` (ROW,) (module docstring)."""
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
    if kind == "curved_tube":
        return radius - _centreline_distance(x, a, b, params[7:10], params[10])
    raise ValueError(f"obstacles: unknown kind {kind!r} (known: {KINDS})")


def translate(kind: str, params, shift):
    """The parameter row (ROW,) of the obstacle ``kind`` moved rigidly by ``shift`` (3,) m
    (its points moved, its directions and sizes kept)."""
    place = np.zeros((ROW, 3))
    for slot in _POINT_SLOTS[kind]:
        place[slot:slot + 3] = np.eye(3)
    return params + jnp.asarray(place) @ shift
