"""Broad phase of rod-rod contact: the element pairs whose bounding spheres overlap, found
through a hashed uniform grid in O(E log E) (a sort and binary searches), with fixed
array sizes so that it runs inside the jit-compiled solvers.

Every element gets a bounding sphere (centre, radius: its stations' spread plus the
chord extension plus its contact radius, :func:`bounding_spheres`); the grid cell is
the largest sphere diameter, so two overlapping spheres sit in the same or neighbouring
cells. Each cell is hashed to one integer; the elements are sorted by it, and every
element looks up the (at most ``CELL_CAPACITY``) elements of each of its 27
neighbouring cells. A chain that is not folded puts a few elements in a cell, so the
work is O(E) sphere tests beyond the sort; the finer test runs on the pairs of
overlapping spheres alone (up to ``NEAR_TESTS`` per element, else on every slot). Kept
pairs: ``e < f``, spheres overlapping, passing a finer test given by the caller (the
element chords close enough), and not excluded as neighbours (same rod and an arclength
gap between them below ``exclusion``; elements sharing a node have gap 0, so they are always excluded).

The narrow phase gets a fixed number ``capacity`` of pairs (``[contact] max_pairs``);
``overflow`` is True when more pairs (or a crowded cell) were found than fit: the
contact is then incomplete, and the callers make the residual non-finite so that no
solve reports convergence with it.
"""
from __future__ import annotations

import itertools

import jax
import jax.numpy as jnp
import numpy as np

CELL_CAPACITY = 16     # elements looked at per neighbouring cell
NEAR_TESTS = 8         # pairs of overlapping spheres per element given the finer test at once
_OFFSETS = np.array(list(itertools.product((-1, 0, 1), repeat=3)))
_PRIMES = (73856093, 19349663, 83492791)


def bounding_spheres(X, radius, reach):
    """Centres (E,3) and radii (E,) (m) of spheres holding each element's stations ``X``
    (E, m+1, 3) widened by ``reach`` (E,) (m: the contact radius and chord extension)."""
    centre = 0.5 * (X.min(1) + X.max(1))
    spread = jnp.sqrt(jnp.max(jnp.sum((X - centre[:, None]) ** 2, -1), 1))
    return centre, spread + radius + reach


def _hash(cells):
    h = cells[..., 0] * _PRIMES[0]
    return (h ^ (cells[..., 1] * _PRIMES[1])) ^ (cells[..., 2] * _PRIMES[2])


def candidate_pairs(centre, radius, near_pair, rod_of, s_start, s_end, exclusion,
                    capacity: int, joined=None):
    """Element pairs ``(e (P,), f (P,), active (P,) bool, overflow ())`` with ``P =
    capacity`` (module docstring); ``near_pair(e, f)`` (vectorized over index arrays)
    the finer test a pair of overlapping spheres must pass too (the chords within
    reach, :mod:`simsoft_jax.couplings.rod_pairs`); ``rod_of`` (E,) NumPy ints (static),
    ``s_start``, ``s_end`` (E,) the elements' arclength ends along their rod (m),
    ``exclusion`` () m; ``joined`` (E,J,2) or None: each element's arclength distance (m)
    to the two ends of each joint between rod nodes (inf off their rods), so that
    elements within ``exclusion`` of each other through a joint do not touch either.
    Inactive slots hold the pair (0, 0)."""
    n = centre.shape[0]
    size = 2.0 * jnp.max(radius)
    cells = jnp.floor(centre / size).astype(jnp.int64)
    keys = _hash(cells)
    order = jnp.argsort(keys)
    sorted_keys = keys[order]
    near = _hash(cells[:, None, :] + jnp.asarray(_OFFSETS))                 # (E, 27)
    earlier = jnp.tril(jnp.ones((27, 27), bool), -1)
    repeated = jnp.any((near[:, :, None] == near[:, None, :]) & earlier, -1)  # hash clash
    lo = jnp.searchsorted(sorted_keys, near, side="left")
    hi = jnp.searchsorted(sorted_keys, near, side="right")
    crowded = jnp.any((hi - lo > CELL_CAPACITY) & ~repeated)
    slot = lo[..., None] + jnp.arange(CELL_CAPACITY)                         # (E, 27, C)
    inside = (slot < hi[..., None]) & ~repeated[..., None]
    f = order[jnp.clip(slot, 0, n - 1)]
    e = jnp.broadcast_to(jnp.arange(n)[:, None, None], f.shape)
    rod = jnp.asarray(rod_of)
    gap = s_start[f] - s_end[e]
    neighbours = (rod[e] == rod[f]) & (gap < exclusion)
    if joined is not None:   # through a joint: e near one end, f near the other
        a, b = joined[..., 0], joined[..., 1]
        neighbours = neighbours | jnp.any((a[e] + b[f] < exclusion)
                                          | (b[e] + a[f] < exclusion), axis=-1)
    overlap = jnp.sum((centre[e] - centre[f]) ** 2, -1) < (radius[e] + radius[f]) ** 2
    spheres = (inside & (f > e) & overlap & ~neighbours).reshape(-1)
    e, f = e.reshape(-1), f.reshape(-1)
    bound = NEAR_TESTS * n

    def few():   # the finer test on the (at most ``bound``) pairs of overlapping spheres,
        # compacted in their order: the kept ones are the first of them that pass
        index = jnp.nonzero(spheres, size=bound, fill_value=0)[0]
        near = near_pair(e[index], f[index]) & (jnp.arange(bound) < jnp.sum(spheres))
        return jnp.sum(near), index[jnp.nonzero(near, size=capacity, fill_value=0)[0]]

    def every():
        keep = spheres & near_pair(e, f)
        return jnp.sum(keep), jnp.nonzero(keep, size=capacity, fill_value=0)[0]

    count, index = jax.lax.cond(jnp.sum(spheres) <= bound, few, every)
    active = jnp.arange(capacity) < count
    e = jnp.where(active, e[index], 0)
    f = jnp.where(active, f[index], 0)
    return e, f, active, crowded | (count > capacity)
