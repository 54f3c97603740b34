"""Static equilibrium on SE(3)^N: Newton with load continuation and line search, and
gradients of the equilibrium by the implicit function theorem (spec algorithm.md section 5).

``solve_static(model)`` is pure and jit-compiled once per model structure: the whole
continuation (adaptive load steps, Newton iterations, backtracking) runs inside
``lax.while_loop``. Its output is differentiable with respect to every array of the Model
(stiffness, loads, gravity, reference geometry) in forward and reverse mode: the Newton
iterations are not unrolled; the tangent of the converged solution is
``dxi = -K_t^-1 (dr/dparams . dparams)`` (spec section 5, last item), solved with the same
block-tridiagonal tangent through ``lax.custom_linear_solve`` (its transpose for reverse mode).

The package: :mod:`.settings` (:class:`StaticSettings`, :class:`Equilibrium`),
:mod:`.newton` (one Newton solve at a load level), :mod:`.branch` (the stability watch
between load levels that keeps the continuation on the stable branch past a critical
load), and here the load continuation, the implicit derivative and :func:`solve_static`.
"""
from __future__ import annotations

import dataclasses
from functools import partial
from typing import NamedTuple

import jax
import jax.interpreters.ad
import jax.numpy as jnp

import numpy as np

from .. import compile_cache, swept_check
from ...couplings import coupling
from ...math import lie
from ...math.lanes import any_lane
from ...math.xla import jit, traced
from ...physics.assembly import residual, residual_and_tangent
from ...math.linalg import implicit_solve_coupled
from ...model.loads import full_loads
from ...model.model import Model
from ..newton import RUNNING, implicit, step_norm, weighted_norm  # noqa: F401
from ..status import Status, raise_if_failed
# the package's names, re-exported (batched sweeps, the dynamics, results import them here)
from . import branch
from .newton import (NewtonState, newton_solve, no_tangent, update_frames,  # noqa: F401
                     at_level, contact_status, level_tolerance, load_scale, max_load_step,
                     newton_outcome, newton_pass, newton_start, settled, settling_force)
from .settings import Equilibrium, StaticSettings, as_traced, settings_from_scene  # noqa: F401


def _secant(R, p, R_prev, p_prev, ratio, kick):
    """Lie-group secant predictor ``H exp(ratio d + kick)`` per node (spec 5), with the
    last step's increment ``d = log(H_prev^-1 H)`` and a branch-switching move ``kick``
    (N,6) (zero but right after a switch, :mod:`.branch`): ``(R, p, d)``."""
    def one(Ri, pi, Rq, pq, k):
        d = lie.log_se3(lie.relative_pose(Rq, pq, Ri, pi))
        return lie.compose_exp(Ri, pi, ratio * d + k) + (d,)
    return jax.vmap(one)(R, p, R_prev, p_prev, kick)


class ContinuationState(NamedTuple):
    """Carry of :func:`_continuation`: the last accepted frames (R, p) at load level lam,
    the ones before (R_prev, p_prev at lam_prev) for the secant predictor, the next load
    increment dlam, counters, the residual at the last accepted level, and the status of
    the last failed Newton solve (cause); y, y_prev: the multipliers (joint multipliers,
    displacement-controlled tendons' tensions) at lam and lam_prev; tangent: the chains' tangent blocks at (R, p) (zero before a level is
    accepted); stable: the tangent at the last accepted level is positive definite (False
    before one is accepted: not known); kick: the branch-switching move (N,6) added to
    the next trial's prediction (zero but right after a switch); kicked: a switch was
    tried since the last accepted level (:mod:`.branch`); settled: the last accepted
    level is at the full loads and its settling springs' force is below the tolerance
    (:func:`.newton.settled`; True from the start without settling rods); friction_R,
    friction_p: the reference of the quasi-static friction at the full loads, the last
    accepted level below them (:func:`friction_reference`)."""
    R: jax.Array
    p: jax.Array
    R_prev: jax.Array
    p_prev: jax.Array
    y: jax.Array
    y_prev: jax.Array
    lam: jax.Array
    lam_prev: jax.Array
    dlam: jax.Array
    accepted: jax.Array
    failures: jax.Array
    iterations: jax.Array
    attempts: jax.Array
    residual: jax.Array
    cause: jax.Array
    tangent: tuple
    stable: jax.Array
    kick: jax.Array
    kicked: jax.Array
    settled: jax.Array
    friction_R: jax.Array
    friction_p: jax.Array


