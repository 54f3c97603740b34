"""Displacement-controlled tendons in statics: the tendon's length change from the
stress-free shape is prescribed, ``Delta l_k(x) = delta_k``, and its tension is the
unknown (a Lagrange multiplier of that constraint).

For the tensions ``t`` (K,) of the K displacement-controlled tendons the equilibrium
``x(t)`` is the tension-controlled static solve (:func:`simsoft_jax.solvers.statics.equilibrium`),
and the tensions solve the K equations ``F(t) = Delta l(x(t)) - delta = 0`` by Newton's
method, with the exact Jacobian ``dF/dt`` (K,K) from the implicit derivative of the
equilibrium (forward mode, K tangent solves). This is the bordered system
``[[K_t, G], [G^T, 0]]`` (G the tendon-length gradients) eliminated on the K
multipliers: ``dF/dt = -G^T K_t^-1 G`` is its Schur complement. The derivative of the
solved tensions with respect to the model is ``dt = -(dF/dt)^-1 dF/dtheta`` (implicit
function theorem), so results stay differentiable. A solved tension below zero means the
tendon would have to push: it is returned as is and reported by the caller (slack).
"""
from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp

from ..couplings.tendon_lengths import displaced, length_changes
from .newton import implicit

MAX_ITERATIONS = 30


def _mismatch(solve, model, settings, t):
    """``(F(t) (K,), equilibrium)``: length changes minus the prescribed ones."""
    idx = jnp.asarray(displaced(model.structure))
    m = model.replace(tendon_tension=model.tendon_tension.at[idx].set(t))
    eq = solve(m, settings)
    return length_changes(m, eq.R, eq.p)[idx] - m.tendon_displacement[idx], eq


def newton_solve(solve, model, settings, tolerance):
    """Newton on the tensions from zero; returns (tensions (K,), converged)."""
    k = len(displaced(model.structure))

    def step(carry):
        t, _, it = carry
        jac, (f, eq) = jax.jacfwd(lambda u: (lambda v: (v[0], v))(_mismatch(solve, model, settings, u)),
                                  has_aux=True)(t)
        dt = -jnp.linalg.solve(jac, f)
        done = (jnp.max(jnp.abs(f)) <= tolerance) | ~eq.converged
        return jnp.where(done, t, t + dt), done & eq.converged, it + 1

    t, ok, _ = jax.lax.while_loop(
        lambda c: ~c[1] & (c[2] < MAX_ITERATIONS), step,
        (jnp.zeros(k), jnp.array(False), jnp.array(0)))
    return t, ok


@dataclasses.dataclass(frozen=True)
class TensionProblem:
    """The tensions t (K,) of the displacement-controlled tendons as an implicit problem
    for :func:`simsoft_jax.solvers.newton.implicit`: ``F(t) = 0`` (:func:`_mismatch`) with
    ``params = (model, settings)``; ``dt = -(dF/dt)^-1 dF/dtheta`` with the exact
    Jacobian (K,K) from the equilibrium's implicit derivative (module docstring).
    ``equilibrium``: the tension-controlled static solve."""
    equilibrium: object

    def prescribed(self, params, t):
        return jnp.zeros_like(t)

    def residual(self, params, t, delta):
        model, settings = params
        return _mismatch(self.equilibrium, model, settings, t + delta)[0]

    def linear_solve(self, params, t, rhs):
        jac = jax.jacfwd(lambda d: self.residual(params, t, d))(jnp.zeros_like(t))
        return jnp.linalg.solve(jac, rhs)

    def merge(self, params, solution, free, moved):
        return free

    def push(self, params, t, delta):
        return delta

    def valid(self, params):
        return True


def solve_tensions(solve, model, settings, tolerance):
    """The model with the tensions of its displacement-controlled tendons solved
    (differentiable; see the module docstring) and whether their Newton converged.
    ``solve(model, settings) -> Equilibrium`` is the tension-controlled static solve
    (it must close over no traced value); the lengths are matched to ``tolerance`` (m)."""
    settings = jax.lax.stop_gradient(settings)
    t, ok = newton_solve(solve, jax.lax.stop_gradient(model), settings, tolerance)
    t = implicit(TensionProblem(solve), (model, settings), t)
    idx = jnp.asarray(displaced(model.structure))
    return model.replace(tendon_tension=model.tendon_tension.at[idx].set(t)), ok
