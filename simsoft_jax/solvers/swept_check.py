"""Swept check of an update of the frames: would it carry the rod through an obstacle or
through another rod? (Newton updates and load-continuation predictions are cut back to a
fraction that does not; :func:`cut_back`.)

A penalty contact (:mod:`simsoft_jax.physics.terms.contact`,
:mod:`simsoft_jax.physics.terms.rod_contact`) pushes back only while the surfaces overlap:
an update that moves a rod from one side of an obstacle or of another rod to the other
in one go lands in a state the penalty does not see, and Newton may converge there, an
equilibrium with the rod passed through. The check sweeps the node positions (m) from
the state before the update to the state after it along the straight path, sampled in
``SAMPLES`` equal parts, and tests (states 0 and 1) the start against every sample for
obstacles, and each part for rods:

* obstacles: a node whose centreline point is in the free space in state 0 (signed
  distance ``phi_0 > 0``, :func:`simsoft_jax.physics.obstacles.signed_distance`) and
  inside the obstacle in state 1 (``phi_1 < 0``) has sunk deeper than its own contact
  radius: no penalty equilibrium sinks a rod that far;
* rods (``[contact] self``): for two element chords ``a0 a1`` and ``b0 b1`` that are not
  neighbours on one rod, the signed distance between their lines along the common normal
  ``n = (da x db) / |da x db|``, ``g = (b0 - a0) . n``, taken positive in state 0
  (``g_1`` measured along state 1's normal turned to the side of state 0's), goes from
  ``g_0 > r`` to ``g_1 < r`` (``r`` the mean of the two contact radii: the centrelines
  come closer than one radius, through each other included) while the closest points of
  the two lines lie within both chords in both states, each chord extended by
  ``OVERLAP`` of its length where its rod goes on (not past a rod's free end, so that a
  crossing at a node, or one moving on to the next chord, is in the test of some pair).
  Chords nearer to parallel than ``PARALLEL_SINE`` (the sine of their angle) are not
  tested (their common normal is not defined).

A broad phase over the whole sweep picks the pairs given this test: each chord's swept
box, the axis-aligned box of its extended chord in all the sampled states, widened by
half its contact radius. Two chords whose swept boxes do not overlap are more than
``r`` apart along some axis all along the sweep, between the samples too (each point of
a chord moves linearly along the straight path), so they can neither touch nor pass
through each other. The test above finds ``|g_1| < r`` only for chords whose
closest points (on the extended chords, so in their boxes) are closer than ``r``; a
sign change of ``g`` between two samples of chords kept apart (their lines turned over
in one part of the sweep) is no pass, so such pairs are not tested. The pairs whose
boxes overlap, at most ``SWEPT_PAIRS`` per element at once (else every pair), are
tested in every sampled state: O(E^2) box comparisons and O(SAMPLES E) line gaps while
each chord's box meets a few others (below 2 per element in the pile of
docs/cosseratbench.md). The check runs only for an update that moves some node by more
than half the smallest contact radius: a smaller one changes the gap of two chords by
less than r, so none crosses to the other side.
"""
from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from ..physics import obstacles
from ..physics.assembly import rod_end_flags

PARALLEL_SINE = 0.05    # chords at a smaller angle are not tested for passing through
OVERLAP = 0.5           # chords extended by this fraction where their rod goes on
SAMPLES = 8             # parts of the swept path tested one by one
HALVINGS = 30           # cut_back halves an update at most this many times
SWEPT_PAIRS = 3         # pairs of overlapping swept boxes tested at once, per element


def checked(model, obstacles_too: bool = True) -> bool:
    """Whether the model has anything an update could pass through (static): rod-rod
    contact, or obstacles when ``obstacles_too``."""
    s = model.structure
    return (obstacles_too and bool(s.obstacle_kinds)) or bool(s.self_contact)


