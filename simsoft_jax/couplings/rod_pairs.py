"""Rod-rod and self contact in the static Newton system (``[contact] self = true``).

The pair terms of :mod:`simsoft_jax.physics.terms.rod_contact` on the candidate pairs of
:mod:`simsoft_jax.couplings.broad_phase` give the exact residual and the exact tangent. A pair of
elements e, f couples the nodes of e with those of f, which are not chain neighbours, so
the tangent is ``K = T + U W U^T``: ``T`` the block-tridiagonal chains (every term of
the rods, plus each pair's blocks inside e and inside f), ``U`` (N,6,6n) the unit
columns of the dofs of the n distinct nodes of the pairs and ``W`` (6n,6n) the pairs'
cross blocks ``K_ef``, ``K_fe`` between those nodes. With ``y = W U^T x`` the Newton system
``K x = -r`` is the bordered system

    [[T, U], [W U^T, -I]] [x; y] = [-r; 0]

solved by :func:`simsoft_jax.math.linalg.solve_coupled` (block cyclic reduction on the chains, a dense
Schur complement of size 6n): an exact Newton step, and the exact implicit derivative
(:mod:`simsoft_jax.solvers.statics`). ``P = [contact] max_pairs`` and the node capacity
``2 P + 2`` (:func:`coupled_nodes`) are static; more candidate pairs or touching nodes
than that make the residual NaN (:func:`overflows`; a dynamic step fails with the status
CONTACT_PAIRS naming ``max_pairs``, never a wrong convergence).
"""
from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from . import broad_phase
from .drives import restrict, restrict_border
from ..physics.assembly import assemble_blocks, element_poses, rod_end_flags
from ..physics.terms import rod_contact
from ..math.lanes import lane_max


class Pairs(NamedTuple):
    """Candidate pairs: element indices e, f (P,), active (P,) bool, overflow () bool,
    and per pair the four nodes (P,4) (e's A, B, f's A, B)."""
    e: jax.Array
    f: jax.Array
    active: jax.Array
    overflow: jax.Array
    nodes: jax.Array


def _rod_of(structure):
    """Static rod index of each element (E,)."""
    return np.concatenate([np.full(info.elements, k) for k, info in enumerate(structure.rods)])


def _arclength(structure, length):
    """Arclength (m) of each element's start and end along its rod (E,), (E,)."""
    starts = []
    for info in structure.rods:
        piece = length[info.first_element:info.first_element + info.elements]
        starts.append(jnp.cumsum(piece) - piece)
    s0 = jnp.concatenate(starts)
    return s0, s0 + length


def _joint_ends(structure):
    """Static ``(element, at_end)`` (J,2) of both ends of each joint between two rod
    nodes: an element of the node's rod that has it as its start (False) or end (True)."""
    a = np.asarray(structure.element_nodes)
    ends = []
    for _, na, nb in structure.joints:
        pair = []
        for n in (na, nb):
            starts, stops = np.nonzero(a == n)[0], np.nonzero(a + 1 == n)[0]
            if starts.size + stops.size == 0:       # a body node: no element
                break
            pair.append((int(starts[0]), False) if starts.size else (int(stops[0]), True))
        if len(pair) == 2:
            ends.append(pair)
    return ends


def _joint_distances(structure, s0, s1):
    """(E,J,2) arclength distance (m) of every element to both ends of each joint between
    rod nodes (0 for the elements that have the node, inf off the node's rod); None
    without such joints."""
    ends = _joint_ends(structure)
    if not ends:
        return None
    rod_of = _rod_of(structure)
    out = []
    for pair in ends:
        sides = []
        for element, at_end in pair:
            s_node = s1[element] if at_end else s0[element]
            d = jnp.maximum(0.0, jnp.maximum(s0 - s_node, s_node - s1))
            sides.append(jnp.where(jnp.asarray(rod_of == rod_of[element]), d, jnp.inf))
        out.append(jnp.stack(sides, axis=-1))
    return jnp.stack(out, axis=1)


