"""Stability of a static equilibrium: the number of negative eigenvalues of the tangent.

At an equilibrium under conservative (dead) loads the left-invariant tangent ``K_t`` is
symmetric; follower loads make it non-symmetric, and the count is then that of its
symmetric part ``(K_t + K_t^T)/2`` (an indicator, not a proof of (in)stability for
non-conservative loads). By Sylvester's law of inertia the count equals the number of
negative eigenvalues of the 6x6 pivots of a block ``L D L^T`` factorisation without
pivoting (block Thomas on the symmetric block-tridiagonal matrix,
``S_0 = D_0``, ``S_i = D_i - L_i S_{i-1}^-1 L_i^T``): O(N) work. The usual case, a
positive definite tangent, is recognised first by a Cholesky test in a few batched
calls (:func:`~simsoft_jax.math.linalg.positive_definite`), and the pivots are counted only
when it fails. :func:`simsoft_jax.pipeline.results.run` hands over the tangent of the static
solve's last Newton pass (taken at the equilibrium) instead of assembling it again
(Princeton: the check 0.26 -> ~0.07 ms of a 3.3 ms solve). Held dofs have identity
rows and columns (:func:`~simsoft_jax.physics.assembly.apply_constraints`) and contribute
positive pivots, so the count is that of the constrained tangent. Zero means a stable
(local energy minimum) equilibrium; ``n > 0`` an unstable one (buckled past n/2 or n
critical loads, depending on multiplicity).

With bodies and joints the tangent is the bordered matrix ``[[K, B], [C, D]]`` of
:mod:`simsoft_jax.couplings.mechanisms`; its inertia is that of the chains plus that of the Schur
complement ``S = D - C K^-1 B`` (Haynsworth), and a saddle-point matrix with M
independent constraints has M negative eigenvalues more than the tangent restricted to
the constraints (Gould 1985, "On practical conditions for the existence and uniqueness
of solutions to the general equality quadratic programming problem"): the count
reported is that of the restricted tangent.
"""
from __future__ import annotations

import jax
import jax.numpy as jnp

from ..couplings import coupling, mechanisms
from ..couplings.tendon_lengths import tension_controlled
from ..physics.assembly import residual_and_tangent
from ..math.linalg import factorize, positive_definite, solve_factored
from ..model.loads import full_loads
from ..model.model import Model


def symmetric_blocks(blocks):
    """Symmetric part ``(K + K^T)/2`` of a block-tridiagonal ``(diag (N,6,6),
    upper (N-1,6,6), lower (N-1,6,6))``, as ``(diag, lower)`` (``lower[i] = K[i+1, i]``)."""
    diag, upper, lower = blocks
    diag = 0.5 * (diag + jnp.swapaxes(diag, -1, -2))
    return diag, 0.5 * (lower + jnp.swapaxes(upper, -1, -2))


def count_negative_pivots(diag, lower):
    """Negative eigenvalues of the symmetric block-tridiagonal matrix ``(diag, lower)``
    (int): the negative eigenvalues of the pivots of its block LDL^T (Sylvester). A
    positive definite matrix (the usual stable equilibrium) is recognised first by a
    Cholesky test (:func:`~simsoft_jax.math.linalg.positive_definite`, a few batched calls)
    and counts 0; the pivots are counted only when that test fails."""
    return jax.lax.cond(positive_definite(diag, lower),
                        lambda: jnp.zeros((), int), lambda: _pivot_count(diag, lower))


def _pivot_count(diag, lower):
    """:func:`count_negative_pivots` by the N sequential pivots of the block LDL^T."""
    def step(S, blocks):
        D, L = blocks
        S = D - L @ jnp.linalg.solve(S, L.T)
        S = 0.5 * (S + S.T)
        return S, jnp.sum(jnp.linalg.eigvalsh(S) < 0.0)

    first = jnp.sum(jnp.linalg.eigvalsh(diag[0]) < 0.0)
    _, counts = jax.lax.scan(step, diag[0], (diag[1:], lower))
    return first + jnp.sum(counts)


def negative_eigenvalues(model: Model, eq, tangent=None, positive=None) -> jax.Array:
    """Negative eigenvalues (int array, 0 = stable) of the symmetric part of the
    constrained tangent at the equilibrium ``eq`` (:class:`~simsoft_jax.solvers.statics.Equilibrium`
    or anything with frames ``R`` (N,3,3) and positions ``p`` (N,3), m) of ``model`` under
    its full loads. ``tangent``: that tangent's blocks ``(diag, upper, lower)`` when at
    hand (the last Newton pass's, ``Equilibrium.tangent``), used for rods without joints
    or friction (the Newton tangent with friction holds its stick terms, which this count
    leaves out); assembled here otherwise. ``positive``: whether that tangent's symmetric
    part is positive definite when already known (``Equilibrium.tangent_positive``, the
    continuation's stability watch), so that only an indefinite one is counted.
    Displacement-controlled tendons count as tension-controlled ones at their solved
    tensions (the multipliers ``eq.multipliers``). Pure: jit- and vmap-able."""
    y = eq.multipliers if eq.multipliers is not None else jnp.zeros(0)
    model = tension_controlled(coupling.with_multipliers(model, y))
    s = model.structure
    if tangent is not None and not (coupling.present(s) or model.obstacle_friction is not None):
        if positive is None:
            return count_negative_pivots(*symmetric_blocks(tangent))
        return jax.lax.cond(positive, lambda: jnp.zeros((), int),
                            lambda: _pivot_count(*symmetric_blocks(tangent)))
    loaded = full_loads(model)
    r, blocks = residual_and_tangent(loaded, eq.R, eq.p, 1.0)
    if not coupling.present(s):
        return count_negative_pivots(*symmetric_blocks(blocks))
    system = coupling.couple(loaded, eq.R, eq.p, y, r, blocks)
    m_joints = mechanisms.coupling_count(s) if s.joints else 0
    return bordered_count(system, m_joints) - mechanisms.multiplier_count(s)


