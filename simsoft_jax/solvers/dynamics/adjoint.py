"""Reverse mode of a differentiable rollout by the discrete adjoint of its steps.

:func:`reverse_rollout` wraps a whole rollout in ``jax.custom_vjp``. Its forward is the
plain rollout (no derivative in it): the compiled program of :func:`~simsoft_jax.run`
when it saves every step (the per-step increments ``w`` are recovered from the saved
states), else a rollout that also keeps, per macro step, the state it started from and
its accepted sub-steps (:class:`Records`: the increments ``w`` and multipliers ``mu``).
Memory: O(steps x nodes), the states of every step. Its backward is a program of its
own, kept in the cache folder like the solvers' (:func:`stored_backward`): a reverse
``lax.scan`` over the steps. A sub-step maps ``s_n`` to ``s_{n+1} = N(s_n, w_n; q)``
(spec S54, S66) with ``w_n`` solving ``F(w, mu; s_n, q) = 0``; for the cotangent
``sbar_{n+1}``:

* ``(sbar_n, qbar, wbar) = (dN/ds_n, dN/dq, dN/dw)^T sbar_{n+1}``;
* ``lambda = J^-T wbar`` on the free unknowns (``J`` the bordered iteration matrix at the
  solution, couplings included: one factorization, its transposed solve), and
  ``-lambda . dF/d(s_n, q)`` added to ``(sbar_n, qbar)``; held dofs follow their
  prescribed motion (:func:`simsoft_jax.solvers.newton.implicit_cotangent`, the transpose
  of the forward-mode :func:`~simsoft_jax.solvers.newton.implicit_tangent`).

``q`` are the float arrays of ``(model, settings)`` that the caller differentiates (the
others are constants of the backward program, compiled once per such choice). The
derivative is the one forward mode gives (:func:`~.newton.replay`), in reverse only:
``jax.jvp`` / ``jax.jacfwd`` use ``simulate(..., differentiable="forward")``.
"""
from __future__ import annotations

import contextlib
import dataclasses
from functools import partial
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from .. import compile_cache
from ...math.xla import jit, traced
from ...physics import element, stick_slip
from ..newton import implicit_cotangent
from .newton import StepProblem, SubSteps
from .residual import element_inertia, step_functions
from .scheme import State


class Records(NamedTuple):
    """What the backward pass needs of each macro step (leading axes (blocks, steps per
    block)): start: the :class:`State` it started from; sub: its accepted sub-steps
    (:class:`~.newton.SubSteps`); count: how many; ok: whether the step was accepted
    (False after a failure: the state is frozen, nothing to differentiate)."""
    start: State
    sub: SubSteps
    count: jax.Array
    ok: jax.Array


def _add(a, b):
    return jax.tree_util.tree_map(jnp.add, a, b)


def differentiated(tree, mask):
    """``(floats, rebuild, cotangent)``: the leaves of ``tree`` that are differentiated
    (float and ``mask`` True, ``mask`` one bool per leaf), a function of such a list
    giving ``tree`` with them replaced, and one giving a cotangent of ``tree`` (None,
    a zero, at the other leaves)."""
    leaves, treedef = jax.tree_util.tree_flatten(tree)
    keep = [bool(m) and jnp.issubdtype(jnp.result_type(x), jnp.inexact)
            for x, m in zip(leaves, mask)]

    def fill(floats, other):
        it = iter(floats)
        return treedef.unflatten([next(it) if k else other(x) for x, k in zip(leaves, keep)])

    return ([x for x, k in zip(leaves, keep) if k], lambda f: fill(f, lambda x: x),
            lambda f: fill(f, lambda x: None))


def sub_step(params, state: State, fraction, w):
    """The state after a sub-step of ``fraction * dt`` with increment ``w`` (N,6) from
    ``state`` (spec S54, S66); ``params = (model, settings)``."""
    model, settings = params
    return step_functions(model, None, settings.rho_inf, state, fraction * settings.dt
                          ).new_state(w)