def stations(model, R, p):
    """The contact stations (E, m+1, 3) of every element at frames R (N,3,3), p (N,3)
    (:func:`simsoft_jax.physics.terms.rod_contact.stations`); every point of the pair
    terms' sub-chords is a convex combination of them."""
    m = model.structure.contact_points
    return jax.vmap(lambda RA, pA, RB, pB, L: rod_contact.stations(RA, pA, RB, pB, L, m))(
        *element_poses(model, R, p), model.length)


def find_pairs(model, R, p, motion=0.0) -> Pairs:
    """The candidate element pairs at frames R (N,3,3), p (N,3). ``motion`` (m, >= 0):
    every element's bounding sphere and chord distance test widened by it, so that the
    pairs also hold every pair that can touch after each station has moved by at most
    ``motion`` (:func:`track`)."""
    s = model.structure
    m = s.contact_points
    X = stations(model, R, p)
    # jnp: a model built on the host (NumPy leaves, sj.run) may be closed over in a traced
    # function, where NumPy arrays cannot be indexed by the traced pair indices
    reach = rod_contact.EXTENSION * jnp.asarray(model.length) / m
    centre, radius = broad_phase.bounding_spheres(X, model.contact_radius, reach + motion)
    # the stations' largest distance from the chord: every sub-chord (extended) lies
    # within ``bow + reach`` of the chord (extended by ``reach``)
    chord = X[:, -1] - X[:, 0]
    along = jnp.sum((X - X[:, :1]) * chord[:, None], -1) / jnp.sum(chord**2, -1)[:, None]
    bow = jnp.sqrt(jnp.max(jnp.sum((X - X[:, :1] - along[..., None] * chord[:, None]) ** 2,
                                   -1), 1))
    margin = bow + reach + model.contact_radius + motion
    grow = reach / model.length

    def near_pair(e, f):
        def one(e, f):
            _, _, dist = rod_contact.closest_points(
                X[e, 0], X[e, -1], X[f, 0], X[f, -1], -grow[e], 1.0 + grow[e], -grow[f],
                1.0 + grow[f])
            return dist < margin[e] + margin[f]
        return jax.vmap(one)(e.reshape(-1), f.reshape(-1)).reshape(e.shape)

    rod_of = _rod_of(s)
    s0, s1 = _arclength(s, model.length)
    e, f, active, overflow = broad_phase.candidate_pairs(
        centre, radius, near_pair, rod_of, s0, s1,
        model.self_exclusion, s.contact_pairs, _joint_distances(s, s0, s1))
    a = jnp.asarray(s.element_nodes)
    nodes = jnp.stack([a[e], a[e] + 1, a[f], a[f] + 1], axis=1)
    return Pairs(e, f, active, overflow, nodes)


class Tracked(NamedTuple):
    """Candidate pairs found once for many evaluations (:func:`track`): the pairs, the
    stations (E, m+1, 3) m where they were found and the motion (m) they allow."""
    pairs: Pairs
    stations: jax.Array
    motion: jax.Array


def track(model, R, p, motion) -> Tracked:
    """The candidate pairs at frames R, p that stay valid while no station moves further
    than ``motion`` (m) from where it is now (:func:`find_pairs`; motion 0 where the
    widened pairs overflow ``max_pairs``); :func:`refresh` finds them again when one has."""
    motion = jnp.asarray(motion, jnp.asarray(p).dtype)
    wide = find_pairs(model, R, p, motion)
    # more pairs than max_pairs hold: the pairs at R, p alone (motion 0, found again at
    # every other frame), which overflow only where the contact itself does
    pairs = jax.lax.cond(wide.overflow, lambda: find_pairs(model, R, p), lambda: wide)
    return Tracked(pairs, stations(model, R, p), jnp.where(wide.overflow, 0.0, motion))


def moved(model, tracked: Tracked, R, p):
    """The largest distance (m) a station has moved at frames R, p since ``tracked``'s
    pairs were found; they hold every touching pair while it is at most ``tracked.motion``
    (the pair terms' points are convex combinations of the stations)."""
    return jnp.sqrt(jnp.max(jnp.sum((stations(model, R, p) - tracked.stations) ** 2, -1)))


def refresh(model, tracked: Tracked, R, p) -> Tracked:
    """``tracked`` if its pairs still hold at frames R, p (:func:`moved`), else the pairs
    found again there with the same motion: the broad phase runs only when a station has
    moved further than the motion allowed (``lax.cond``: no work otherwise)."""
    return jax.lax.cond(moved(model, tracked, R, p) > tracked.motion,
                        lambda: track(model, R, p, tracked.motion), lambda: tracked)