def bordered_count(system: coupling.Coupled, m_joints: int):
    """Negative eigenvalues of the symmetric part of the bordered tangent
    ``[[K, B], [C, D]]`` of :func:`simsoft_jax.couplings.coupling.couple` (int): the joints' first
    ``m_joints`` border unknowns are unknowns of the tangent (their count adds by
    Haynsworth's inertia additivity over the chains' pivots and the Schur complement
    ``S = D - C K^-1 B``); the rod-rod contact's border after them stands for the term
    ``U W U^T`` of the tangent (``B = U``, ``C = W U^T``, ``D = -I``: :mod:`simsoft_jax.couplings.rod_pairs`).

    For the contact part, with the symmetric ``W = V diag(lam) V^T`` and its nonzero
    modes ``lam`` (the zero ones add nothing), the matrix ``P = [[A, U V], [V^T U^T,
    -diag(1/lam)]]`` (A: the tangent without the contact's cross term) has the tangent
    ``A + U W U^T`` as Schur complement of its second block, so (Haynsworth, twice)
    ``neg(A + U W U^T) = neg(A) + neg(-diag(1/lam) - V^T U^T A^-1 U V) -
    neg(-diag(1/lam))``. A zero mode gets -1 on both sides, which cancels. Needs the
    chains' symmetric tangent nonsingular (a held rod's is)."""
    diag, lower = symmetric_blocks(system.blocks)
    chain = factorize((diag, jnp.swapaxes(lower, -1, -2), lower))
    m = system.D.shape[0]
    # the tangent's own border: the joints' coupling unknowns
    B = 0.5 * (system.B[..., :m_joints] + jnp.transpose(system.C[:m_joints], (1, 2, 0)))
    D = 0.5 * (system.D[:m_joints, :m_joints] + system.D[:m_joints, :m_joints].T)
    count = count_negative_pivots(diag, lower)
    if m_joints:     # the joints' Schur complement: its count, and A^-1 below
        KinvB = solve_factored(chain, B)
        schur = D - jnp.einsum("nja,njb->ab", B, KinvB)
        count = count + jnp.sum(jnp.linalg.eigvalsh(0.5 * (schur + schur.T)) < 0.0)
    if m == m_joints:                     # joints only
        return count
    # the contact's cross term U W U^T: U its unit columns on the chains and the joints'
    # coupling unknowns, W from C = W U^T (C's columns at U's dofs)
    U = system.B[..., m_joints:]                                     # (N,6,mc)
    U_z = system.D[:m_joints, m_joints:]                             # (mj,mc)
    W = (jnp.einsum("anj,njb->ab", system.C[m_joints:], U)
         + system.D[m_joints:, :m_joints] @ U_z)
    lam, V = jnp.linalg.eigh(0.5 * (W + W.T))
    nonzero = jnp.abs(lam) > 1e-12 * jnp.maximum(jnp.max(jnp.abs(lam)), 1e-300)
    UV, UV_z = jnp.einsum("njb,bk->njk", U, V), U_z @ V
    # A^-1 (U V) on the tangent without the contact's cross term: the chains bordered by
    # the joints' coupling unknowns (none: the chains)
    KinvUV = solve_factored(chain, UV)
    if m_joints:
        z = jnp.linalg.solve(schur, UV_z - jnp.einsum("nja,njk->ak", B, KinvUV))
        x = KinvUV - jnp.einsum("nja,ak->njk", KinvB, z)
        G = jnp.einsum("njk,njl->kl", UV, x) + UV_z.T @ z
    else:
        G = jnp.einsum("njk,njl->kl", UV, KinvUV)
    inverse = jnp.where(nonzero, 1.0 / jnp.where(nonzero, lam, 1.0), 0.0)
    keep = nonzero[:, None] & nonzero[None, :]
    S = jnp.where(keep, -jnp.diag(inverse) - 0.5 * (G + G.T), 0.0) + jnp.diag(
        jnp.where(nonzero, 0.0, -1.0))
    return (count + jnp.sum(jnp.linalg.eigvalsh(S) < 0.0)
            - jnp.sum(jnp.where(nonzero, -inverse, -1.0) < 0.0))