def sub_step_cotangent(rebuild, floats, state: State, fraction, w, mu, bar: State):
    """``(sbar_n, qbar)`` of one sub-step from ``state`` for the cotangent ``bar`` of its
    end state (see the module docstring); ``qbar`` a list like ``floats``, the
    differentiated leaves of ``rebuild(floats) = (model, settings)``."""
    _, next_vjp = jax.vjp(lambda f, s, x: sub_step(rebuild(f), s, fraction, x),
                          floats, state, w)
    q_bar, s_bar, w_bar = next_vjp(bar)

    def problem_params(x):
        model, settings = rebuild(x[0])
        return model, element_inertia(model), settings, x[1], fraction * settings.dt

    more = implicit_cotangent(StepProblem(), problem_params, (floats, state), (w, mu),
                              (w_bar, jnp.zeros_like(mu)))
    return _add(s_bar, more[1]), _add(q_bar, more[0])


def macro_step_cotangent(rebuild, floats, start: State, sub: SubSteps, count, bar: State):
    """``(sbar_n, qbar)`` of an accepted macro step of ``count`` sub-steps ``sub`` from
    ``start``, its sub-steps taken in reverse; the start of sub-step k is recomputed from
    ``start`` (explicit updates, no solve; none for the common ``count == 1``)."""
    params = rebuild(floats)

    def one(i, carry):
        s_bar, q_bar = carry
        k = count - 1 - i
        state = jax.lax.fori_loop(0, k, lambda j, s: sub_step(
            params, s, sub.fractions[j], sub.increments[j]), start)
        s_bar, q_more = sub_step_cotangent(rebuild, floats, state, sub.fractions[k],
                                           sub.increments[k], sub.multipliers[k], s_bar)
        return s_bar, _add(q_bar, q_more)

    return jax.lax.fori_loop(0, count, one, (bar, [jnp.zeros_like(x) for x in floats]))


def reverse_steps(rebuild, floats, records: Records, saved_bar: State, final_bar: State):
    """``(sbar_0, qbar)``: the cotangents of the start state and of ``floats`` (the
    differentiated leaves of ``rebuild(floats) = (model, settings)``) for the cotangents
    ``saved_bar`` of the states at the ends of the blocks of steps (stacked) and
    ``final_bar`` of the last one: a reverse scan over the steps' ``records`` (leading
    axes (blocks, steps per block)); a step not accepted (after a failure) passes its
    cotangent through."""
    zeros = [jnp.zeros_like(x) for x in floats]

    def step(carry, record: Records):
        s_bar, q_bar = carry
        s_bar, q_more = jax.lax.cond(
            record.ok, lambda b: macro_step_cotangent(rebuild, floats, record.start,
                                                      record.sub, record.count, b),
            lambda b: (b, zeros), s_bar)
        return (s_bar, _add(q_bar, q_more)), None

    def block(carry, xs):
        s_bar, q_bar = carry
        block_bar, block_records = xs
        return jax.lax.scan(step, (_add(s_bar, block_bar), q_bar), block_records,
                            reverse=True)[0], None

    return jax.lax.scan(block, (final_bar, zeros), (saved_bar, records), reverse=True)[0]


def reverse_whole_steps(rebuild, floats, start: State, R, p, v, mu, saved_bar: State,
                        final_bar: State):
    """``(sbar_0, qbar)`` as :func:`reverse_steps` for a rollout of whole steps (no
    sub-step, none failed) saved at every step: the steps' start states again from the
    saved states, then one reverse scan of :func:`sub_step_cotangent`, a step each
    (no sub-step loop, no record of failure: a smaller program to compile).

    The increments ``w_n = log((R_n, p_n)^-1 (R_{n+1}, p_{n+1}))`` (spec S54 inverted;
    :func:`~simsoft_jax.physics.element.relative_twist`); the accelerations ``vd``, ``a``
    again by the scheme's update (S66) from ``start``. ``rebuild(floats) = (model,
    settings)``; R (T,N,3,3), p (T,N,3), v (T,N,6): the saved states, the start first;
    mu (T,M): the multipliers after each step (row 0 unused); ``saved_bar`` the
    cotangents of the saved states after the start (stacked), ``final_bar`` of the last."""
    params = rebuild(floats)

    def forward(state, xs):
        R1, p1, v1 = xs
        w = jax.vmap(element.relative_twist)(state.R, state.p, R1, p1)
        return sub_step(params, state, 1.0, w)._replace(R=R1, p=p1, v=v1), (state, w)

    starts, w = jax.lax.scan(forward, start, (R[1:], p[1:], v[1:]))[1]

    def back(carry, xs):
        s_bar, q_bar = carry
        state, w_n, mu_n, bar = xs
        s_bar, q_more = sub_step_cotangent(rebuild, floats, state, 1.0, w_n, mu_n,
                                           _add(s_bar, bar))
        return (s_bar, _add(q_bar, q_more)), None

    zeros = [jnp.zeros_like(x) for x in floats]
    return jax.lax.scan(back, (final_bar, zeros), (starts, w, mu[1:], saved_bar),
                        reverse=True)[0]


