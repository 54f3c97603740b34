"""Lane-wide reductions for control flow under ``jax.vmap``.

Under ``vmap`` a ``lax.cond`` or ``lax.switch`` whose predicate or index is batched
becomes a select that evaluates every branch for every lane. Where a branch is only a
cheaper way of computing the same answer (rebuild an iteration matrix only when needed;
factorize only the part of a border that couples, :func:`simsoft_jax.math.linalg.factorize_coupled`),
the choice can be made once for the whole batch instead: :func:`any_lane` and
:func:`lane_max` are the identity for one lane and, under ``vmap``, the reduction over
the lanes, unbatched, so the branch on them stays a branch.

Running every branch is also a hazard, not only a cost: jaxlib before 0.11.2 lets the
independent batched LAPACK calls of the branches run at once on XLA's CPU thread pool,
each blocking a pool thread until its pieces are done, and a vmapped solve with a rod
contact border of several sizes hung (two cores, 8 lanes).
"""
from __future__ import annotations

import jax.numpy as jnp
from jax.custom_batching import custom_vmap


@custom_vmap
def any_lane(pred):
    """``pred`` (a boolean scalar) for one lane; under ``vmap``, whether any lane's is true
    (unbatched, so a ``lax.cond`` on it stays a branch)."""
    return pred


@any_lane.def_vmap
def _any_lane_vmap(axis_size, in_batched, pred):
    return (jnp.any(pred) if in_batched[0] else pred), False


@custom_vmap
def lane_max(count):
    """``count`` (an integer scalar) for one lane; under ``vmap``, the largest of the
    lanes' (unbatched, so a ``lax.switch`` on a size chosen from it stays a branch)."""
    return count


@lane_max.def_vmap
def _lane_max_vmap(axis_size, in_batched, count):
    return (jnp.max(count) if in_batched[0] else count), False
