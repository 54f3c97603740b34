"""Staying on the stable branch in the static load continuation (:mod:`simsoft_jax.solvers.statics`).

Between load levels the continuation watches whether the tangent at the accepted
equilibrium is positive definite (a stable equilibrium, :mod:`simsoft_jax.solvers.stability`:
no negative eigenvalue of the symmetric part of the tangent). When a level converges to
an unstable state right after a stable one, the load step jumped a critical point
(bifurcation or limit point) or Newton left the branch the loads follow; the level is
refused and the step halved. At the smallest step the continuation switches branch
once: the next trial starts from its prediction moved along the critical mode
``phi`` (the eigenvector of the tangent's eigenvalue nearest zero, by inverse
iteration from the last load step's increment ``d``, the secant predictor's
``log(H_prev^-1 H)``), to the side ``d`` points to (the
side the loads and imperfections were bending the structure to, sign of
``<phi, d>``), by :data:`KICK` (largest nodal rotation in rad, or translation /
char_length). A perfectly symmetric path (``<phi, d>`` zero to round-off: a straight
column under an axial load) has no side to take: its unstable state is accepted, and
reported by the stability count of the result.

Rods with joints, friction or rod-rod contact are not watched (their kept tangent is
not the whole tangent, see :func:`simsoft_jax.solvers.stability.negative_eigenvalues`).

Cost. Where every load is conservative (:func:`symmetric_at_equilibrium`) the tangent
at an equilibrium is symmetric (the Hessian of the energy; its antisymmetric part is
linear in the residual, zero there), and whether it is positive definite is read from the
pivots of the factorization the Newton solve did anyway at its converged pass
(:func:`simsoft_jax.math.linalg.pivots_positive_definite`): two small Cholesky tests per
level instead of a second factorization (Princeton rod: about 1 instead of 23 us per
level; its static program 4936 -> 3770 StableHLO operations, 3611 unwatched, with the
leaner gathers and series of the same change). Other loads (follower loads, pressure,
tendons, contact and the other registered terms) keep the Cholesky test of the
tangent's symmetric part (:func:`stable`). The critical mode is found, only after a
loss, from one dense eigendecomposition for up to :data:`EIGH_LIMIT_NODES` nodes (the
same 8-step inverse iteration in closed form, fewer operations to compile), else by
inverse iteration with the block factorization.
"""
from __future__ import annotations

import jax
import jax.numpy as jnp

from ...math.linalg import dense, factorize, positive_definite, solve_factored
from ..stability import symmetric_blocks
from ...physics.terms import registry

# Size of the branch-switching move: largest nodal rotation (rad) or translation / char_length.
KICK = 0.1
# Inverse-iteration passes for the critical mode (each multiplies the other modes'
# share by the ratio of the critical eigenvalue to theirs).
_INVERSE_ITERATIONS = 8
# <phi, d> below this fraction of |phi| |d| is round-off: no side to switch to.
_SIDE_THRESHOLD = 1e-6
# The critical mode of chains of up to this many nodes by a dense eigendecomposition
# (a (6N, 6N) matrix), of longer ones by inverse iteration with the block factorization.
EIGH_LIMIT_NODES = 17


def watched(model) -> bool:
    """Whether the continuation of ``model`` watches stability (not with joints, friction
    or self contact)."""
    s = model.structure
    return not (s.joints or model.obstacle_friction is not None or s.self_contact)


def symmetric_at_equilibrium(model) -> bool:
    """Whether every load of ``model`` is conservative, so that its tangent at an
    equilibrium is symmetric (static): rods under dead nodal and offset forces, world
    distributed loads, gravity and attached masses, and the elastic terms. Follower
    loads, obstacles and the registered terms (tendons, chambers, magnetic and fluid
    loads, point loads in elements, offset gravity) are left out, and so are structures
    that are not :func:`watched`: where in doubt, :func:`stable` tests the tangent's
    symmetric part."""
    s = model.structure
    return watched(model) and not (
        model.nodal_follower is not None or model.distributed_local is not None
        or model.element_point_dead is not None or model.element_point_follower is not None
        or s.obstacle_kinds or s.tendon_names or s.chamber_names or registry.active(model))


def stable(tangent) -> jax.Array:
    """Whether the symmetric part of the tangent blocks ``(diag, upper, lower)`` is
    positive definite (bool)."""
    return positive_definite(*symmetric_blocks(tangent))


def _weighted(model, x):
    """Twists (N,6) with translations divided by ``char_length`` (rotations in rad)."""
    return jnp.concatenate([x[:, :3] / model.char_length, x[:, 3:]], axis=1)


def critical_kick(model, tangent, d) -> jax.Array:
    """The branch-switching move (N,6) (module docstring): :data:`KICK` times the critical
    mode of the tangent blocks ``(diag, upper, lower)``, on the side of the last load
    step's increment ``d`` (N,6); zeros when ``d`` has no share of that mode."""
    diag, lower = symmetric_blocks(tangent)
    blocks = (diag, jnp.swapaxes(lower, -1, -2), lower)
    n = diag.shape[0]
    if n <= EIGH_LIMIT_NODES:     # S^-8 d = V diag(lam^-8) V^T d, scaled
        V, lam = jax.lax.linalg.eigh(dense(blocks), symmetrize_input=False)
        w = (jnp.min(jnp.abs(lam)) / lam) ** _INVERSE_ITERATIONS
        phi = (V @ (w * (V.T @ d.reshape(-1)))).reshape(n, 6)
    else:
        factors = factorize(blocks, model.structure.identity_nodes())

        def inverse_step(_, x):
            x = solve_factored(factors, x)
            return x / jnp.maximum(jnp.linalg.norm(x), 1e-300)

        phi = jax.lax.fori_loop(0, _INVERSE_ITERATIONS, inverse_step, d)
    wphi, wd = _weighted(model, phi), _weighted(model, d)
    side = jnp.vdot(wphi, wd)
    has_side = (jnp.abs(side) > _SIDE_THRESHOLD * jnp.linalg.norm(wphi) * jnp.linalg.norm(wd)
                ) & jnp.all(jnp.isfinite(phi))
    size = jnp.max(jnp.maximum(jnp.linalg.norm(wphi[:, :3], axis=1),
                               jnp.linalg.norm(wphi[:, 3:], axis=1)))
    return jnp.where(has_side, jnp.sign(side) * KICK / jnp.maximum(size, 1e-300) * phi, 0.0)