def _pair_args(model, R, p, pairs: Pairs):
    s = model.structure
    ends = jnp.asarray(rod_end_flags(s))
    ef = jnp.stack([pairs.e, pairs.f], 1)
    return ((R[pairs.nodes], p[pairs.nodes]), jnp.asarray(model.contact_radius)[ef],
            jnp.asarray(model.contact_stiffness)[ef], jnp.asarray(model.length)[ef], ends[ef])


def residual(model, R, p, slide=None, pairs=None):
    """The rod-rod contact residual (N,6) (held dofs zeroed, sliding drives reduced with
    ``slide``, :func:`simsoft_jax.couplings.drives.restrict`; NaN on overflow) on the
    candidate ``pairs`` (:class:`Pairs`; None: found at R, p; given, they must hold every
    touching pair: :func:`refresh`)."""
    s = model.structure
    pairs = find_pairs(model, R, p) if pairs is None else pairs
    m = s.contact_points

    g = jax.vmap(lambda *a: rod_contact.pair_residual(*a, m))(
        *_pair_args(model, R, p, pairs)) * pairs.active[:, None]
    r = _scatter(s.n_nodes, pairs.nodes, g)
    return restrict(s, slide, jnp.where(pairs.overflow, jnp.nan, r))


def _scatter(n_nodes, nodes, g):
    return jnp.zeros((n_nodes, 6), g.dtype).at[nodes.reshape(-1)].add(g.reshape(-1, 6))


