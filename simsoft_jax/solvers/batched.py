"""Solvers whose control flow suits ``jax.vmap``: the static continuation as one flat loop,
and a lane-wide "any" for conditions that should stay branches.

Why. Under ``jax.vmap`` a ``lax.while_loop`` runs until its slowest lane is done (finished
lanes are masked, not stopped), and a ``lax.cond`` with a batched predicate becomes a
select that evaluates both branches. The static solver nests its Newton loop inside the
load continuation loop, so a vmapped solve pays, for every continuation pass, the Newton
iterations of the slowest lane at that pass: the sum over passes of maxima. Measured on
random Princeton cases (16 elements, gravity; benchmarks/README.md): a vmapped batch of
200 cost 10-16 ms of CPU per lane against 12.8 ms for one solve alone.

:func:`flat_continuation` is the same algorithm (the same Newton passes, load levels,
secant predictions and status codes as :func:`~simsoft_jax.solvers.statics.solve_static`) written
as a single loop whose every pass is one Newton pass of one load level: a lane whose
Newton solve ends applies the continuation update and starts its next level in the next
pass. Vmapped, the loop runs for the largest number of Newton passes of any lane (the
maximum of sums), and every pass is one batched residual, tangent and factorization.
Lanes that are finished keep their carry (``vmap`` of ``while_loop`` selects it), so a
lane reports exactly the status, iterations and result it would alone. Measured
(benchmarks/README.md, "Batched sweeps"), its cost per lane does not grow with the batch
but its passes carry the secant predictor and Newton restart of every lane, so in small
chunks the nested solver is cheaper: ``sweeps`` uses the flat loop from
``sweeps.FLAT_FROM`` points per chunk on.

Conditions that should stay branches under ``vmap`` (the dynamic Newton solver's matrix
rebuild, the static solver's stability test) use :mod:`simsoft_jax.math.lanes`.
"""
from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp

from ..model.model import Model
from .statics import (Equilibrium, StaticSettings, after_newton, continuation_result,
                      continuation_start, continuing, equilibrium, friction_reference,
                      load_scale,
                      newton_outcome, newton_pass, newton_start, trial_level)
from .statics import ContinuationState, NewtonState, RUNNING


class _FlatState(NamedTuple):
    """Carry of :func:`flat_continuation`: the continuation carry, the Newton carry of the
    level being solved (lam_try), whether the next pass starts a new level (starting) and
    whether the continuation has ended (done)."""
    cont: ContinuationState
    newton: NewtonState
    lam_try: jax.Array
    starting: jax.Array
    done: jax.Array


def select(pred, new, old):
    """``new`` where the boolean scalar ``pred`` holds, else ``old`` (pytrees alike)."""
    return jax.tree_util.tree_map(lambda a, b: jnp.where(pred, a, b), new, old)


def flat_continuation(model: Model, settings: StaticSettings) -> Equilibrium:
    """The load continuation of :func:`~simsoft_jax.solvers.statics.solve_static` (spec section 5)
    as one loop of Newton passes (see the module docstring); same results and counts."""
    ref = load_scale(model)

    def body(f: _FlatState) -> _FlatState:
        lam_try, Rs, ps, ys, d = trial_level(model, f.cont)
        lam = jnp.where(f.starting, lam_try, f.lam_try)
        newton = newton_pass(model, settings, lam, ref,
                             select(f.starting, newton_start(Rs, ps, ys), f.newton),
                             friction_reference(f.cont), (f.cont.R, f.cont.p))
        ended = newton.status != RUNNING
        cont = select(ended, after_newton(model, settings, f.cont, d, lam,
                                          *newton_outcome(newton)), f.cont)
        return _FlatState(cont, newton, lam, ended, ~continuing(settings, cont))

    cont = continuation_start(model, settings)
    init = _FlatState(cont, newton_start(model.R0, model.p0, cont.y), jnp.array(0.0),
                      jnp.array(True), ~continuing(settings, cont))
    f = jax.lax.while_loop(lambda f: ~f.done, body, init)
    return continuation_result(settings, f.cont)


def solve_static_lane(model: Model, settings: StaticSettings) -> Equilibrium:
    """:func:`~simsoft_jax.solvers.statics.solve_static` for use under ``vmap`` (not jitted: the
    sweep compiles the whole batch), differentiable the same way (implicit function)."""
    return equilibrium(model, settings, flat_continuation)


