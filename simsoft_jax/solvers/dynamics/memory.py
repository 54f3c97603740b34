"""What the dynamic Newton solver carries from one time step to the next (spec section 4):
the factorized iteration matrix it reuses (modified Newton, :mod:`simsoft_jax.solvers.dynamics`)
and the recent accelerations, and the predictor of a step's increment built from them.

Shapes: N nodes; accelerations and increments (N,6) ordered ``[linear; angular]`` in the
nodal (body) frames; step sizes in s.
"""
from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp

from ...math.linalg import CoupledFactors, factorize_coupled


class NewtonMemory(NamedTuple):
    """factors: the factorized iteration matrix (see :func:`linalg.factorize_coupled`; no
    couplings without joints); h: the
    step size (s) it was built for; renew: rebuild it at the start of the next step (the
    last step had to rebuild it mid-way, or its contraction shows it has aged;
    :func:`~.newton.newton_step`); vd_history (2,N,6): the accelerations one and two
    accepted steps back; h_history (2,): the sizes (s) of the last and the one-but-last
    accepted steps (0: none yet), for :func:`predicted_increment`; multipliers (M,): the
    joint multipliers of the last accepted step, the next step's guess (M = 0 without
    joints)."""
    factors: CoupledFactors
    h: jax.Array
    renew: jax.Array
    vd_history: jax.Array
    h_history: jax.Array
    multipliers: jax.Array


def empty_newton_memory(n_nodes: int, couplings: int = 0, multipliers: int = 0,
                        identity: tuple = ()) -> NewtonMemory:
    """A :class:`NewtonMemory` of the right shapes with no history (the matrix is built at
    first use): ``couplings`` m unknowns beside the N nodes' chains, of which the last
    ``multipliers`` are joint multipliers (:mod:`simsoft_jax.couplings.mechanisms`); ``identity``:
    the nodes the factorization leaves out (:func:`simsoft_jax.math.linalg.factorize`)."""
    n, m = n_nodes, couplings
    blocks = (jnp.zeros((n, 6, 6)), jnp.zeros((n - 1, 6, 6)), jnp.zeros((n - 1, 6, 6)))
    shapes = jax.eval_shape(lambda *a: factorize_coupled(*a, identity), blocks,
                            jnp.zeros((n, 6, m)), jnp.zeros((m, n, 6)), jnp.zeros((m, m)))
    zeros = jax.tree_util.tree_map(lambda x: jnp.zeros(x.shape, x.dtype), shapes)
    return NewtonMemory(zeros, jnp.asarray(-1.0), jnp.asarray(True), jnp.zeros((2, n, 6)),
                        jnp.zeros(2), jnp.zeros(multipliers))


def remember_step(memory: NewtonMemory, vd, h, accepted) -> NewtonMemory:
    """``memory`` with the accelerations ``vd`` (N,6) at the start of an accepted step of
    size h pushed onto its history (unchanged when not ``accepted``)."""
    history = jnp.stack([vd, memory.vd_history[0]])
    sizes = jnp.stack([jnp.asarray(h, jnp.float64), memory.h_history[0]])
    return memory._replace(vd_history=jnp.where(accepted, history, memory.vd_history),
                           h_history=jnp.where(accepted, sizes, memory.h_history))


def predicted_increment(v, vd, a, h, memory: NewtonMemory, alpha_m, alpha_f, beta):
    """Starting guess ``w0`` (N,6) of a generalized-alpha step of size h from the state's
    velocities v, accelerations vd and pseudo-accelerations a (N,6) (spec S60 with a chosen
    ``vdot``; ``alpha_m, alpha_f, beta`` of S53).

    The increment is ``w = h v_n + h^2 ((1/2 - beta) a_n + beta a_{n+1})`` (S66); only
    ``a_{n+1}`` is unknown, and it follows from a guess of ``vdot_{n+1}`` through S52.
    Three guesses: zero (the textbook predictor of S60), constant ``vdot_n``, and linear
    extrapolation ``vdot_n + (h / h_n)(vdot_n - vdot_{n-1})``. The one used is the guess
    that would have predicted ``vdot_n`` best from the step before (constant before there
    is a history). Smooth motions take the extrapolation (the paper's synthetic helical scene:
    residual evaluations in 300 steps with the textbook, constant and extrapolated guess
    1302, 1129 and 932); on stiff ones with oscillating accelerations extrapolation
    overshoots (spring-steel scene: 2423, 2593 and 3087; selected: 2505). The guess
    changes the iteration count only, not the solution.
    """
    (vd1, vd2), (h1, h2) = memory.vd_history, memory.h_history
    safe = lambda x: jnp.maximum(x, 1e-300)  # noqa: E731
    linear = vd + (h / safe(h1)) * (vd - vd1)
    errors = jnp.stack([
        jnp.where(h1 > 0.0, jnp.linalg.norm(vd), jnp.inf),
        jnp.where(h1 > 0.0, jnp.linalg.norm(vd - vd1), 0.0),
        jnp.where(h2 > 0.0, jnp.linalg.norm(vd - vd1 - (h1 / safe(h2)) * (vd1 - vd2)), jnp.inf)])
    guesses = jnp.stack([jnp.zeros_like(vd), vd, linear])
    vd_next = guesses[jnp.argmin(errors)]
    a1 = ((1.0 - alpha_f) * vd_next + alpha_f * vd - alpha_m * a) / (1.0 - alpha_m)
    return h * (v + (0.5 - beta) * h * a + beta * h * a1)
