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

from ..math.quadrature import gauss_rule

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
            offset[m, e], slope[m, e] = part.routing.offsets_at(at)
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
