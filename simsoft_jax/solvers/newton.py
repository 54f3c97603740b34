"""The Newton core of the static and dynamic solvers, and their one implicit derivative.

Both solvers iterate ``x <- x + dx`` with ``J dx = -r`` on the nodal frames (and the
couplings' unknowns, :mod:`simsoft_jax.couplings.coupling`) inside one ``lax.while_loop`` that runs
while the carry's status is :data:`RUNNING`. They differ only in their policy, a pass
function of the carry: the static policy (:mod:`simsoft_jax.solvers.statics.newton`) builds the
tangent at every iterate and backtracks on a natural-level divergence test inside a load
continuation; the dynamic policy (:mod:`simsoft_jax.solvers.dynamics.newton`) reuses a factorized
iteration matrix over iterations and steps (chord iterations) and sub-steps a macro step
on failure. What is shared lives here: the loop (:func:`iterate`), the unit-consistent
norms (spec 4.7.9), the cap on a step's nodal rotations (spec 4.7.6), the status ladder
(:func:`ladder`), the bordered Newton step (:func:`coupled_step`) and the implicit
derivative of a converged solution (:func:`implicit`, spec section 5).
"""
from __future__ import annotations

from functools import partial

import jax
import jax.numpy as jnp

from ..couplings import coupling
from ..math.xla import jit
from ..math.linalg import factorize_coupled, solve_coupled
from .status import Status

RUNNING = -1
"""Status of a Newton carry that has not ended (every ended one holds a :class:`Status`)."""


def weighted_norm(model, r):
    """Unit-consistent norm (N) of a nodal residual r (N,6): forces in N, moments divided
    by ``char_length`` (spec 4.7.9)."""
    return jnp.sqrt(jnp.sum(r[:, :3] ** 2) + jnp.sum((r[:, 3:] / model.char_length) ** 2))


def step_norm(model, dx):
    """Largest nodal increment of dx (N,6): translation / char_length and rotation (rad)."""
    trans = jnp.linalg.norm(dx[:, :3], axis=1) / model.char_length
    rot = jnp.linalg.norm(dx[:, 3:], axis=1)
    return jnp.max(jnp.maximum(trans, rot))


def step_size(model, dx):
    """Weighted 2-norm of a Newton step dx (N,6): translations / char_length, rotations in
    rad."""
    return jnp.sqrt(jnp.sum((dx[:, :3] / model.char_length) ** 2) + jnp.sum(dx[:, 3:] ** 2))


def residual_norm(model, system: coupling.Coupled, ref):
    """Weighted size (N) of a bordered system's residual: the chains' (:func:`weighted_norm`)
    and the couplings' own (:func:`simsoft_jax.couplings.coupling.violation`: coupling-node forces,
    and joint gaps / char_length and rotations times the load scale ``ref``, so that a
    converged solve holds its joints to the tolerance of the length)."""
    res = weighted_norm(model, system.r)
    violation = coupling.violation(model, system.r_z)
    if violation is None:
        return res
    forces, gaps = violation
    return jnp.sqrt(res ** 2 + forces ** 2 + (ref * gaps) ** 2)


def capped(limit, dx, dy):
    """The Newton step ``(dx (N,6), dy (M,))`` scaled down so that no nodal rotation in dx
    exceeds ``limit`` (rad) (spec 4.7.6: keeps the iteration on the rotation branch)."""
    rot = jnp.max(jnp.linalg.norm(dx[:, 3:], axis=1))
    cap = jnp.minimum(1.0, limit / jnp.maximum(rot, 1e-300))
    return dx * cap, dy * cap


def ladder(converged, failures):
    """The status after a pass: CONVERGED where ``converged``, else the code of the first
    true condition of ``failures`` (a sequence of ``(condition, Status)``), else
    :data:`RUNNING`."""
    status = jnp.where(converged, Status.CONVERGED, RUNNING)
    for condition, code in failures:
        status = jnp.where((status == RUNNING) & condition, code, status)
    return status


def iterate(one_pass, start):
    """Run ``one_pass`` (carry -> carry) from ``start`` while the carry's ``status`` is
    :data:`RUNNING`; every policy's pass ends the loop by a status."""
    return jax.lax.while_loop(lambda c: c.status == RUNNING, one_pass, start)


def factorize(model, system: coupling.Coupled):
    """The factors of a bordered system ``[[K, B], [C, D]]`` (:func:`simsoft_jax.couplings.coupling.couple`;
    :func:`simsoft_jax.math.linalg.factorize_coupled`), held nodes' identity rows skipped."""
    return factorize_coupled(system.blocks, system.B, system.C, system.D,
                             model.structure.identity_nodes())


def coupled_step(model, factors, r, r_z):
    """The Newton step ``(dx (N,6), dy (M,))`` of a bordered system with residuals r (N,6)
    and r_z (m,): ``[[K, B], [C, D]] [x; z] = -[r; r_z]`` with the ``factors`` of
    :func:`factorize` (new, or reused over chord iterations), split into nodal increments
    and multipliers (:func:`simsoft_jax.couplings.coupling.split`)."""
    return coupling.split(model.structure, *solve_coupled(factors, -r, -r_z))


