"""Staying on the stable branch in the static load continuation (:mod:`simsoft_jax.statics`).

Between load levels the continuation watches whether the tangent at the accepted
equilibrium is positive definite (a stable equilibrium, :mod:`simsoft_jax.stability`:
no negative eigenvalue of the symmetric part of the tangent). When a level converges to
an unstable state right after a stable one, the load step jumped a critical point
(bifurcation or limit point) or Newton left the branch the loads follow; the level is
refused and the step halved. At the smallest step the continuation switches branch
once: the next trial starts from its prediction moved along the critical mode
``phi`` (the eigenvector of the tangent's eigenvalue nearest zero, by inverse
iteration from the last load step's increment ``d``), to the side ``d`` points to (the
side the loads and imperfections were bending the structure to, sign of
``<phi, d>``), by :data:`KICK` (largest nodal rotation in rad, or translation /
char_length). A perfectly symmetric path (``<phi, d>`` zero to round-off: a straight
column under an axial load) has no side to take: its unstable state is accepted, and
reported by the stability count of the result.

Rods with joints, friction or rod-rod contact are not watched (their kept tangent is
not the whole tangent, see :func:`simsoft_jax.stability.negative_eigenvalues`).
"""
from __future__ import annotations

import jax
import jax.numpy as jnp

from .. import lie
from ..linalg import factorize, positive_definite, solve_factored
from ..stability import symmetric_blocks

# Size of the branch-switching move: largest nodal rotation (rad) or translation / char_length.
KICK = 0.1
# Inverse-iteration passes for the critical mode (each multiplies the other modes'
# share by the ratio of the critical eigenvalue to theirs).
_INVERSE_ITERATIONS = 8
# <phi, d> below this fraction of |phi| |d| is round-off: no side to switch to.
_SIDE_THRESHOLD = 1e-6


def watched(model) -> bool:
    """Whether the continuation of ``model`` watches stability (not with joints, friction
    or self contact)."""
    s = model.structure
    return not (s.joints or model.obstacle_friction is not None or s.self_contact)


def stable(tangent) -> jax.Array:
    """Whether the symmetric part of the tangent blocks ``(diag, upper, lower)`` is
    positive definite (bool)."""
    return positive_definite(*symmetric_blocks(tangent))


def increment(R_from, p_from, R_to, p_to) -> jax.Array:
    """Body-frame twists (N,6) ``log(H_from^-1 H_to)`` from frames (N,3,3), (N,3)."""
    return jax.vmap(lambda Ra, pa, Rb, pb: lie.log_se3(lie.relative_pose(Ra, pa, Rb, pb)))(
        R_from, p_from, R_to, p_to)


def _weighted(model, x):
    """Twists (N,6) with translations divided by ``char_length`` (rotations in rad)."""
    return jnp.concatenate([x[:, :3] / model.char_length, x[:, 3:]], axis=1)


def critical_kick(model, tangent, d) -> jax.Array:
    """The branch-switching move (N,6) (module docstring): :data:`KICK` times the critical
    mode of the tangent blocks ``(diag, upper, lower)``, on the side of the last load
    step's increment ``d`` (N,6); zeros when ``d`` has no share of that mode."""
    diag, lower = symmetric_blocks(tangent)
    factors = factorize((diag, jnp.swapaxes(lower, -1, -2), lower),
                        model.structure.identity_nodes())

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