def friction_reference(c: ContinuationState):
    """The frames (R, p) the quasi-static friction of the next level slips from: the last
    accepted level, but at the full loads the last one below them, so that the repeated
    full-load levels of the settling (:func:`.newton.settling_force`) do not let the
    friction creep (its regularized law carries a force with a slip of order ``u_s`` at
    every level it is measured from)."""
    below = c.lam < 1.0
    return jnp.where(below, c.R, c.friction_R), jnp.where(below, c.p, c.friction_p)


def trial_level(model: Model, c: ContinuationState):
    """The next load level of the continuation, the secant prediction of its frames
    (moved by ``c.kick`` after a branch switch) and multipliers, and the last load
    step's increment ``d`` (N,6) (body-frame twists ``log(H_prev^-1 H)``, for
    :func:`after_newton`): ``(lam_try, R, p, y, d)``."""
    lam_try = c.lam + c.dlam
    lam_try = jnp.where(lam_try > 1.0 - 1e-9, 1.0, lam_try)  # no sliver step from round-off
    ratio = (lam_try - c.lam) / jnp.maximum(c.lam - c.lam_prev, 1e-300)
    ratio = jnp.where(c.accepted >= 1, ratio, 0.0)
    # a prediction that would carry a rod through an obstacle or another rod is cut back
    ratio = swept_check.cut_back(
        model, c.p, lambda t: _secant(c.R, c.p, c.R_prev, c.p_prev, t, c.kick)[1], ratio)
    Rs, ps, d = _secant(c.R, c.p, c.R_prev, c.p_prev, ratio, c.kick)
    return lam_try, Rs, ps, c.y + ratio * (c.y - c.y_prev), d


def after_newton(model: Model, settings: StaticSettings, c: ContinuationState, d, lam_try,
                 R, p, y, its, res, status, tangent, positive) -> ContinuationState:
    """The continuation carry after the Newton solve at ``lam_try`` ended with ``status``:
    a converged level is accepted and the increment grows by 1.5 after an easy solve (fewer
    than 5 steps), up to :func:`max_load_step`; a failed one halves the increment. A level
    that converged to an unstable state right after a stable one is refused
    (:mod:`.branch`): the increment is halved, and at its smallest the level is tried
    once more from a prediction moved toward the stable branch (along the critical mode,
    to the side of the last load step's increment ``d`` (N,6) of :func:`trial_level`);
    after that try it is accepted. With settling rods (:func:`.newton.settling_force`) the
    full-load level is repeated, each one sprung to the one before, until one is
    settled (:func:`.newton.settled`). A solve made non-finite by more rod-rod candidate
    pairs than ``[contact] max_pairs`` fails with ``CONTACT_PAIRS``
    (:func:`.newton.contact_status`), the cause a stopped continuation reports. The
    other arguments are :func:`newton_outcome`'s."""
    status = contact_status(model, R, p, status)
    converged = status == Status.CONVERGED
    stable_now, lost, kick = _watch(model, c, d, converged, tangent, positive)
    dlam_min = settings.min_step_fraction / settings.load_steps
    refine = lost & (0.5 * c.dlam >= dlam_min)
    switch = lost & ~refine & ~c.kicked & jnp.any(kick != 0.0)
    ok = converged & ~refine & ~switch
    grow = jnp.where(its < 5, 1.5, 1.0)
    keep = lambda new, old: jnp.where(ok, new, old)  # noqa: E731
    return ContinuationState(
        R=keep(R, c.R), p=keep(p, c.p), R_prev=keep(c.R, c.R_prev),
        p_prev=keep(c.p, c.p_prev), y=keep(y, c.y), y_prev=keep(c.y, c.y_prev),
        lam_prev=keep(c.lam, c.lam_prev),
        lam=keep(lam_try, c.lam),
        dlam=jnp.where(ok, jnp.minimum(c.dlam * grow, max_load_step(model, settings)),
                       jnp.where(switch, c.dlam, 0.5 * c.dlam)),
        accepted=c.accepted + ok, failures=c.failures + (~ok),
        iterations=c.iterations + its, attempts=c.attempts + 1,
        residual=keep(res, c.residual), cause=jnp.where(ok | converged, c.cause, status),
        tangent=jax.tree_util.tree_map(keep, tangent, c.tangent),
        stable=keep(stable_now, c.stable), kick=jnp.where(switch, kick, 0.0),
        kicked=~ok & (c.kicked | switch),
        settled=keep((lam_try >= 1.0) & settled(model, settings, R, p, (c.R, c.p),
                                                load_scale(model)), c.settled),
        friction_R=jnp.where(ok & (c.lam < 1.0), c.R, c.friction_R),
        friction_p=jnp.where(ok & (c.lam < 1.0), c.p, c.friction_p))


