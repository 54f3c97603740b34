"""One float64 vector for everything a compiled program hands to the host.

Copying a result to the host costs ~20 us per array on CPU whatever its size (an
11-array static equilibrium: 0.22 ms, as much as 5 % of a Princeton solve), against
~6 us for one vector. A program therefore returns :func:`pack` of its outputs, and the
host rebuilds them with :meth:`Layout.unpack` from their known shapes and types. Integers and
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


class Layout:
    """Where each output of a packed vector lies: built once per compiled program from
    ``like``, the pytree of the packed outputs with :class:`jax.ShapeDtypeStruct` leaves
    (None for absent fields), so that :meth:`unpack` only cuts (~1 us per field; working
    the offsets out at every call cost ~0.1 ms for the dozen fields of a static solve)."""

    def __init__(self, like):
        leaves, self.tree = jax.tree_util.tree_flatten(like)
        self.fields, start = [], 0
        for x in leaves:
            size = int(np.prod(x.shape, dtype=int))
            self.fields.append((start, start + size, tuple(x.shape), np.dtype(x.dtype)))
            start += size
        self.size = start

    def unpack(self, vector: np.ndarray):
        """Inverse of :func:`pack` on the host: the outputs as NumPy arrays of their shapes
        and dtypes, cut from ``vector`` (1-D) in pytree order. Raises ValueError when the
        sizes do not add up to the vector's."""
        if vector.size != self.size:
            raise ValueError(f"packed vector of {vector.size} numbers, layout of "
                             f"{self.size}")
        return self.tree.unflatten([vector[a:b].reshape(shape).astype(dtype)
                                    for a, b, shape, dtype in self.fields])

