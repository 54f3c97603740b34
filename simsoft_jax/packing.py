"""One float64 vector for everything a compiled program hands to the host.

Copying a result to the host costs ~20 us per array on CPU whatever its size (an
11-array static equilibrium: 0.22 ms, as much as 5 % of a Princeton solve), against
~6 us for one vector. A program therefore returns :func:`pack` of its outputs, and the
host rebuilds them with :func:`unpack` from their known shapes and types. Integers and
booleans travel as float64, exact below 2**53.
"""
from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np


def pack(tree) -> jax.Array:
    """The leaves of ``tree`` (arrays or scalars, inside a program), ravelled, converted to
    float64 and concatenated in pytree order: a vector of their total size."""
    return jnp.concatenate([jnp.ravel(x).astype(jnp.float64)
                            for x in jax.tree_util.tree_leaves(tree)])


def unpack(vector: np.ndarray, like):
    """Inverse of :func:`pack` on the host: ``like`` is the pytree of the packed outputs
    with :class:`jax.ShapeDtypeStruct` leaves (None for absent fields); returns it with
    NumPy arrays of those shapes and dtypes, cut from ``vector`` (1-D) in pytree order.
    Raises ValueError when the sizes do not add up to the vector's."""
    leaves, tree = jax.tree_util.tree_flatten(like)
    sizes = [int(np.prod(x.shape, dtype=int)) for x in leaves]
    if sum(sizes) != vector.size:
        raise ValueError(f"packed vector of {vector.size} numbers, layout of {sum(sizes)}")
    out, start = [], 0
    for x, size in zip(leaves, sizes):
        out.append(vector[start:start + size].reshape(x.shape).astype(x.dtype))
        start += size
    return jax.tree_util.tree_unflatten(tree, out)