class Programs(NamedTuple):
    """The rollout programs :func:`reverse_rollout` runs (module functions of
    :mod:`.rollout`): plain(model, settings, state) -> Trajectory (no derivative);
    recorded(model, settings, state) -> (Trajectory, Records); driven(model, settings,
    state) -> the Trajectory of the compiled program of :func:`~simsoft_jax.run` (from
    ``state``, or the start state when None; NumPy arrays); initial(model) -> the start
    State."""
    plain: object
    recorded: object
    driven: object
    initial: object


@jax.tree_util.register_static
@dataclasses.dataclass(frozen=True)
class Perturbed:
    """Which leaves of the model and settings are differentiated (a bool per leaf): a
    static part of the backward program."""
    model: tuple
    settings: tuple


@partial(jax.custom_vjp, nondiff_argnums=(0,))
def reverse_rollout(programs: Programs, model, settings, state):
    """The rollout ``programs.plain(model, settings, state)``, differentiated in reverse
    mode by the discrete adjoint (module docstring); derivatives of a failed rollout are
    NaN.

    Forward pass: called on arrays (not inside ``jit`` or ``vmap``) with
    ``save_every == 1`` and without stick-slip friction, from the start state or a given
    one, the compiled program of :func:`~simsoft_jax.run` (``programs.driven``: no new
    compile), whose saved states give the backward pass
    what it needs when no step was sub-stepped and none failed; otherwise
    ``programs.recorded``, which also keeps the steps' :class:`Records`. Backward pass: a
    compiled program of its own (:func:`stored_backward`), for the leaves of the model
    and settings that are differentiated."""
    return programs.plain(model, settings, state)


def _reverse_forward(programs: Programs, model, settings, state):
    is_primal = lambda x: isinstance(x, jax.custom_derivatives.CustomVJPPrimal)  # noqa: E731
    values = lambda t: jax.tree_util.tree_map(lambda x: x.value, t,  # noqa: E731
                                              is_leaf=is_primal)
    perturbed = Perturbed(*(tuple(x.perturbed for x in jax.tree_util.tree_leaves(
        t, is_leaf=is_primal)) for t in (model, settings)))
    model, settings, state = values(model), values(settings), values(state)
    concrete = not traced(model, settings, state)
    # the stick-slip anchors are not saved: their rollouts keep records
    if settings.save_every == 1 and concrete and not stick_slip.active(model):
        traj = programs.driven(model, settings, state)
        # a failed rollout has no derivative (NaN): its sub-steps need no record
        if not bool(traj.converged) or np.all(np.asarray(traj.substeps) == 1):
            # device_put: no program per shape (jnp.asarray compiles one, ~25 ms each)
            traj = jax.tree_util.tree_map(jax.device_put, traj)
            mu = (traj.multipliers if traj.multipliers is not None
                  else np.zeros(traj.time.shape + (0,)))
            return traj, (perturbed, model, settings, state,
                          (traj.R, traj.p, traj.v, mu, traj.converged), None)
    args = (model, settings, state)
    with (compile_cache.first_call("recorded rollout", args) if concrete
          else contextlib.nullcontext()):
        traj, records = programs.recorded(*args)
    return traj, (perturbed, model, settings, state, None, records)


def _reverse_backward(programs: Programs, residuals, traj_bar):
    perturbed, model, settings, state, saved, records = residuals
    zero = lambda x: (np.zeros(x.aval.shape, x.aval.dtype)  # noqa: E731
                      if isinstance(x, jax.custom_derivatives.SymbolicZero) else x)
    bar = (traj_bar.time, traj_bar.R, traj_bar.p, traj_bar.v, traj_bar.final)
    bar = jax.tree_util.tree_map(
        zero, bar, is_leaf=lambda x: isinstance(x, jax.custom_derivatives.SymbolicZero))
    args = (model, settings, state, saved, records, bar)
    if traced(args):
        return backward_program(programs, perturbed, *args)
    return stored_backward(programs, perturbed, args)(*args)


