"""Start rotations in moment balance: the nodal rotations of rods started from points
without given rotations, relaxed with the positions held.

A rod started from ``initial.points`` alone gets, node by node, its stress-free frame
turned onto the points' chord tangent (:func:`~simsoft_jax.scene.start_frames.initial_frames`).
Those frames are not in moment balance: the bending of the chord polygon and the shear of
the elements on either side of a node leave moment rows of the residual (spec S47/S70) that
the tiny rotational inertia of a slender section turns into huge rotational accelerations
(the crossing ropes of cosseratbench, 51 elements: up to 0.016 rad off balance, 7e5
rad/s^2 at the start; relaxed in 3 Newton iterations), a transient that the time steps
must resolve. The rotational inertia of a section is negligible next to its
bending and shear stiffness, so the rotations reach moment balance at once: the consistent
start holds the positions and solves the moment rows of the static residual at the loads
of ``t = 0`` (gravity included) for the rotations,

``r_k^M(R, p_0) = 0`` for every relaxed node ``k`` (rotation dofs left free by the supports),

by Newton on ``R_k <- R_k exp(theta_k^)`` with the static tangent's rotation blocks (a
block-tridiagonal system of 3 unknowns per node), a proximal term ``EPSILON |K_ii|`` on its
diagonal (rotations the residual does not see, such as the twist of a rope pinned at both
ends, stay where they are; the term vanishes with the step, so the balance is exact) and a
trust region of ``TRUST`` rad per node; it stops when the largest correction is below
``TOLERANCE`` rad (not applied). Nodes of joints keep their chord frames (the joints'
multipliers are not known before the first step); rod-rod contact is not in the balance
(ropes that touch at the start are not balanced against it).
"""
from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from ..math import lie
from ..math.linalg import block_solve
from ..math.xla import jit
from .loads import loads_at
from ..physics.assembly import apply_constraints, residual_and_tangent

MAX_ITERATIONS = 30
TOLERANCE = 1e-10   # rad: the largest nodal rotation of the last Newton correction
TRUST = np.pi / 4   # rad: the largest nodal rotation of one Newton step
EPSILON = 1e-9      # proximal term, relative to the tangent's diagonal


class Balance(NamedTuple):
    """The relaxed start rotations R (N,3,3) (world), whether Newton converged, its
    iterations, and the norm (N, moments / char_length) of the relaxed moment rows at
    the start frames and at the last Newton iterate (the relaxed frames when converged)."""
    R: jax.Array
    converged: jax.Array
    iterations: jax.Array
    moment_before: jax.Array
    moment_after: jax.Array


def _moment_rows(model, R, mask):
    """Residual (N,6) with only the relaxed rotation rows kept, and the tangent's blocks
    with the others replaced by the identity."""
    r, blocks = residual_and_tangent(loads_at(model, 0.0), R, model.p0)
    return apply_constraints(mask, r, blocks)


@jit
def balanced_rotations(model, relaxed) -> Balance:
    """Newton on the moment rows of the start (module docstring) for the nodes where
    ``relaxed`` (N,) is True, from ``model.R0`` with the positions ``model.p0`` held."""
    mask = model.structure.free_mask() * jnp.concatenate(
        [jnp.zeros((relaxed.shape[0], 3)), jnp.repeat(relaxed[:, None], 3, 1)], axis=1)
    norm = lambda r: jnp.linalg.norm(r[:, 3:]) / model.char_length  # noqa: E731

    def step(c):
        R, k, _, before, _ = c
        r, (diag, upper, lower) = _moment_rows(model, R, mask)
        d = jnp.diagonal(diag, axis1=1, axis2=2)
        diag = diag + jax.vmap(jnp.diag)(EPSILON * jnp.abs(d) * mask)
        dx = -block_solve((diag, upper, lower), r)
        turn = jnp.max(jnp.linalg.norm(dx[:, 3:], axis=1))
        theta = dx[:, 3:] * jnp.minimum(1.0, TRUST / jnp.maximum(turn, 1e-300))
        turned = R @ jax.vmap(lie.exp_so3)(theta)
        # a correction below the tolerance is not applied: the residual is the final one,
        # and frames already in balance stay as given
        return (jnp.where(turn > TOLERANCE, turned, R), k + 1, turn,
                jnp.where(k == 0, norm(r), before), norm(r))

    def going(c):
        return (c[1] < MAX_ITERATIONS) & (c[2] > TOLERANCE) & ~jnp.isnan(c[2])

    zero = jnp.zeros((), model.p0.dtype)
    R, k, size, before, after = jax.lax.while_loop(
        going, step, (model.R0, 0, jnp.array(jnp.inf, model.p0.dtype), zero, zero))
    ok = (size <= TOLERANCE) & jnp.all(jnp.isfinite(R))
    return Balance(R, ok, k, before, after)
