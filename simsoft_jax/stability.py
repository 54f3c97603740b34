"""Stability of a static equilibrium: the number of negative eigenvalues of the tangent.

At an equilibrium under conservative (dead) loads the left-invariant tangent ``K_t`` is
symmetric; follower loads make it non-symmetric, and the count is then that of its
symmetric part ``(K_t + K_t^T)/2`` (an indicator, not a proof of (in)stability for
non-conservative loads). By Sylvester's law of inertia the count equals the number of
negative eigenvalues of the 6x6 pivots of a block ``L D L^T`` factorisation without
pivoting (block Thomas on the symmetric block-tridiagonal matrix,
``S_0 = D_0``, ``S_i = D_i - L_i S_{i-1}^-1 L_i^T``): O(N) work. Held dofs have identity
rows and columns (:func:`~simsoft_jax.assembly.apply_constraints`) and contribute
positive pivots, so the count is that of the constrained tangent. Zero means a stable
(local energy minimum) equilibrium; ``n > 0`` an unstable one (buckled past n/2 or n
critical loads, depending on multiplicity).
"""
from __future__ import annotations

import jax
import jax.numpy as jnp

from .assembly import residual_and_tangent
from .loads import full_loads
from .model import Model


def symmetric_blocks(blocks):
    """Symmetric part ``(K + K^T)/2`` of a block-tridiagonal ``(diag (N,6,6),
    upper (N-1,6,6), lower (N-1,6,6))``, as ``(diag, lower)`` (``lower[i] = K[i+1, i]``)."""
    diag, upper, lower = blocks
    diag = 0.5 * (diag + jnp.swapaxes(diag, -1, -2))
    return diag, 0.5 * (lower + jnp.swapaxes(upper, -1, -2))


def count_negative_pivots(diag, lower):
    """Negative eigenvalues of the symmetric block-tridiagonal matrix ``(diag, lower)``
    (int): the negative eigenvalues of the pivots of its block LDL^T (Sylvester)."""
    def step(S, blocks):
        D, L = blocks
        S = D - L @ jnp.linalg.solve(S, L.T)
        S = 0.5 * (S + S.T)
        return S, jnp.sum(jnp.linalg.eigvalsh(S) < 0.0)

    first = jnp.sum(jnp.linalg.eigvalsh(diag[0]) < 0.0)
    _, counts = jax.lax.scan(step, diag[0], (diag[1:], lower))
    return first + jnp.sum(counts)


def negative_eigenvalues(model: Model, eq) -> jax.Array:
    """Negative eigenvalues (int array, 0 = stable) of the symmetric part of the
    constrained tangent at the equilibrium ``eq`` (:class:`~simsoft_jax.statics.Equilibrium`
    or anything with frames ``R`` (N,3,3) and positions ``p`` (N,3), m) of ``model`` under
    its full loads. Pure: jit- and vmap-able."""
    _, blocks = residual_and_tangent(full_loads(model), eq.R, eq.p, 1.0)
    return count_negative_pivots(*symmetric_blocks(blocks))
