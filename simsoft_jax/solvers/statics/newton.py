"""The static policy of the Newton core (:mod:`simsoft_jax.solvers.newton`): one Newton solve at
a load level of the continuation (:mod:`simsoft_jax.solvers.statics`), a fresh tangent at every
iterate with a natural-level divergence guard and backtracking, and the load scale of the
tolerance."""
from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from ...couplings import coupling, rod_pairs, tendon_lengths
from ...math import lie
from ...math.lanes import any_lane
from ...physics.assembly import residual_and_tangent
from ...physics.inertia import line_density
from ...math.linalg import pivots_positive_definite
from ...model.model import Model
from ..newton import (RUNNING, capped, coupled_step, factorize, iterate, ladder, residual_norm,
                      step_norm, step_size, weighted_norm)
from ..status import Status
from .. import swept_check
from ...physics.terms import registry, tendons
from .branch import symmetric_at_equilibrium
from .settings import StaticSettings


def load_scale(model: Model):
    """Weighted size (N) of the full external loads, the reference of the tolerance: the
    nodal, distributed and attached loads here, the registered terms' declared shares
    (:func:`simsoft_jax.physics.terms.registry.load_scale_squared`)."""
    s = model.structure
    mask = s.free_mask()
    nodal = jnp.zeros((s.n_nodes, 6))
    if model.nodal_dead is not None:
        nodal = nodal + jnp.abs(model.nodal_dead)
    if model.nodal_follower is not None:
        nodal = nodal + jnp.abs(model.nodal_follower)
    total = jnp.sum(weighted_norm(model, nodal * mask) ** 2)
    q = jnp.zeros((s.n_elements, 3))
    if model.gravity is not None:
        rho_a = jax.vmap(line_density)(model.inertia)
        q = q + rho_a[:, None] * model.gravity
    if model.distributed_world is not None:
        q = q + model.distributed_world
    if model.distributed_local is not None:
        q = q + jnp.abs(model.distributed_local)
    total = total + jnp.sum((model.length[:, None] * q) ** 2)
    if s.offset_load_nodes:        # forces at offset points and their moments
        f = model.offset_force
        total = total + jnp.sum(f ** 2) + jnp.sum(
            (jnp.linalg.norm(model.offset_point, axis=1) * jnp.linalg.norm(f, axis=1)
             / model.char_length) ** 2)
    if s.mass_nodes and model.gravity is not None:   # weights of attached masses
        w = model.mass[:, None] * model.gravity
        total = total + jnp.sum(w ** 2) + jnp.sum(
            (jnp.linalg.norm(model.mass_offset, axis=1) * jnp.linalg.norm(w, axis=1)
             / model.char_length) ** 2)
    return jnp.sqrt(total + registry.load_scale_squared(model))


def at_level(model: Model, y, lam) -> Model:
    """The model of the bordered static system at load level ``lam`` (> 0) and multipliers
    y (M,) (:func:`simsoft_jax.couplings.coupling.border_sizes`: joint multipliers, then the
    displacement-controlled tendons' tensions t): those tendons' prescribed length changes
    grow with the loads, ``lam delta``, and their tensions are the multipliers t
    themselves. The tendon term scales its tensions by lam
    (:func:`simsoft_jax.physics.terms.tendons.force`), so they are set as ``t / lam``: the
    forces are ``t grad l`` and the border ``B = G^T`` of
    :mod:`simsoft_jax.couplings.tendon_lengths` is their derivative in t. ``model``
    unchanged without such tendons."""
    if not tendon_lengths.count(model.structure):
        return model
    level = coupling.with_multipliers(model, y / lam)
    return level.replace(tendon_displacement=lam * model.tendon_displacement)


def tension_scale(model: Model, ref):
    """The load scale ``ref`` (N) of :func:`load_scale` with the share of the
    displacement-controlled tendons' tensions of ``model`` (:func:`at_level`: at the
    multipliers of the current iterate, taken to the full loads): their forces are not
    known before the solve. ``ref`` unchanged without such tendons."""
    if not tendon_lengths.count(model.structure):
        return ref
    idx = jnp.asarray(tendon_lengths.displaced(model.structure), dtype=int)
    only = jnp.zeros_like(model.tendon_tension).at[idx].set(model.tendon_tension[idx])
    return jnp.sqrt(ref ** 2 + tendons.load_scale(model.replace(tendon_tension=only)))