@partial(jax.custom_jvp, nondiff_argnums=(0,))
def implicit(problem, params, solution):
    """``solution``, carrying the implicit-function derivative of ``problem`` (spec section
    5, last item): for a solution ``x*(params)`` of ``F(params, x) = 0``,
    ``dx = -J^-1 dF/dparams . dparams`` with the dofs the problem prescribes (held nodes,
    a drive's motion) following their prescribed motion instead.

    ``problem`` (hashable, static) gives, for the traced ``params`` and ``solution``
    pytrees: ``prescribed(params, solution)`` -> the unknowns' increment whose derivative
    in ``params`` is the prescribed motion (zero where free); ``residual(params,
    solution, delta)`` -> F at the solution moved by the increment ``delta``;
    ``linear_solve(params, solution, rhs)`` -> ``J^-1 rhs`` on the free unknowns (inside
    ``lax.custom_linear_solve`` so that reverse mode transposes it with the same
    factors); ``merge(params, solution, free, moved)`` -> one increment from the free part
    and the prescribed part; ``push(params, solution, delta)`` -> the solution's tangent for the
    increment ``delta``; ``valid(params)`` -> whether the solve converged (the derivative
    of a failed solve is NaN: there is no solution to differentiate)."""
    return solution


@implicit.defjvp
def _implicit_jvp(problem, primals, tangents):
    params, solution = primals
    return solution, implicit_tangent(problem, params, solution, tangents[0])


@jit(static_argnums=0)
def implicit_tangent(problem, params, solution, dparams):
    """The tangent of :func:`implicit`'s solution for the parameter tangent ``dparams``: one
    compiled program of its own (linear in ``dparams``), so that the gradient of a solve
    called outside ``jit`` reuses the solve's compiled program and compiles only this
    (and its transpose) rather than the solve again."""
    _, moved = jax.jvp(lambda q: problem.prescribed(q, solution), (params,), (dparams,))
    _, dr = jax.jvp(lambda q, d: problem.residual(q, solution, d),
                    (params, jax.tree_util.tree_map(jnp.zeros_like, moved)), (dparams, moved))
    free = problem.linear_solve(params, solution, jax.tree_util.tree_map(jnp.negative, dr))
    delta = problem.merge(params, solution, free, moved)
    scale = jnp.where(problem.valid(params), 1.0, jnp.nan)
    delta = jax.tree_util.tree_map(lambda d: d * scale, delta)
    return problem.push(params, solution, delta)


def implicit_cotangent(problem, params_of, x, solution, cotangent):
    """The cotangent of ``x`` for the cotangent ``cotangent`` of :func:`implicit`'s
    solution at the parameters ``params_of(x)``: the transpose of
    :func:`implicit_tangent` (the discrete adjoint), ``x`` the differentiated inputs
    (a pytree of float arrays) the parameters are made of.

    With the free unknowns' cotangent ``c`` (from the transposed ``merge``), the adjoint
    ``lambda = J^-T c`` is one transposed solve (``problem.system_solve`` transposed:
    ``lax.custom_linear_solve``'s ``transpose_solve``); then ``-lambda . dF/dx`` (one
    reverse pass of the residual), plus the prescribed dofs' part through
    ``prescribed``. The problem gives, besides :func:`implicit`'s methods,
    ``residual_and_system(params, solution, delta)`` -> ``(residual, system)``: the
    residual and the iteration matrix from one evaluation (the residual differentiated,
    the matrix kept: one trace of their shared kinematics, not two), and
    ``system_solve(params, system, rhs)`` -> ``J^-1 rhs`` with that matrix."""
    params = params_of(x)
    moved, prescribed_vjp = jax.vjp(lambda y: problem.prescribed(params_of(y), solution), x)
    zeros = jax.tree_util.tree_map(jnp.zeros_like, moved)
    _, push_vjp = jax.vjp(lambda d: problem.push(params, solution, d), zeros)
    scale = jnp.where(problem.valid(params), 1.0, jnp.nan)
    delta = jax.tree_util.tree_map(lambda d: d * scale, push_vjp(cotangent)[0])
    _, merge_vjp = jax.vjp(lambda f, m: problem.merge(params, solution, f, m), zeros, zeros)
    free, moved_bar = merge_vjp(delta)
    r, residual_vjp, system = jax.vjp(
        lambda y, d: problem.residual_and_system(params_of(y), solution, d), x, zeros,
        has_aux=True)
    adjoint = jax.linear_transpose(lambda rhs: problem.system_solve(params, system, rhs),
                                   r)(free)[0]
    x_bar, moved_more = residual_vjp(jax.tree_util.tree_map(jnp.negative, adjoint))
    moved_bar = jax.tree_util.tree_map(jnp.add, moved_bar, moved_more)
    return jax.tree_util.tree_map(jnp.add, x_bar, prescribed_vjp(moved_bar)[0])
