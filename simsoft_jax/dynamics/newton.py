"""One generalized-alpha step: modified Newton on ``F(w) = 0`` (spec S66), its implicit
derivative, and sub-stepping of a macro step on failure.

The factorized iteration matrix ``S_t`` (S61) is kept in a :class:`~.memory.NewtonMemory`
and reused over iterations and steps while the iteration contracts; the starting guess
comes from :func:`~.memory.predicted_increment`. Held dofs (clamps, pins, drives) are
eliminated: their ``w`` is prescribed (spec 4.5). Each failed Newton solve records why
(:class:`~simsoft_jax.status.Status`: iteration limit, non-finite, off the rotation branch).
"""
from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp

from ..batched import any_lane, select
from ..linalg import Factors, factorize, implicit_solve, solve_factored
from ..drives import held_increments, slide_maps
from ..statics import step_norm, weighted_norm
from ..status import Status
from .memory import NewtonMemory, predicted_increment, remember_step
from .residual import step_functions
from .scheme import alpha_parameters

# A reused iteration matrix is kept while each correction is at most this fraction of the
# previous one (linear contraction of modified Newton); otherwise it is rebuilt for the
# next iteration (see newton_step for which corrections are kept).
_CONTRACTION_LIMIT = 0.1
_RUNNING = -1


class _NewtonCarry(NamedTuple):
    """Carry of :func:`newton_step`: the increment w, iterations so far, status (-1
    running, else a Status code), the factors in use and whether to rebuild them (fresh),
    the size of the last kept correction (previous), whether the matrix was rebuilt in
    this step (rebuilt), and the weighted residual norm at the last iterate."""
    w: jax.Array
    iterations: jax.Array
    status: jax.Array
    factors: Factors
    fresh: jax.Array
    previous: jax.Array
    rebuilt: jax.Array
    residual: jax.Array


class StepResult(NamedTuple):
    """Outcome of one Newton solve: increment w (N,6), iterations, status (Status code),
    residual (weighted norm at the last iterate, N), memory (with the matrix in use)."""
    w: jax.Array
    iterations: jax.Array
    status: jax.Array
    residual: jax.Array
    memory: NewtonMemory


def newton_step(model, inert, settings, state, h, memory: NewtonMemory) -> StepResult:
    """Modified Newton on F(w) = 0 (spec S66) from :func:`memory.predicted_increment`.

    The factorized iteration matrix ``S_t`` (S61) is reused from earlier iterations and
    earlier steps of the same size h; only the residual is evaluated at each iterate. A
    correction from a reused matrix that contracts by less than ``_CONTRACTION_LIMIT``
    (but contracts) is applied and the matrix rebuilt at the new iterate; one that does
    not contract, is not finite or leaves the rotation branch is discarded and the matrix
    rebuilt at the current iterate; the matrix is also rebuilt at the start of a step when
    the previous step rebuilt it. With a fresh matrix the iteration is exact Newton.
    Approximating ``S_t`` changes only the convergence rate, not the solution (spec 4.4).
    Converged when the estimated distance to the solution, ``|dw| theta / (1 - theta)``
    with the observed contraction ``theta`` (``|dw|`` itself at the first iteration), is
    below the tolerance. Fails (status) when a fresh matrix gives a non-finite correction
    (NONFINITE) or one that takes a nodal rotation increment to pi/2 (OFF_BRANCH), or at
    ``max_iterations`` (MAX_ITERATIONS).
    """
    fns = step_functions(model, inert, settings.rho_inf, state, h, settings.tangent)
    mask = model.structure.free_mask()
    alpha_m, alpha_f, _, beta = alpha_parameters(settings.rho_inf)
    w0 = predicted_increment(state.v, state.vd, state.a, h, memory, alpha_m, alpha_f, beta)
    w0 = jnp.where(mask > 0, w0, held_increments(model, state, fns.t1))
    sliding = bool(model.structure.slide_drives)

    def body(c: _NewtonCarry) -> _NewtonCarry:
        r = fns.newton_residual(c.w)  # once in the program; the branch builds only the matrix
        # a branch also under vmap (any_lane): lanes that keep their matrix select it back
        factors = jax.lax.cond(
            any_lane(c.fresh),
            lambda w, f: select(c.fresh, factorize(fns.residual_and_matrix(w)[1]), f),
            lambda _, f: f, c.w, c.factors)
        dw = -solve_factored(factors, r)
        if sliding:  # back from slide unknowns to increments (spec: slides_along)
            dw = jnp.einsum("nij,nj->ni", slide_maps(model, state.R, c.w)[1], dw)
        # cap nodal rotation corrections at pi/4 (spec 4.7.6): keeps Newton on the branch
        rot = jnp.max(jnp.linalg.norm(dw[:, 3:], axis=1))
        dw = dw * jnp.minimum(1.0, 0.25 * jnp.pi / jnp.maximum(rot, 1e-300))
        size = step_norm(model, dw)
        finite = jnp.all(jnp.isfinite(dw))
        off_branch = jnp.max(jnp.linalg.norm((c.w + dw)[:, 3:], axis=1)) > 0.5 * jnp.pi
        bad = ~finite | off_branch
        theta = size / c.previous
        reject = ~c.fresh & (bad | (theta >= 1.0))
        rebuild = reject | (~c.fresh & (theta > _CONTRACTION_LIMIT))
        w_new = jnp.where(reject | ~finite, c.w, c.w + jnp.where(finite, dw, 0.0))
        estimate = jnp.where(jnp.isfinite(c.previous) & (theta < _CONTRACTION_LIMIT),
                             size * theta / (1.0 - theta), size)
        converged = ~reject & finite & (estimate <= settings.tolerance)
        status = jnp.where(converged, Status.CONVERGED, _RUNNING)
        status = jnp.where((status == _RUNNING) & c.fresh & ~finite, Status.NONFINITE, status)
        status = jnp.where((status == _RUNNING) & c.fresh & off_branch, Status.OFF_BRANCH,
                           status)
        status = jnp.where((status == _RUNNING) & (c.iterations + 1 >= settings.max_iterations),
                           Status.MAX_ITERATIONS, status)
        return _NewtonCarry(w_new, c.iterations + 1, status, factors, rebuild,
                            jnp.where(reject, c.previous, size), c.rebuilt | rebuild,
                            weighted_norm(model, r))

    stale = memory.renew | (jnp.abs(memory.h - h) > 1e-9 * h)
    init = _NewtonCarry(w0, jnp.array(0), jnp.array(_RUNNING), memory.factors, stale,
                        jnp.array(jnp.inf), jnp.array(False), jnp.array(jnp.inf))
    c = jax.lax.while_loop(lambda c: c.status == _RUNNING, body, init)
    memory = memory._replace(factors=c.factors, h=jnp.asarray(h, jnp.float64),
                             renew=c.rebuilt)
    return StepResult(c.w, c.iterations, c.status, c.residual, memory)