SETTLING = 0.1   # the settling springs' stiffness, relative (settling_force)


def settling_force(model: Model, R, p, previous, ref):
    """The settling regularization of the rods whose supports leave rigid motions free
    (``Structure.settling``): a spring per node of such a rod to its frame ``H_0`` at the
    last accepted load level ``previous`` (proximal-point / pseudo-time continuation):
    energy ``sum_i 1/2 xi_i . (k xi_i)`` with ``xi_i = log(H_0i^-1 H_i)`` (N,6) (body
    twists), ``k = SETTLING ref / (sqrt(n) h)`` on the translations (N/m) and ``k h^2`` on
    the rotations (N m/rad), ``ref`` the load scale (N, :func:`load_scale`), ``n`` the
    settling nodes, ``h`` the characteristic length. It makes the tangent regular where
    contact, friction or the loads hold those motions only once the rod has moved, and it
    vanishes at convergence: the continuation repeats the full-load level, each one
    sprung to the one before, until the springs' force is below the tolerance
    (:func:`settled`). Returns the residual-side force ``k xi`` (N,6) (held dofs and
    other rods' nodes zero) and the stiffness diagonal ``k`` (N,6) added to the tangent
    (exact at ``xi = 0``)."""
    h = model.char_length
    mask = model.structure.settling_mask()
    k = SETTLING * ref / (np.sqrt(mask.sum()) * h)
    k = (jnp.asarray(mask)[:, None] * model.structure.free_mask()
         * jnp.concatenate([jnp.full(3, 1.0), jnp.full(3, h * h)]) * k)
    xi = jax.vmap(lambda Rq, pq, Ri, pi: lie.log_se3(lie.relative_pose(Rq, pq, Ri, pi)))(
        previous[0], previous[1], R, p)
    return k * xi, k


def settled(model: Model, settings: StaticSettings, R, p, previous, ref):
    """Whether the settling springs' force (:func:`settling_force`) at (R, p) against
    ``previous`` is below ``tolerance`` times the load scale ``ref`` (True without
    settling rods)."""
    if not model.structure.settling:
        return jnp.array(True)
    force, _ = settling_force(model, R, p, previous, ref)
    return weighted_norm(model, force) <= settings.tolerance * ref


def update_frames(R, p, dx):
    return jax.vmap(lie.compose_exp)(R, p, dx)


class NewtonState(NamedTuple):
    """Carry of :func:`newton_solve`: the trial frames (R, p), the accepted base frames and
    the Newton step from the base (dx), the fraction of it tried (step), the size of that
    step (size_base) and the residual at the base (res_base), the residual at the last
    evaluated trial (res), rejected trials in a row (backtracks), accepted Newton steps
    (iterations), and the status: -1 running, else a :class:`Status` code. y, base_y,
    dy: the multipliers (joint multipliers, displacement-controlled tendons' tensions)
    like R, p and dx (empty without them). tangent: the
    chains' tangent blocks evaluated at the last pass's trial (at (R, p) once done).
    positive: that tangent is positive definite, read from the pivots of its
    factorization when the pass converged and :func:`.branch.symmetric_at_equilibrium`
    holds (False otherwise)."""
    R: jax.Array
    p: jax.Array
    base_R: jax.Array
    base_p: jax.Array
    dx: jax.Array
    y: jax.Array
    base_y: jax.Array
    dy: jax.Array
    step: jax.Array
    size_base: jax.Array
    res: jax.Array
    res_base: jax.Array
    backtracks: jax.Array
    iterations: jax.Array
    status: jax.Array
    tangent: tuple
    positive: jax.Array


def level_tolerance(model: Model, settings: StaticSettings):
    """The tolerance of the intermediate load levels (see :class:`StaticSettings`)."""
    if model.obstacle_friction is not None:
        return settings.tolerance
    return jnp.maximum(settings.level_tolerance, settings.tolerance)


def max_load_step(model: Model, settings: StaticSettings):
    """The largest load increment of the continuation (see :class:`StaticSettings`)."""
    first = 1.0 / settings.load_steps
    if settings.max_load_step is None or model.obstacle_friction is not None:
        return first
    return jnp.maximum(settings.max_load_step, first)