def _watch(model: Model, c: ContinuationState, d, converged, tangent, positive):
    """``(stable, lost, kick)`` after a Newton solve that ended with tangent blocks
    ``tangent`` (:mod:`.branch`): whether that tangent is positive definite (``positive``,
    read from the Newton solve's factorization, where the tangent at an equilibrium is
    symmetric, else tested here), whether a converged solve lost the stability of the
    last accepted level, and the branch-switching move (N,6) for a lost one, to the side
    of the last load step's increment ``d`` (N,6). The test runs only when some (batched)
    lane converged, the move only when some lane lost stability."""

    zero = jnp.zeros_like(c.kick)
    if not branch.watched(model):
        return c.stable, jnp.array(False), zero

    if not branch.symmetric_at_equilibrium(model):
        positive = jax.lax.cond(any_lane(converged), lambda: branch.stable(tangent),
                                lambda: c.stable)
    lost = converged & c.stable & ~positive
    kick = jax.lax.cond(any_lane(lost), lambda: branch.critical_kick(model, tangent, d),
                        lambda: zero)
    return positive, lost, kick


def continuing(settings: StaticSettings, c: ContinuationState):
    """Whether the continuation goes on: loads not reached or not settled, increment
    above its minimum (``min_step_fraction / load_steps``), attempts left."""
    dlam_min = (1.0 / settings.load_steps) * settings.min_step_fraction
    return (((c.lam < 1.0) | ~c.settled) & (c.dlam >= dlam_min)
            & (c.attempts < settings.max_attempts))


def continuation_start(model: Model, settings: StaticSettings) -> ContinuationState:
    """The continuation carry at load level 0 (the start frames of ``model``)."""
    zero = jnp.array(0)
    y = jnp.zeros(coupling.border_sizes(model.structure)[1], model.p0.dtype)
    return ContinuationState(
        R=model.R0, p=model.p0, R_prev=model.R0, p_prev=model.p0, y=y, y_prev=y,
        lam=jnp.array(0.0),
        lam_prev=jnp.array(0.0), dlam=jnp.asarray(1.0 / settings.load_steps, jnp.float64),
        accepted=zero, failures=zero, iterations=zero, attempts=zero,
        residual=jnp.array(jnp.inf), cause=jnp.array(int(Status.NOT_RUN)),
        tangent=no_tangent(model.p0), stable=jnp.array(False),
        kick=jnp.zeros(model.p0.shape[:1] + (6,), model.p0.dtype), kicked=jnp.array(False),
        settled=jnp.array(not model.structure.settling),
        friction_R=model.R0, friction_p=model.p0)