@jax.custom_jvp
def _implicit_increment(model, inert, settings, state, h, w):
    """Identity on a converged step increment ``w``; its derivative is the implicit-function
    one: ``dw_free = -J^-1 dF`` with the held dofs following the prescribed motion."""
    return w


@_implicit_increment.defjvp
def _implicit_increment_jvp(primals, tangents):
    model, inert, settings, state, h, w = primals
    mask = model.structure.free_mask()

    def held(m, st, hh):
        return held_increments(m, st, st.t + hh)

    def F(m, ine, se, st, hh):  # residual with the free w frozen and the held w prescribed
        residual = step_functions(m, ine, se.rho_inf, st, hh).residual
        return residual(jnp.where(mask > 0, w, held(m, st, hh)))

    primal_args, tangent_args = (model, inert, settings, state, h), tangents[:5]
    _, dF = jax.jvp(F, primal_args, tangent_args)
    _, dheld = jax.jvp(held, (model, state, h), (tangents[0], tangents[3], tangents[4]))
    blocks = step_functions(model, inert, settings.rho_inf, state, h,
                            settings.tangent).residual_and_matrix(w)[1]
    dw = implicit_solve(blocks, -dF)
    return w, jnp.where(mask > 0, dw, dheld)


class Attempt(NamedTuple):
    """One step attempt: the new state, Newton iterations, status, residual, memory."""
    state: object
    iterations: jax.Array
    status: jax.Array
    residual: jax.Array
    memory: NewtonMemory


def attempt(model, inert, settings, state, h, differentiable, memory) -> Attempt:
    """One generalized-alpha step of size h; an accepted step becomes the predictor's
    history. With ``differentiable`` the increment carries the implicit derivative."""
    new_state = step_functions(model, inert, settings.rho_inf, state, h).new_state
    m, ine, se, st, hh, mem = jax.lax.stop_gradient((model, inert, settings, state, h, memory))
    res = newton_step(m, ine, se, st, hh, mem)
    w = res.w
    if differentiable:
        w = _implicit_increment(model, inert, settings, state, h, w)
    ok = res.status == Status.CONVERGED
    memory = remember_step(res.memory, st.vd, hh, ok)
    return Attempt(new_state(w), res.iterations, res.status, res.residual, memory)


class Advance(NamedTuple):
    """One macro step: state, Newton iterations (all sub-steps), accepted sub-steps,
    status (CONVERGED or STEP_TOO_SMALL), cause (last Newton failure, NOT_RUN if none),
    residual (at the last attempt), memory."""
    state: object
    iterations: jax.Array
    substeps: jax.Array
    status: jax.Array
    cause: jax.Array
    residual: jax.Array
    memory: NewtonMemory


class _AdvanceCarry(NamedTuple):
    state: object
    h: jax.Array
    iterations: jax.Array
    substeps: jax.Array
    failed: jax.Array
    cause: jax.Array
    residual: jax.Array
    memory: NewtonMemory


def advance(model, inert, settings, state, memory) -> Advance:
    """One macro step of size dt, with sub-stepping on failure (halve, up to max_halvings;
    after a success the sub-step doubles again, up to dt)."""
    dt = settings.dt
    t_target = state.t + dt
    h_min = dt / 2.0**settings.max_halvings

    def body(c: _AdvanceCarry) -> _AdvanceCarry:
        h_try = jnp.minimum(c.h, t_target - c.state.t)
        att = attempt(model, inert, settings, c.state, h_try, False, c.memory)
        ok = att.status == Status.CONVERGED
        st = jax.tree_util.tree_map(lambda x, y: jnp.where(ok, x, y), att.state, c.state)
        h = jnp.where(ok, jnp.minimum(2.0 * c.h, dt), 0.5 * c.h)
        return _AdvanceCarry(st, h, c.iterations + att.iterations, c.substeps + ok,
                             c.failed | (h < h_min * (1 - 1e-12)),
                             jnp.where(ok, c.cause, att.status), att.residual, att.memory)

    def running(c: _AdvanceCarry):
        return (c.state.t < t_target - 1e-12 * dt) & ~c.failed

    zero = jnp.array(0)
    c = jax.lax.while_loop(running, body, _AdvanceCarry(
        state, jnp.asarray(dt, jnp.float64), zero, zero, jnp.array(False),
        jnp.array(int(Status.NOT_RUN)), jnp.array(0.0), memory))
    status = jnp.where(c.failed, Status.STEP_TOO_SMALL, Status.CONVERGED)
    return Advance(c.state, c.iterations, c.substeps, status, c.cause, c.residual, c.memory)
