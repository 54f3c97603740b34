"""Scene actuators -> Model arrays: tendon routings sampled at the quadrature points of
the elements they pass, tensions, chamber pressures and areas, and their time laws
(:mod:`simsoft_jax.physics.terms.tendons`, :mod:`simsoft_jax.physics.terms.chambers`).

Arc length ``s`` (m) along a rod is measured from its first node in the stress-free
shape, the nodes at ``RodSpec.node_arc`` (evenly spaced, ``s_k = k L_rod / elements``,
unless the rod's segments give their lengths); a tendon across welded rods
is sampled part by part, each in its own rod. The offsets and their slopes
are evaluated here once (NumPy) and become traced Model arrays, so a routing can be
changed, or differentiated, without recompiling.
"""
from __future__ import annotations

import numpy as np

_SAMPLES_PER_TURN = 12   # Gauss points per helix turn inside an element (at least 6)


def quadrature_size(scene) -> int:
    """Gauss points per element for the tendons (static): 1 when every offset is constant
    (the length integrand is constant then), else 6, or 12 per helix turn inside the
    longest element, whichever is more."""
    parts = [part for t in getattr(scene, "tendons", ()) for part in t.parts]
    if all(part.routing.kind == "constant" for part in parts):
        return 1
    specs = {rod.name: rod for rod in scene.rods}
    turns = [np.diff(specs[part.rod].node_arc()).max() / abs(part.routing.pitch) for part in parts if part.routing.kind == "helix"]
    return int(max([6] + [int(np.ceil(_SAMPLES_PER_TURN * x)) for x in turns]))


def gauss_rule(q: int):
    """Gauss-Legendre points and weights (q,) on [0, 1]."""
    x, w = np.polynomial.legendre.leggauss(q)
    return 0.5 * (1.0 + x), 0.5 * w


def routing_at(routing, s):
    """Offsets (y, z) and slopes d(y, z)/ds at arc lengths ``s`` (...,): two (..., 2)."""
    if routing.kind == "constant":
        offset = np.broadcast_to([routing.y, routing.z], s.shape + (2,))
        return offset, np.zeros_like(offset)
    if routing.kind == "helix":
        k = 2.0 * np.pi / routing.pitch
        theta = np.deg2rad(routing.phase_deg) + k * s
        r = routing.radius
        return (np.stack([r * np.cos(theta), r * np.sin(theta)], -1),
                np.stack([-r * k * np.sin(theta), r * k * np.cos(theta)], -1))
    offset = np.stack([np.interp(s, routing.s, routing.ys), np.interp(s, routing.s, routing.zs)], -1)
    if len(routing.s) == 1:
        return offset, np.zeros_like(offset)
    # slope of the piece s lies on; zero outside the samples (the offset is held there)
    piece = np.clip(np.searchsorted(routing.s, s, side="right") - 1, 0, len(routing.s) - 2)
    ds = np.diff(routing.s)
    slope = np.stack([np.diff(routing.ys)[piece] / ds[piece],
                      np.diff(routing.zs)[piece] / ds[piece]], -1)
    inside = (s >= routing.s[0]) & (s <= routing.s[-1])
    return offset, slope * inside[..., None]


def _members(items, rods, n_elements):
    """Static membership of chambers: per item, a tuple of E bools (True for the elements
    it spans)."""
    out = []
    for it in items:
        first = rods[it.rod].first_element
        mask = np.zeros(n_elements, bool)
        mask[first + it.from_node:first + it.to_node] = True
        out.append(tuple(mask.tolist()))
    return tuple(out)


def _node_arcs(scene):
    """Rod name -> arc length (m) of its nodes, (nodes,)."""
    return {rod.name: rod.node_arc() for rod in scene.rods}


def tendon_arrays(scene, rods, n_elements):
    """``(static, arrays)``: static structure (names, membership, quadrature size,
    displacement-controlled flags) and the tendon arrays of the Model: tension (M,),
    displacement (M,), offset and slope (M,E,Q,2), each part of a tendon sampled in its
    own rod (arc length from that rod's first node)."""
    tendons = getattr(scene, "tendons", ())
    q = quadrature_size(scene)
    xi, _ = gauss_rule(q)
    offset = np.zeros((len(tendons), n_elements, q, 2))
    slope = np.zeros_like(offset)
    member = np.zeros((len(tendons), n_elements), bool)
    arcs = _node_arcs(scene)
    for m, t in enumerate(tendons):
        for part in t.parts:
            k = np.arange(part.first, part.last)
            e = rods[part.rod].first_element + k
            s_node = arcs[part.rod]
            at = s_node[k, None] + xi[None, :] * (s_node[k + 1] - s_node[k])[:, None]
            offset[m, e], slope[m, e] = routing_at(part.routing, at)
            member[m, e] = True
    static = dict(tendon_names=tuple(t.name for t in tendons),
                  tendon_elements=tuple(tuple(row) for row in member.tolist()),
                  tendon_quadrature=q,
                  tendon_displaced=tuple(t.displacement is not None for t in tendons))
    arrays = dict(tendon_tension=np.array([t.tension or 0.0 for t in tendons]),
                  tendon_displacement=np.array([t.displacement or 0.0 for t in tendons]),
                  tendon_offset=offset, tendon_slope=slope)
    return static, arrays


def chamber_arrays(scene, rods, n_elements):
    """``(static, arrays)``: names and membership; pressure (C,), area (C,), offset (C,2)."""
    chambers = getattr(scene, "chambers", ())
    static = dict(chamber_names=tuple(c.name for c in chambers),
                  chamber_elements=_members(chambers, rods, n_elements))
    arrays = dict(chamber_pressure=np.array([c.pressure for c in chambers]),
                  chamber_area=np.array([c.area for c in chambers]),
                  chamber_offset=np.reshape([c.offset for c in chambers], (-1, 2)))
    return static, arrays
