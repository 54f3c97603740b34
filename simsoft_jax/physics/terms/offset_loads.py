"""A dead (world-fixed) force at a point offset from a node in its section frame (the
weight of an offset mass, a weight hung behind a wing's trailing edge).

The force ``F`` (N, world) acts at ``x = p + R c`` (``c`` (3,) m, section frame), so its
potential is ``-F . (p + R c)``; under the right perturbation ``p + R du``,
``R exp(dtheta)`` its gradient, the residual-side nodal load, is
``-[R^T F; c x R^T F]``: the force and the moment about the node, which turns with the
section (spec S43 extended to an offset point). A follower (section-frame) force at an
offset makes the constant moment ``c x F`` and needs no term of its own
(:func:`simsoft_jax.model.model.build_model` adds it to the follower moments).
"""
import jax.numpy as jnp


def force(R, force_world, offset, lam):
    """``-lam [R^T F; c x R^T F]`` (6,) at one node: ``R`` (3,3) the node's rotation,
    ``force_world`` F (3,) N, ``offset`` c (3,) m in the section frame."""
    a = R.T @ force_world
    return -lam * jnp.concatenate([a, jnp.cross(offset, a)])