def newton_pass(model: Model, settings: StaticSettings, lam, ref, c: NewtonState,
                previous=None, settle=None) -> NewtonState:
    """One pass of :func:`newton_solve` at load level ``lam`` (load scale ``ref``): residual,
    tangent and Newton step at the trial state, then accept or backtrack (see there);
    ``previous``: the frames (R, p) of the reference of the quasi-static friction (the
    last converged level below the full loads); ``settle``: those of the settling springs
    (:func:`settling_force`; the last converged level; default ``previous``). With
    displacement-controlled tendons the system is that of
    :func:`at_level`, the load scale holds their tensions (:func:`tension_scale`) and a
    converged pass also holds their lengths: the couplings' gaps / char_length
    (:func:`simsoft_jax.couplings.coupling.violation`) below the relative tolerance (the
    tensions, so the load scale, may be zero at the start)."""
    relative = jnp.where(lam < 1.0, level_tolerance(model, settings), settings.tolerance)
    level = at_level(model, c.y, lam)
    ref = tension_scale(level, ref)
    tol = relative * ref
    r, tangent = residual_and_tangent(level, c.R, c.p, lam, settings.tangent, previous)
    if model.structure.settling:   # rods their supports leave free: settling springs
        force, k = settling_force(model, c.R, c.p, previous if settle is None else settle, ref)
        r = r + force
        tangent = (tangent[0] + jax.vmap(jnp.diag)(k),) + tuple(tangent[1:])
    system = coupling.couple(level, c.R, c.p, c.y, r, tangent)
    res = residual_norm(level, system, ref)
    held = True
    if tendon_lengths.count(model.structure):
        held = coupling.violation(level, system.r_z)[1] <= relative
    factors = factorize(model, system)
    dx, dy = capped(settings.max_rotation_step,
                    *coupled_step(model, factors, system.r, system.r_z))
    size = step_size(model, dx)
    finite = jnp.isfinite(res) & jnp.isfinite(size)
    exhausted = c.backtracks >= settings.line_search_steps
    accept = finite & ((size < settings.max_step_growth * c.size_base) | exhausted)
    # converged: residual below tolerance, or stagnating at the round-off floor (a stiff
    # axial term makes |r| ~ eps EA) well below the load scale
    converged = accept & held & ((res <= tol) | ((res <= settings.stagnation_level * ref)
                                                  & (res >= 0.5 * c.res_base)))
    # the next Newton step is below step_tolerance: the state is that accurate, even
    # where round-off keeps the residual above tol (stiff axial terms, spec (S64))
    stalled = accept & (step_norm(model, dx) <= settings.step_tolerance)
    base_R = jnp.where(accept, c.R, c.base_R)
    base_p = jnp.where(accept, c.p, c.base_p)
    base_y = jnp.where(accept, c.y, c.base_y)
    dx = jnp.where(accept, dx, c.dx)
    dy = jnp.where(accept, dy, c.dy)
    step = jnp.where(accept, 1.0, 0.5 * c.step)
    # never through an obstacle or another rod: the step is cut back (swept_check)
    step = swept_check.cut_back(model, base_p,
                                lambda t: update_frames(base_R, base_p, t * dx)[1], step)
    trial_R, trial_p = update_frames(base_R, base_p, step * dx)
    trial_y = base_y + step * dy
    iterations = c.iterations + accept
    # a non-finite trial from a base with no finite step (the first evaluation, or
    # after line_search_steps halvings) cannot be backtracked: the solve fails here
    nonfinite = ~finite & (exhausted | ~jnp.isfinite(c.size_base))
    status = ladder(converged | stalled, (
        (nonfinite, Status.NONFINITE),
        (iterations > settings.max_iterations, Status.MAX_ITERATIONS),
        (~jnp.all(jnp.isfinite(trial_p)), Status.NONFINITE)))
    done = status != RUNNING
    positive = jnp.array(False)
    if symmetric_at_equilibrium(model):   # the stability watch's test, at the converged pass
        positive = jax.lax.cond(any_lane(status == Status.CONVERGED),
                                lambda: pivots_positive_definite(factors.chain),
                                lambda: positive)
    return NewtonState(
        R=jnp.where(done, c.R, trial_R), p=jnp.where(done, c.p, trial_p),
        base_R=base_R, base_p=base_p, dx=dx, y=jnp.where(done, c.y, trial_y),
        base_y=base_y, dy=dy, step=step,
        size_base=jnp.where(accept, size, c.size_base), res=res,
        res_base=jnp.where(accept, res, c.res_base),
        backtracks=jnp.where(accept, 0, c.backtracks + 1),
        iterations=iterations, status=status, tangent=tangent, positive=positive)