def continuation_result(settings: StaticSettings, c: ContinuationState) -> Equilibrium:
    """The :class:`Equilibrium` of a finished continuation carry: at the full loads but not
    settled, status UNRESTRAINED (a motion the supports leave free kept moving)."""
    converged = (c.lam >= 1.0) & c.settled
    status = jnp.where(converged, Status.CONVERGED,
                       jnp.where(c.lam >= 1.0, Status.UNRESTRAINED,
                                 jnp.where(c.attempts >= settings.max_attempts,
                                           Status.MAX_ATTEMPTS, Status.STEP_TOO_SMALL)))
    return Equilibrium(c.R, c.p, converged, c.iterations, c.residual, c.lam, c.accepted,
                       c.failures, status, c.cause, c.y if c.y.size else None,
                       previous=(c.friction_R, c.friction_p), tangent=c.tangent,
                       tangent_positive=c.stable)


def _continuation(model: Model, settings: StaticSettings) -> Equilibrium:
    """Adaptive load continuation lam: 0 -> 1 with Newton at each level (spec section 5)."""
    ref = load_scale(model)

    def body(c: ContinuationState) -> ContinuationState:
        lam_try, Rs, ps, ys, d = trial_level(model, c)
        outcome = newton_solve(model, settings, Rs, ps, ys, lam_try, ref,
                               friction_reference(c), (c.R, c.p))
        return after_newton(model, settings, c, d, lam_try, *outcome)

    c = jax.lax.while_loop(lambda c: continuing(settings, c), body,
                           continuation_start(model, settings))
    return continuation_result(settings, c)


@dataclasses.dataclass(frozen=True)
class EquilibriumProblem:
    """The static equilibrium as an implicit problem for :func:`simsoft_jax.solvers.newton.implicit`
    (spec section 5): ``params = (model, converged, previous, kept)``, ``solution = (R, p, y)``
    (frames and multipliers: joint multipliers, displacement-controlled tendons' tensions,
    :func:`.newton.at_level`), increments ``(dx (N,6), dy (M,))`` on the right of the
    frames. Held dofs follow the start frames ``model.R0, model.p0`` (a clamp holds its
    node there). With quasi-static friction (``previous``: the frames of the level before
    the last, else None) the derivative is that of the last level's equilibrium with
    ``previous`` held fixed: the history of the earlier levels is not differentiated
    (exact for stations sliding in a direction the parameters do not turn, as the
    friction (F1) is then ``mu f_n`` whatever the slip's size; an approximation for
    sticking stations). With settling rods (:func:`.newton.settling_force`) the tangent
    holds the settling springs: a motion nothing else holds (neutral) keeps its converged
    value in the derivative. ``tangent``: the tangent path of the solve. ``kept``: the
    solve's own tangent blocks at the solution (``Equilibrium.tangent``, settling springs
    included), used as they are instead of assembled again (a smaller gradient program),
    or None; they are not differentiated, so a derivative of the derivative needs None."""
    tangent: str

    def prescribed(self, params, solution):
        """An increment whose derivative in the model is the held dofs' motion (zero on
        the free dofs): translations ``R^T dp0``, rotations ``vee(R^T dR0)`` (its value
        is not used)."""
        model = params[0]
        R, _, y = solution
        held = 1.0 - model.structure.free_mask()
        A = jnp.einsum("nji,njk->nik", R, model.R0)
        rot = 0.5 * jnp.stack([A[:, 2, 1] - A[:, 1, 2], A[:, 0, 2] - A[:, 2, 0],
                               A[:, 1, 0] - A[:, 0, 1]], axis=1)
        moved = jnp.concatenate([jnp.einsum("nji,nj->ni", R, model.p0), rot], axis=1)
        return held * moved, jnp.zeros_like(y)

    def residual(self, params, solution, delta):
        model, _, previous, _ = params
        R, p, y = solution
        Rx, px = update_frames(R, p, delta[0])
        level = at_level(model, y + delta[1], 1.0)
        return coupling.coupled_residual(level, Rx, px, y + delta[1],
                                         residual(level, Rx, px, 1.0, previous))

    def linear_solve(self, params, solution, rhs):
        model, _, previous, kept = params
        R, p, y = solution
        level = at_level(model, y, 1.0)
        if kept is not None:   # the residual is not read: only the matrix is used here
            r, tangent = jnp.zeros(p.shape[:1] + (6,), p.dtype), kept
        else:
            r, tangent = residual_and_tangent(level, R, p, 1.0, self.tangent, previous)
        if model.structure.settling and kept is None:   # the settling springs (zero force
            k = settling_force(model, R, p, (R, p), load_scale(model))[1]   # at the solution)
            tangent = (tangent[0] + jax.vmap(jnp.diag)(k),) + tuple(tangent[1:])
        system = coupling.couple(level, R, p, y, r, tangent)
        x, z = implicit_solve_coupled(system.blocks, system.B, system.C, system.D, *rhs,
                                      model.structure.identity_nodes())
        return coupling.split(model.structure, x, z)

    def merge(self, params, solution, free, moved):
        held = 1.0 - params[0].structure.free_mask()
        return jnp.where(held > 0, moved[0], free[0]), free[1]

    def push(self, params, solution, delta):
        """d/dt [R exp(t dxi)] at t = 0: ``(R skew(dxi_w), R dxi_u)``, and dy."""
        R, p, y = solution
        dxi, dy = delta
        return (jnp.einsum("nij,njk->nik", R, jax.vmap(lie.skew)(dxi[:, 3:])),
                jnp.einsum("nij,nj->ni", R, dxi[:, :3]), dy)

    def valid(self, params):
        return params[1]