def chord_pairs(structure):
    """Static indices ``(e, f)`` (P,), (P,) of the element pairs tested for passing
    through: every pair of elements of two rods, and of one rod unless neighbours."""
    a = np.asarray(structure.element_nodes)
    e, f = np.triu_indices(len(a), 1)
    keep = a[f] != a[e] + 1            # neighbours on one rod share a node
    return e[keep], f[keep]


def _line_gap(a0, a1, b0, b1):
    """Common normal ``n`` (3,), signed gap ``g = (b0 - a0) . n`` (m), the line
    parameters ``(s, t)`` of the closest points and the sine of the chords' angle."""
    da, db, r = a1 - a0, b1 - b0, b0 - a0
    cross = jnp.cross(da, db)
    size = jnp.linalg.norm(cross)
    sine = size / jnp.maximum(jnp.linalg.norm(da) * jnp.linalg.norm(db), 1e-300)
    n = cross / jnp.maximum(size, 1e-300)
    aa, bb, ab = jnp.dot(da, da), jnp.dot(db, db), jnp.dot(da, db)
    det = jnp.maximum(aa * bb - ab * ab, 1e-300)
    s = (jnp.dot(r, da) * bb - jnp.dot(r, db) * ab) / det
    t = (jnp.dot(r, da) * ab - jnp.dot(r, db) * aa) / det
    return n, jnp.dot(r, n), s, t, sine


def _extensions(structure):
    """Static line parameters ``lo`` (E,) <= 0 and ``hi`` (E,) >= 1 of each chord's ends
    extended by ``OVERLAP`` where its rod goes on (module docstring)."""
    lo, hi = -OVERLAP * (1.0 - rod_end_flags(structure).T)
    return lo, 1.0 - hi


def _passing(model, x, e, f):
    """Per pair ``(e, f)`` (K,) of chords, whether it passes through or comes closer than
    one radius in some part of the sweep ``x`` (S+1, N, 3) (module docstring): (K,) bool.
    Each state's line gaps are computed once."""
    a = np.asarray(model.structure.element_nodes)
    ae, af = jnp.asarray(a)[e], jnp.asarray(a)[f]

    def one(y):
        return jax.vmap(_line_gap)(y[ae], y[ae + 1], y[af], y[af + 1])

    n, g, s, t, sine = jax.vmap(one)(x)                   # each (S+1, K, ...)
    n0, g0, s0, t0, sin0 = n[:-1], g[:-1], s[:-1], t[:-1], sine[:-1]
    n1, g1, s1, t1, sin1 = n[1:], g[1:], s[1:], t[1:], sine[1:]
    g1 = g1 * jnp.sign(jnp.sum(n0 * n1, axis=-1)) * jnp.sign(g0)
    lo, hi = (jnp.asarray(v) for v in _extensions(model.structure))
    inside = ((s0 >= lo[e]) & (s0 <= hi[e]) & (t0 >= lo[f]) & (t0 <= hi[f])
              & (s1 >= lo[e]) & (s1 <= hi[e]) & (t1 >= lo[f]) & (t1 <= hi[f]))
    angled = (sin0 > PARALLEL_SINE) & (sin1 > PARALLEL_SINE)
    radius = jnp.asarray(model.contact_radius)
    r = 0.5 * (radius[e] + radius[f])
    return jnp.any(inside & angled & (jnp.abs(g0) > r) & (g1 < r), axis=0)


def swept_boxes(model, x):
    """Lower and upper corners (E,3), (E,3) (m) of each chord's swept box: its extended
    chord (:func:`_extensions`) in every state of the sweep ``x`` (S+1, N, 3), widened by
    half its contact radius (module docstring)."""
    a = np.asarray(model.structure.element_nodes)
    lo, hi = _extensions(model.structure)
    y0, y1 = x[:, a], x[:, a + 1]                                # (S+1, E, 3)
    ends = jnp.concatenate([y0 + lo[:, None] * (y1 - y0), y0 + hi[:, None] * (y1 - y0)])
    # a relative widening of 1e-9 keeps round-off from parting boxes that touch
    half = 0.5 * (1.0 + 1e-9) * jnp.asarray(model.contact_radius)[:, None]
    return ends.min(0) - half, ends.max(0) + half