def _tangent_sizes(capacity: int) -> tuple:
    """The numbers of pair tangents (static, decreasing from ``capacity``)
    :func:`_residuals_and_tangents` chooses from besides none: above 8 pairs, halved
    while above 4, at most four (each is a branch XLA compiles: the default 8 pairs keep
    one). A pair tangent costs about 0.1 ms (the cosseratbench pile's heap of 32
    candidates, of which a few touch: 4 tangents 0.43 ms, 8 0.79 ms)."""
    sizes = [capacity]
    while capacity > 8 and sizes[-1] > 4 and len(sizes) < 4:
        sizes.append(-(-sizes[-1] // 2))
    return tuple(sizes)


def _residuals_and_tangents(args, active, m: int):
    """Residuals (P,24) and tangents (P,24,24) of the pairs ``args``
    (:func:`_pair_args`), zero where not ``active``. A tangent (24 derivatives of the
    residual, ~30 times its cost) is formed only for the pairs with a nonzero residual,
    moved to the front: the smallest of :func:`_tangent_sizes` that holds them
    (``lax.switch``), or none where no pair touches; a pair whose residual is zero is
    out of reach (its penalty and weights are C2 and vanish there with their
    derivatives), so its tangent is zero."""
    g = jax.vmap(lambda *a: rod_contact.pair_residual(*a, m))(*args) * active[:, None]
    touching = active & jnp.any(g != 0, axis=1)
    order = jnp.argsort(~touching, stable=True)
    sizes = _tangent_sizes(active.shape[0])

    def tangents(count):
        def branch():
            if count == 0:
                return jnp.zeros(g.shape + g.shape[-1:], g.dtype)
            first = order[:count] if count < active.shape[0] else slice(None)
            k = jax.vmap(lambda *a: rod_contact.pair_residual_and_tangent(*a, m)[1])(
                *jax.tree_util.tree_map(lambda x: x[first], args))
            k = k * touching[first][:, None, None]
            if count == active.shape[0]:
                return k
            return jnp.zeros((active.shape[0],) + k.shape[1:], k.dtype).at[first].set(k)
        return branch

    sizes = sizes + (0,)
    # one branch also under vmap: the size of the lane with the most (math.lanes)
    which = jnp.sum(jnp.asarray(sizes) >= lane_max(jnp.sum(touching))) - 1
    return g, jax.lax.switch(which, [tangents(c) for c in sizes])


class Coupling(NamedTuple):
    """The bordered terms of :func:`system`: B = U (N,6,6n), C = W U^T (6n,N,6),
    D = -I (6n,6n), n = :func:`coupled_nodes`."""
    B: jax.Array
    C: jax.Array
    D: jax.Array


def system(model, R, p, r, blocks, T=None, slide=None, pairs=None):
    """Add the rod-rod contact to a masked residual ``r`` (N,6) and block-tridiagonal
    tangent ``blocks`` (held dofs already identity rows): returns ``(r, blocks,
    Coupling)`` of the bordered Newton system (module docstring). ``T`` (N,6,6): the
    maps ``T_SE3(w)`` of a dynamic step's increments ``w`` (the unknowns there), which
    multiply each node's columns of the pairs' tangents (None: statics, identity).
    ``slide``: the sliding drives' maps of a dynamic step (the chains reduced by them,
    :func:`simsoft_jax.couplings.drives.slide_maps`), which reduce the contact's terms
    and border alike (:func:`~simsoft_jax.couplings.drives.restrict`); None: none.
    ``pairs``: the candidate pairs, as in :func:`residual`."""
    s = model.structure
    pairs = find_pairs(model, R, p) if pairs is None else pairs
    m = s.contact_points
    g, k = _residuals_and_tangents(_pair_args(model, R, p, pairs), pairs.active, m)
    if T is not None:
        P = k.shape[0]
        k = jnp.einsum("pqnj,pnjk->pqnk", k.reshape(P, 24, 4, 6),
                       T[pairs.nodes]).reshape(P, 24, 24)
    # blocks inside e and inside f join chain neighbours: into the chains
    per_element = jnp.zeros((s.n_elements, 12, 12), p.dtype).at[pairs.e].add(
        k[:, :12, :12]).at[pairs.f].add(k[:, 12:, 12:])
    g, added = restrict(s, slide, jnp.where(pairs.overflow, jnp.nan,
                                            _scatter(s.n_nodes, pairs.nodes, g)),
                        assemble_blocks(s.n_nodes, s.element_nodes, per_element))
    r = r + g
    blocks = tuple(b + c for b, c in zip(blocks, added))
    # cross blocks (e's nodes with f's): W on the distinct nodes of the pairs, U their
    # unit columns
    n, cap = s.n_nodes, coupled_nodes(s)
    uniq, crowded = _border_nodes(s, pairs, k)
    slot = jnp.searchsorted(uniq, pairs.nodes)                               # (P, 4)
    rows = (6 * slot[:, :, None] + jnp.arange(6)).reshape(-1, 24)            # (P, 24)
    W = jnp.zeros((6 * cap, 6 * cap), p.dtype)
    W = W.at[rows[:, :12, None], rows[:, None, 12:]].add(k[:, :12, 12:])
    W = W.at[rows[:, 12:, None], rows[:, None, :12]].add(k[:, 12:, :12])
    # each node's border column per dof (N,6), 6 cap for a node not in the border: U by a
    # comparison and C = W U^T by a gather of W's columns (a scatter runs as a loop on CPU)
    at = jnp.minimum(jnp.searchsorted(uniq, jnp.arange(n)), cap - 1)
    column = jnp.where((uniq[at] == jnp.arange(n))[:, None], 6 * at[:, None] + jnp.arange(6),
                       6 * cap)
    U = (column[:, :, None] == jnp.arange(6 * cap)).astype(p.dtype)
    C = jnp.concatenate([W, jnp.zeros((6 * cap, 1), p.dtype)], axis=1)[:, column]
    U, C = restrict_border(s, slide, U, C)
    r = jnp.where(crowded, jnp.nan, r)
    return r, blocks, Coupling(U, C, -jnp.eye(6 * cap, dtype=p.dtype))


def _border_nodes(structure, pairs: Pairs, k):
    """The distinct nodes (cap,) of the pairs that touch, increasing, padded with
    ``n_nodes``, and whether there are more than ``cap = coupled_nodes``; ``k`` (P,24,24)
    the pairs' tangents. Only pairs with nonzero cross blocks take border nodes: a
    candidate farther apart couples nothing (and the factorization leaves the unused node
    slots out, :func:`simsoft_jax.math.linalg.factorize_coupled`)."""
    n, cap = structure.n_nodes, coupled_nodes(structure)
    touching = (jnp.any(k[:, :12, 12:] != 0, axis=(1, 2))
                | jnp.any(k[:, 12:, :12] != 0, axis=(1, 2))) & pairs.active
    listed = jnp.where(touching[:, None], pairs.nodes, n)
    distinct = jnp.unique(listed, size=listed.size, fill_value=n)
    uniq = distinct[:cap] if distinct.size >= cap else jnp.concatenate(
        [distinct, jnp.full(cap - distinct.size, n)])
    return uniq, jnp.sum(distinct < n) > cap


def overflows(model, R, p):
    """Whether the rod-rod contact at frames R (N,3,3), p (N,3) holds more candidate
    pairs than ``[contact] max_pairs``, or its touching pairs more nodes than
    :func:`coupled_nodes` (() bool): where :func:`residual` and :func:`system` are NaN."""
    pairs = find_pairs(model, R, p)
    _, k = jax.vmap(lambda *a: rod_contact.pair_residual_and_tangent(
        *a, model.structure.contact_points))(*_pair_args(model, R, p, pairs))
    return pairs.overflow | _border_nodes(model.structure, pairs, k)[1]


def coupled_nodes(structure) -> int:
    """Capacity (static) of the distinct nodes the pairs couple: ``2 max_pairs + 2``
    (pairs along a line contact share nodes); more make the residual NaN."""
    return min(structure.n_nodes, 2 * structure.contact_pairs + 2)


@jax.jit
def _summary(model, R, p):
    s = model.structure
    pairs = find_pairs(model, R, p)
    normal, force, pen = jax.vmap(
        lambda *a: rod_contact.pair_summary(*a, s.contact_points))(
        *_pair_args(model, R, p, pairs))
    on = pairs.active
    normal, force, pen = normal * on, force * on[:, None], pen * on
    per_element = (jnp.zeros((s.n_elements, 3), p.dtype).at[pairs.e].add(force)
                   .at[pairs.f].add(-force))
    touching = (jnp.zeros(s.n_elements, bool).at[pairs.e].max(pen > 0.0)
                .at[pairs.f].max(pen > 0.0))
    return jnp.sum(normal), per_element, jnp.max(pen, initial=0.0), touching


def report(model, R, p) -> dict:
    """The rod-rod entry of the result's ``contacts`` at frames R (N,3,3), p (N,3):
    ``normal_force`` (N, the sum over pairs of ``sum h h l psi'``), ``force`` (3,) N (the
    total contact force on all rods: zero by Newton's third law), ``rod_force``
    (``{rod: (3,)}`` N, world: the contact force on each rod), ``max_penetration`` (m)
    and ``nodes`` (``{rod: [node, ...]}``: nodes of elements with a penetrating pair).
    Frames (T,N,3,3), (T,N,3) of a trajectory give each with a leading time axis
    (``nodes``: a list per time)."""
    summary = jax.vmap(_summary, (None, 0, 0)) if p.ndim == 3 else _summary
    normal, per_element, pen, touching = jax.device_get(summary(model, R, p))
    s = model.structure
    rod_force, nodes = {}, {}
    for info in s.rods:
        span = slice(info.first_element, info.first_element + info.elements)
        rod_force[info.name] = per_element[..., span, :].sum(-2)
        hits = touching[..., span].reshape(-1, info.elements)
        per_time = []
        for hit_elements in hits:
            hit = np.zeros(info.nodes, bool)
            hit[:-1] |= hit_elements
            hit[1:] |= hit_elements
            per_time.append(np.flatnonzero(hit).tolist())
        nodes[info.name] = per_time if p.ndim == 3 else per_time[0]
    return {"normal_force": normal, "force": per_element.sum(-2), "rod_force": rod_force,
            "max_penetration": pen, "nodes": nodes}


def energy(model, R, p):
    """Penalty energy (J) of the rod-rod contact at frames R (N,3,3), p (N,3): the sum of
    :func:`simsoft_jax.physics.terms.rod_contact.pair_energy` over the active candidate pairs."""
    pairs = find_pairs(model, R, p)
    m = model.structure.contact_points
    each = jax.vmap(lambda *a: rod_contact.pair_energy(*a, m))(*_pair_args(model, R, p, pairs))
    return jnp.sum(each * pairs.active)