def newton_start(R, p, y) -> NewtonState:
    """The Newton carry before the first pass, from the predicted frames (R, p) and
    multipliers y."""
    inf, zero = jnp.array(jnp.inf), jnp.array(0)
    return NewtonState(R=R, p=p, base_R=R, base_p=p, dx=jnp.zeros(p.shape[:1] + (6,)),
                        y=y, base_y=y, dy=jnp.zeros_like(y),
                        step=jnp.array(1.0), size_base=inf, res=inf, res_base=inf,
                        backtracks=zero, iterations=zero, status=jnp.array(RUNNING),
                        tangent=no_tangent(p), positive=jnp.array(False))


def no_tangent(p):
    """Zero tangent blocks ``(diag, upper, lower)`` for the N nodes of positions p (N,3)."""
    n = p.shape[0]
    return (jnp.zeros((n, 6, 6), p.dtype),) + (jnp.zeros((n - 1, 6, 6), p.dtype),) * 2


def newton_outcome(c: NewtonState):
    """(R, p, y, Newton steps, residual norm, status code, tangent blocks at (R, p),
    whether they are positive definite as read by the last pass) of a finished Newton
    carry."""
    return (c.R, c.p, c.y, jnp.maximum(c.iterations - 1, 0), c.res, c.status,
            c.tangent, c.positive)


def contact_status(model: Model, R, p, status):
    """``status`` of a Newton solve that ended at frames (R, p) (N,3,3), (N,3), but
    ``CONTACT_PAIRS`` where it is ``NONFINITE`` because the broad phase finds more rod-rod
    candidate pairs there than ``[contact] max_pairs`` holds (``overflow`` of
    :func:`simsoft_jax.couplings.rod_pairs.find_pairs`, where the contact residual is NaN
    by design). Touching pairs on more nodes than the border holds (the rest of
    :func:`~simsoft_jax.couplings.rod_pairs.overflows`) stay ``NONFINITE``: testing them
    takes the pairs' tangents (the crossing rods' static program: 14146 StableHLO
    operations against 10277 without any test; 11289 with this one).
    The pairs are found only when some (batched) lane ended ``NONFINITE``; ``status``
    unchanged without rod-rod contact."""
    if not model.structure.self_contact:
        return status
    nonfinite = status == Status.NONFINITE

    def named():
        overflow = rod_pairs.find_pairs(model, R, p).overflow
        return jnp.where(nonfinite & overflow, Status.CONTACT_PAIRS, status)
    return jax.lax.cond(any_lane(nonfinite), named, lambda: status)


def newton_solve(model: Model, settings: StaticSettings, R, p, y, lam, ref, previous=None,
                 settle=None):
    """Newton iterations at load level ``lam`` from (R, p) (spec S71) with damping.

    One loop evaluates residual, tangent and Newton step at a trial state. The trial is
    accepted unless its Newton step exceeds ``max_step_growth`` times the step that led
    to it (a natural-level divergence guard in the spirit of Deuflhard's monotonicity
    test: it measures the distance to the solution in the unknowns, so the huge axial
    stiffness of a rod cannot make a good step look bad, as a residual-based Armijo test
    does; a strict theta < 1 test rejects good steps of stiff rods) or is not finite; a
    rejected trial halves the step from the base. Every loop pass either accepts (counted
    against ``max_iterations``) or backtracks (at most ``line_search_steps`` in a row), so
    the loop always ends (:func:`newton_pass`). Returns (R, p, y, Newton steps, residual
    norm, status code, tangent blocks at (R, p), their positive definiteness as
    :class:`NewtonState` says). ``previous``, ``settle``: as in :func:`newton_pass`.
    """
    c = iterate(lambda c: newton_pass(model, settings, lam, ref, c, previous, settle),
                newton_start(R, p, y))
    return newton_outcome(c)