def rods_pass(model, x):
    """Whether, between consecutive node positions of the sweep ``x`` (S+1, N, 3), some
    pair of chords (:func:`chord_pairs`) comes closer than one radius, or passes through
    each other (module docstring); only pairs whose swept boxes (:func:`swept_boxes`)
    overlap are tested, at most ``SWEPT_PAIRS`` per element at once (else every pair)."""
    e, f = chord_pairs(model.structure)
    if not len(e):
        return jnp.array(False)
    low, high = swept_boxes(model, x)
    overlap = jnp.all((low[e] <= high[f]) & (low[f] <= high[e]), axis=-1)   # (P,)
    count = jnp.sum(overlap)
    bound = min(len(e), SWEPT_PAIRS * model.structure.n_elements)

    def few():
        index = jnp.nonzero(overlap, size=bound, fill_value=0)[0]
        return jnp.any(_passing(model, x, jnp.asarray(e)[index], jnp.asarray(f)[index])
                       & (jnp.arange(bound) < count))

    return jax.lax.cond(count <= bound, few,
                        lambda: jnp.any(overlap & _passing(model, x, e, f)))


def obstacles_pass(model, p0, p1, rows=None):
    """Whether a node goes from the free space (p0 (N,3)) to inside an obstacle (p1)
    (module docstring); ``rows`` (K,11) the obstacles' parameter rows (default
    ``model.obstacles``: fixed obstacles)."""
    kinds = model.structure.obstacle_kinds
    if not kinds:
        return jnp.array(False)
    rows = model.obstacles if rows is None else rows
    out = jnp.array(False)
    for k, kind in enumerate(kinds):
        phi = jax.vmap(lambda x: obstacles.signed_distance(kind, rows[k], x))
        out = out | jnp.any((phi(p0) > 0.0) & (phi(p1) < 0.0))
    return out


def passes(model, p0, p1, rows=None, obstacles_too: bool = True):
    """Whether the update of the node positions p0 -> p1 (N,3) carries a rod through
    another rod or (``obstacles_too``) an obstacle, swept in SAMPLES parts (module
    docstring); False when the model has neither."""
    if not checked(model, obstacles_too):
        return jnp.array(False)
    t = jnp.linspace(0.0, 1.0, SAMPLES + 1)[:, None, None]
    x = (1.0 - t) * p0 + t * p1

    out = jnp.array(False)
    if obstacles_too:
        out = jnp.any(jax.vmap(lambda b: obstacles_pass(model, p0, b, rows))(x[1:]))
    if model.structure.self_contact:
        # no node moving by more than half the smallest radius: every pair of chords
        # stays on its side (their gap changes by less than r), nothing to sweep
        far = jnp.max(jnp.sum((p1 - p0) ** 2, axis=-1)) > (
            0.5 * jnp.min(model.contact_radius)) ** 2
        out = out | jax.lax.cond(far, lambda: rods_pass(model, x), lambda: jnp.array(False))
    return out


def cut_back(model, p0, moved, fraction, rows=None, obstacles_too: bool = True):
    """The largest ``fraction / 2^k`` (k = 0 .. HALVINGS) of an update whose end state
    ``moved(fraction)`` (node positions (N,3)) does not pass through (:func:`passes`)
    from p0; the last one tried when every one does. ``fraction`` unchanged without
    rod contact and (``obstacles_too``) obstacles."""
    if not checked(model, obstacles_too):
        return fraction

    def cond(c):
        step, k = c
        return (k < HALVINGS) & passes(model, p0, moved(step), rows, obstacles_too)

    return jax.lax.while_loop(cond, lambda c: (0.5 * c[0], c[1] + 1), (fraction, 0))[0]