def equilibrium(model: Model, settings: StaticSettings, continuation=None,
                keep_tangent: bool = False) -> Equilibrium:
    """The continuation (default :func:`_continuation`; the batched sweeps pass their
    flattened one) under the full loads, with the implicit derivative attached
    (:func:`with_derivative`). Displacement-controlled tendons border its Newton system
    (their tensions are multipliers, :func:`.newton.at_level`). ``keep_tangent``: return
    the last Newton pass's tangent blocks as ``Equilibrium.tangent`` (not differentiated;
    for the stability count) and, where the continuation watched stability, whether
    they are positive definite (``Equilibrium.tangent_positive``), else None."""
    model = full_loads(model)
    eq = (continuation or _continuation)(jax.lax.stop_gradient(model),
                                         jax.lax.stop_gradient(settings))
    watched = keep_tangent and branch.watched(model)
    eq = eq._replace(previous=eq.previous if model.obstacle_friction is not None else None,
                     tangent=eq.tangent if keep_tangent else None,
                     tangent_positive=eq.tangent_positive if watched else None)
    return with_derivative(eq, model, settings.tangent)


def with_derivative(eq: Equilibrium, model: Model, tangent: str,
                    kept: bool = False) -> Equilibrium:
    """``eq``, solved for ``model`` (under its full loads), carrying the implicit
    derivative in ``model`` (:class:`EquilibriumProblem`, ``tangent`` its tangent path),
    with the tendons' tensions: as given, the displacement-controlled ones from the
    multipliers (None without tendons, as a zero-size output would trouble batched
    maps). ``kept``: the derivative factorizes the solve's tangent blocks
    ``eq.tangent`` (first derivatives only; not with settling rods, whose springs the
    solve scaled to its last load level) instead of assembling them again."""
    y = jnp.zeros(0) if eq.multipliers is None else eq.multipliers   # None: no multipliers
    blocks = eq.tangent if kept and not model.structure.settling else None
    R, p, y = implicit(EquilibriumProblem(tangent),
                       (model, eq.converged, eq.previous, blocks), (eq.R, eq.p, y))
    tension = (coupling.with_multipliers(model, y).tendon_tension
               if model.structure.tendon_names else None)
    return eq._replace(R=R, p=p, multipliers=None if eq.multipliers is None else y,
                       tendon_tension=tension)


@jit(static_argnames="tangent")
def differentiable(eq: Equilibrium, model: Model, tangent: str) -> Equilibrium:
    """``eq``, solved for ``model``, with the implicit derivative in ``model`` attached
    outside the compiled solve (:func:`with_derivative`): ``jax.grad`` or ``jax.jvp`` of
    a function calling :func:`solve_static` outside ``jit`` runs the solve's compiled
    program as it is and compiles only the small tangent program (``tangent``: its
    tangent path)."""
    return with_derivative(eq, full_loads(model), tangent)