reverse_rollout.defvjp(_reverse_forward, _reverse_backward, symbolic_zeros=True)


def stored_backward(programs: Programs, perturbed: Perturbed, args):
    """The compiled :func:`backward` of ``programs`` for the differentiated leaves
    ``perturbed`` and arguments of the structure, shapes and types of ``args = (model,
    settings, state, saved, records, bar)`` (arrays): compiled once per process (kept in
    :data:`~simsoft_jax.solvers.programs.PROGRAMS`) and kept in the cache folder, so that a
    later process loads it instead of tracing and compiling it again
    (:func:`~simsoft_jax.solvers.compile_cache.compile_stored`; said on stderr when
    compiled)."""
    from ..programs import PROGRAMS    # it imports the dynamics
    leaves, tree = jax.tree_util.tree_flatten(args)
    key = ("rollout gradient", programs, perturbed, tree, compile_cache.leaf_signature(leaves))
    if key not in PROGRAMS:
        model, settings, state = args[:3]
        floats, _, cotangent = differentiated((model, settings),
                                              perturbed.model + perturbed.settings)
        out_tree = jax.tree_util.tree_structure((*cotangent(floats), state))

        def rollout_gradient(*a):
            return backward(programs, perturbed, *a)

        # LLVM's O1: less compile time, same run time (simsoft_jax.math.xla)
        program = jit(rollout_gradient, optimization_level=1)
        PROGRAMS[key] = compile_cache.compile_stored(program, args, out_tree,
                                                     "rollout gradient",
                                                     variant=repr(perturbed))
    return PROGRAMS[key]


def backward(programs: Programs, perturbed: Perturbed, model, settings, state, saved,
             records, bar):
    """The cotangents ``(model, settings, state)`` of :func:`reverse_rollout` (None at
    the leaves not differentiated) for the cotangents ``bar = (time, R, p, v, final)``
    of the trajectory (the rest has no derivative), from the steps' ``records`` or, when
    None, from the ``saved`` states ``(R, p, v, multipliers, converged)`` of every step
    (:func:`reverse_whole_steps`). The start state (``state``, or
    :func:`~.rollout.initial_state` of the model when None) is differentiated here too."""
    time_bar, R_bar, p_bar, v_bar, final_bar = bar
    floats, rebuild, cotangent = differentiated((model, settings),
                                                perturbed.model + perturbed.settings)
    if state is None:
        start, start_vjp = jax.vjp(lambda f: programs.initial(rebuild(f)[0]), floats)
    else:
        start = state
    blocks = R_bar.shape[0] - 1
    zeros = jnp.zeros((blocks,) + start.vd.shape)
    anchor = (None if start.anchor is None else
              jnp.zeros((blocks,) + start.anchor.shape))
    saved_bar = State(R_bar[1:], p_bar[1:], v_bar[1:], zeros, zeros, time_bar[1:], anchor)
    if records is None:
        *saved, converged = saved
        s_bar, q_bar = reverse_whole_steps(rebuild, floats, start, *saved, saved_bar,
                                           final_bar)
        ok = converged
    else:
        s_bar, q_bar = reverse_steps(rebuild, floats, records, saved_bar, final_bar)
        ok = jnp.all(records.ok)
    s_bar = s_bar._replace(R=s_bar.R + R_bar[0], p=s_bar.p + p_bar[0],
                           v=s_bar.v + v_bar[0], t=s_bar.t + time_bar[0])
    if state is None:
        q_bar, state_bar = _add(q_bar, start_vjp(s_bar)[0]), None
    else:
        state_bar = s_bar
    scale = jnp.where(ok, 1.0, jnp.nan)
    poison = lambda t: jax.tree_util.tree_map(lambda x: x * scale, t)  # noqa: E731
    return (*cotangent(poison(q_bar)), poison(state_bar))


backward_program = jit(backward, static_argnums=(0, 1))
""":func:`backward` compiled with the enclosing computation (a gradient inside ``jit``)."""