def _solved(eq: Equilibrium):
    """The differentiated fields of ``eq``: frames, multipliers, tendons' tensions."""
    return eq.R, eq.p, eq.multipliers, eq.tendon_tension


@partial(jax.custom_vjp, nondiff_argnums=(0,))
def _reverse_only(tangent: str, eq: Equilibrium, model: Model):
    """:func:`_solved` of :func:`differentiable` with a reverse mode of its own: the
    backward pass is one program compiled on arrays and kept in the cache folder
    (:func:`stored_static_gradient`, with this package's compile options, which a program
    compiled under JAX's own reverse mode cannot take) instead of the two that JAX's
    linearization and transpose of the implicit derivative compile. It differentiates
    only the model's arrays that are perturbed (a gradient in the stiffness alone: 2550
    StableHLO operations instead of 3628 for all of them)."""
    return _solved(differentiable(eq, model, tangent))


def _reverse_only_forward(tangent, eq, model):
    is_primal = lambda x: isinstance(x, jax.custom_derivatives.CustomVJPPrimal)  # noqa: E731
    perturbed = tuple(x.perturbed for x in jax.tree_util.tree_leaves(model, is_leaf=is_primal))
    eq, model = jax.tree_util.tree_map(lambda x: x.value, (eq, model), is_leaf=is_primal)
    return _reverse_only(tangent, eq, model), (eq, model, perturbed)


def _reverse_only_backward(tangent, saved, bar):
    from ..dynamics.adjoint import differentiated   # the dynamics import this package
    eq, model, perturbed = saved
    symbolic = lambda x: isinstance(x, jax.custom_derivatives.SymbolicZero)  # noqa: E731
    bar = jax.tree_util.tree_map(
        lambda x: np.zeros(x.aval.shape, x.aval.dtype) if symbolic(x) else x, bar,
        is_leaf=symbolic)
    _, _, cotangent = differentiated(model, perturbed)
    program = stored_static_gradient(tangent, perturbed, (eq, model, bar))
    return None, cotangent(program(eq, model, bar))


_reverse_only.defvjp(_reverse_only_forward, _reverse_only_backward, symbolic_zeros=True)


def static_cotangent(eq: Equilibrium, model: Model, bar, tangent: str,
                     perturbed=None) -> list:
    """The cotangents of the float arrays of ``model`` that ``perturbed`` (a bool per
    leaf of ``model``; None: all) marks, in the order of its leaves, for the cotangents
    ``bar`` of :func:`_solved` of ``eq`` with the implicit derivative attached
    (:func:`with_derivative`, ``tangent`` its tangent path): reverse mode through it
    (spec section 5: one transposed solve with the tangent at ``eq``)."""
    from ..dynamics.adjoint import differentiated   # the dynamics import this package
    if perturbed is None:
        perturbed = [True] * len(jax.tree_util.tree_leaves(model))
    floats, rebuild, _ = differentiated(model, perturbed)
    _, pullback = jax.vjp(lambda f: _solved(with_derivative(
        eq, full_loads(rebuild(f)), tangent, kept=eq.tangent is not None)), floats)
    return pullback(bar)[0]


def stored_static_gradient(tangent: str, perturbed: tuple, args):
    """:func:`static_cotangent` for the model's leaves ``perturbed`` (a bool each)
    compiled for arguments ``args = (eq, model, bar)`` of this structure, shapes and
    types: once per process (kept in :data:`~simsoft_jax.solvers.programs.PROGRAMS`) and
    kept in the cache folder, so that a later process loads it instead of tracing and
    compiling it again (:func:`~simsoft_jax.solvers.compile_cache.compile_stored`; said
    on stderr when compiled). Call it as ``program(eq, model, bar)``."""
    from ..programs import PROGRAMS   # it imports this package
    leaves, tree = jax.tree_util.tree_flatten(args)
    key = ("static gradient", tangent, perturbed, tree, compile_cache.leaf_signature(leaves))
    if key not in PROGRAMS:
        def static_gradient(eq, model, bar):
            return static_cotangent(eq, model, bar, tangent, perturbed)

        from ..dynamics.adjoint import differentiated   # the dynamics import this package
        floats = differentiated(args[1], perturbed)[0]
        # LLVM's O1: less compile time, same run time (simsoft_jax.math.xla)
        PROGRAMS[key] = compile_cache.compile_stored(
            jit(static_gradient, optimization_level=1), args,
            jax.tree_util.tree_structure(floats), "static gradient",
            variant=repr((tangent, perturbed)))
    return PROGRAMS[key]


def _compiled(model: Model, settings: StaticSettings, tangent: bool = False) -> Equilibrium:
    """The equilibrium of plain arrays by ``sj.run``'s compiled static program for this
    structure (:func:`simsoft_jax.solvers.programs.compiled_static_solver`, the stability count
    switched off), so that both share one program; with its tangent blocks at the
    solution when ``tangent``."""
    from ..programs import compiled_static_solver   # it imports this package
    from ..dynamics.driver import with_arrays
    model = with_arrays(model)
    solver, _ = compiled_static_solver(model, settings)
    return solver(model, as_traced(settings), np.bool_(False), tangent=tangent)[0]


def forward_mode(model: Model) -> bool:
    """Whether ``model``'s arrays are traced by JAX's forward mode (``jax.jvp``,
    ``jax.jacfwd``; reverse mode traces them by linearization)."""
    return any(isinstance(x, jax.interpreters.ad.JVPTracer)
               for x in jax.tree_util.tree_leaves(model))


@jit
def static_program(model: Model, settings: StaticSettings) -> Equilibrium:
    return equilibrium(model, settings)


def solve_static(model: Model, settings: StaticSettings = StaticSettings(),
                 throw: bool = False) -> Equilibrium:
    """Static equilibrium of ``model`` under its full loads (spec S70-S71).

    Returns an :class:`Equilibrium`; when ``converged`` is False, ``status``/``cause``
    and :meth:`Equilibrium.message` say why, ``load_level`` how far the continuation got,
    and R, p hold the last converged state. Compiled once per model structure and
    ``tangent`` (the settings that are numbers are traced). Differentiable in all Model
    arrays (implicit function theorem); the derivative of a non-converged solve is NaN.
    ``throw=True`` raises :class:`~simsoft_jax.solvers.status.SolveError` instead of returning a
    failed solve.

    Called on arrays (not inside ``jit``, ``vmap`` or ``grad``) it runs the program of
    :func:`~simsoft_jax.run` for this structure and ``tangent`` (one compile
    for both, said on stderr, kept in the cache folder:
    :func:`~simsoft_jax.solvers.programs.compiled_static_solver`) and returns NumPy arrays;
    traced, :func:`static_program`, compiled with the enclosing computation (JAX's
    persistent cache keeps it, :func:`~simsoft_jax.solvers.compile_cache.enable`). Under
    ``jax.grad`` or ``jax.jvp`` (not inside ``jit``) it runs that compiled solve too, and
    compiles only the derivative: forward mode the tangent program
    (:func:`differentiable`), reverse mode one backward program kept in the
    cache folder (:func:`stored_static_gradient`). ``jax.linearize`` of it outside
    ``jit`` is reverse mode only (JAX's custom_vjp error); inside ``jit`` every mode
    works.
    """
    compile_cache.enable()
    if not traced(model, settings):
        eq = _compiled(model, settings)
    else:   # the program's answer, its derivative attached by a program of its own
        primal = jax.lax.stop_gradient(model)   # plain arrays under an eager grad or jvp
        if traced(primal, settings):
            eq = differentiable(static_program(primal, as_traced(settings)), model,
                                settings.tangent)
        elif forward_mode(model):
            eq = differentiable(_compiled(primal, settings), model, settings.tangent)
        else:   # reverse mode (jax.grad, jax.vjp): a backward program of its own
            eq = _compiled(primal, settings, tangent=True)
            R, p, y, tension = _reverse_only(settings.tangent, eq, model)
            eq = eq._replace(R=R, p=p, multipliers=y, tendon_tension=tension, tangent=None)
    if throw:
        raise_if_failed("static", eq.converged, eq.status, eq.cause, eq.load_level,
                        eq.residual_norm)
    return eq
