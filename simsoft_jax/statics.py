"""Static equilibrium on SE(3)^N: Newton with load continuation and line search, and
gradients of the equilibrium by the implicit function theorem (spec algorithm.md section 5).

``solve_static(model)`` is pure and jit-compiled once per model structure: the whole
continuation (adaptive load steps, Newton iterations, backtracking) runs inside
``lax.while_loop``. Its output is differentiable with respect to every array of the Model
(stiffness, loads, gravity, reference geometry) in forward and reverse mode: the Newton
iterations are not unrolled; the tangent of the converged solution is
``dxi = -K_t^-1 (dr/dparams . dparams)`` (spec section 5, last item), solved with the same
block-tridiagonal tangent through ``lax.custom_linear_solve`` (its transpose for reverse mode).
"""
from __future__ import annotations

import dataclasses
from functools import partial
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from . import lie, mechanisms, rod_pairs, tendon_control
from ._xla import jit
from .assembly import check_tangent, residual, residual_and_tangent
from .inertia import centre_of_mass, line_density
from .linalg import (block_solve, factorize_coupled, implicit_solve, implicit_solve_coupled,
                     solve_coupled)
from .loads import full_loads
from .model import Model
from .status import Status, describe, raise_if_failed


@dataclasses.dataclass(frozen=True)
class StaticSettings:
    """Solver settings. Floats are traced (changing them never recompiles); the integers
    (max_iterations, load_steps, max_attempts, line_search_steps) are static structure.
    ``level_tolerance=0`` (with ``max_load_step`` left None) is the continuation of
    before issue 16 (every level to ``tolerance``, at least ``load_steps`` levels).

    tolerance: converged when the weighted residual norm is below ``tolerance`` times the
      load scale (forces in N, moments divided by the model's ``char_length``).
    max_iterations: Newton iterations per load step before the step is halved.
    load_steps: the first load increment of the continuation is ``1/load_steps`` of the
      full loads; increments are halved on failure down to ``min_step_fraction`` of it,
      and grow by 1.5 after easy steps (fewer than 5 Newton steps) up to
      ``max_load_step``. By default that cap is ``1/load_steps`` itself, so a solve
      takes at least ``load_steps`` increments (the scene format's "minimum
      continuation steps").
    max_load_step: None (default: ``1/load_steps``, see above), or the largest load
      increment (fraction of the full loads, in (0, 1]) the continuation may grow to:
      ``max_load_step=1`` lets an easy solve take fewer than ``load_steps`` increments
      (a random Princeton case: 15 instead of 25 Newton steps; benchmarks/README.md,
      "Batched sweeps"; the Princeton replay and sweeps use it). With quasi-static
      friction (a load-path-dependent state) the cap is ``1/load_steps`` whatever this
      is.
    level_tolerance: the tolerance (as ``tolerance``) of the intermediate load levels
      (lam < 1); the last level (lam = 1) is always solved to ``tolerance``. Intermediate
      levels only start the next one (secant predictor), so a loose tolerance there saves
      Newton steps without changing the equilibrium at the full loads (benchmarks/README.md,
      "Batched sweeps"). Values below ``tolerance`` act as ``tolerance``; with quasi-static
      friction every level is solved to ``tolerance``.
    max_attempts: cap on load steps tried (accepted or not) in one solve.
    max_rotation_step: cap (rad) on the nodal rotation of one Newton update (spec 4.7.6).
    line_search_steps, max_step_growth: a trial state is rejected (and the step from the
      base halved, at most line_search_steps times) when its Newton step is more than
      max_step_growth times the step that led to it — a divergence guard. A trial whose
      residual or step is not finite is rejected the same way; after line_search_steps
      such halvings the Newton solve fails with status NONFINITE.
    step_tolerance: converged when the next Newton step is below it (translations /
      char_length, rotations in rad).
    stagnation_level: also converged when the residual stops halving below this fraction
      of the load scale (round-off floor of stiff axial terms, ~ eps EA).
    tangent: "closed_form" (closed-form element tangents where a term has one) or
      "autodiff" (``jax.jacfwd`` of every term); the same tangent, different speed (static).
    """
    tolerance: float = 1e-10
    max_iterations: int = 50
    load_steps: int = 10
    min_step_fraction: float = 2.0**-12
    max_attempts: int = 2000
    line_search_steps: int = 8
    max_rotation_step: float = 0.5 * np.pi
    step_tolerance: float = 1e-11
    stagnation_level: float = 1e-6
    max_step_growth: float = 4.0
    max_load_step: float | None = None
    level_tolerance: float = 1e-3
    tangent: str = "closed_form"

    def __post_init__(self):
        check_tangent(self.tangent)

    def replace(self, **changes) -> "StaticSettings":
        """A copy with some settings changed."""
        return dataclasses.replace(self, **changes)


_STATIC_INTEGERS = ("max_iterations", "load_steps", "max_attempts", "line_search_steps",
                    "tangent")
jax.tree_util.register_dataclass(
    StaticSettings,
    data_fields=[f.name for f in dataclasses.fields(StaticSettings)
                 if f.name not in _STATIC_INTEGERS],
    meta_fields=list(_STATIC_INTEGERS))


def as_traced(settings):
    """``settings`` with every float leaf a float64 array, so that Python floats, NumPy
    scalars and arrays all hit the same compiled program. Host numbers become NumPy
    arrays (a compiled program transfers them when called; no device transfer each),
    JAX arrays and tracers stay JAX arrays."""
    def f64(x):
        if isinstance(x, (float, int, np.ndarray, np.generic)):
            return np.asarray(x, np.float64)
        return jnp.asarray(x, jnp.float64)
    return jax.tree_util.tree_map(f64, settings)


class Equilibrium(NamedTuple):
    """Result of :func:`solve_static`. R (N,3,3), p (N,3): nodal frames (world); the rest
    are scalars: converged (bool), iterations (total Newton iterations), residual_norm
    (weighted, N; at the last accepted load level), load_level (fraction of the loads
    reached, 1 when converged), load_steps (accepted continuation steps), step_failures
    (halvings), status (:class:`~simsoft_jax.status.Status` code: how the solve ended),
    cause (the reason of the last failed Newton solve, ``NOT_RUN`` if none), multipliers
    (M,): the joint multipliers (:mod:`~simsoft_jax.mechanisms`; None without joints),
    tendon_tension (M,) the tendons' tensions (N): as given, or solved for
    displacement-controlled tendons (:mod:`simsoft_jax.tendon_control`); None when the
    model has no tendons; previous: the frames (R, p) of the load level before the last
    one, the reference of the quasi-static friction there
    (:mod:`simsoft_jax.terms.static_friction`); None without friction. tangent: the
    chains' tangent blocks ``(diag, upper, lower)`` at the equilibrium under the full
    loads, from the last Newton pass (see :func:`equilibrium`, ``keep_tangent``); None
    unless asked for."""
    R: jax.Array
    p: jax.Array
    converged: jax.Array
    iterations: jax.Array
    residual_norm: jax.Array
    load_level: jax.Array
    load_steps: jax.Array
    step_failures: jax.Array
    status: jax.Array
    cause: jax.Array
    multipliers: jax.Array | None = None
    tendon_tension: jax.Array | None = None
    previous: tuple | None = None
    tangent: tuple | None = None

    def message(self) -> str:
        """How the solve ended, in words (concrete, unbatched results)."""
        return describe("static", self.status, self.cause, float(self.load_level),
                        float(self.residual_norm))


def weighted_norm(model, r):
    """Unit-consistent norm: forces in N, moments divided by ``char_length`` (spec 4.7.9)."""
    return jnp.sqrt(jnp.sum(r[:, :3] ** 2) + jnp.sum((r[:, 3:] / model.char_length) ** 2))


def step_norm(model, dx):
    """Largest nodal increment: translation / char_length and rotation (rad)."""
    trans = jnp.linalg.norm(dx[:, :3], axis=1) / model.char_length
    rot = jnp.linalg.norm(dx[:, 3:], axis=1)
    return jnp.max(jnp.maximum(trans, rot))


def _step_size(model, dx):
    """Weighted 2-norm of a Newton step: translations / char_length, rotations in rad."""
    return jnp.sqrt(jnp.sum((dx[:, :3] / model.char_length) ** 2) + jnp.sum(dx[:, 3:] ** 2))


def load_scale(model: Model):
    """Weighted size (N) of the full external loads, the reference of the tolerance."""
    s = model.structure
    mask = s.free_mask()
    nodal = jnp.zeros_like(model.nodal_dead)
    if s.has_nodal_dead:
        nodal = nodal + jnp.abs(model.nodal_dead)
    if s.has_nodal_follower:
        nodal = nodal + jnp.abs(model.nodal_follower)
    total = jnp.sum(weighted_norm(model, nodal * mask) ** 2)
    if s.has_point_dead or s.has_point_follower:
        point = jnp.abs(model.element_point_dead) + jnp.abs(model.element_point_follower)
        total = (total + jnp.sum(point[:, :3] ** 2)
                 + jnp.sum((point[:, 3:] / model.char_length) ** 2))
    q = jnp.zeros_like(model.distributed_world)
    if s.has_gravity:
        rho_a = jax.vmap(line_density)(model.inertia)
        q = q + rho_a[:, None] * model.gravity
        if s.inertia_offset:   # the weight's moment about the axis (offset centre of mass)
            arm = jnp.linalg.norm(jax.vmap(centre_of_mass)(model.inertia), axis=1)
            total = total + jnp.sum((model.length * rho_a * arm / model.char_length) ** 2
                                    * jnp.sum(model.gravity ** 2))
    if s.has_distributed_world:
        q = q + model.distributed_world
    if s.has_distributed_local:
        q = q + jnp.abs(model.distributed_local)
    total = total + jnp.sum((model.length[:, None] * q) ** 2)
    if s.offset_load_nodes:        # forces at offset points and their moments
        f = model.offset_force
        total = total + jnp.sum(f ** 2) + jnp.sum(
            (jnp.linalg.norm(model.offset_point, axis=1) * jnp.linalg.norm(f, axis=1)
             / model.char_length) ** 2)
    if s.mass_nodes and s.has_gravity:   # weights of attached masses
        w = model.mass[:, None] * model.gravity
        total = total + jnp.sum(w ** 2) + jnp.sum(
            (jnp.linalg.norm(model.mass_offset, axis=1) * jnp.linalg.norm(w, axis=1)
             / model.char_length) ** 2)
    if s.tendon_names:   # tendon tensions and the moments they make at their offsets
        r = jnp.max(jnp.linalg.norm(model.tendon_offset, axis=-1), axis=(1, 2))
        total = total + jnp.sum(model.tendon_tension ** 2 * (1.0 + (r / model.char_length) ** 2))
    if s.chamber_names:  # pressure times area, and its moment at the chamber's offset
        r = jnp.linalg.norm(model.chamber_offset, axis=-1)
        f = model.chamber_pressure * model.chamber_area
        total = total + jnp.sum(f ** 2 * (1.0 + (r / model.char_length) ** 2))
    return jnp.sqrt(total)


def _update(R, p, dx):
    return jax.vmap(lie.compose_exp)(R, p, dx)


class _NewtonState(NamedTuple):
    """Carry of :func:`_newton`: the trial frames (R, p), the accepted base frames and
    the Newton step from the base (dx), the fraction of it tried (step), the size of that
    step (size_base) and the residual at the base (res_base), the residual at the last
    evaluated trial (res), rejected trials in a row (backtracks), accepted Newton steps
    (iterations), and the status: -1 running, else a :class:`Status` code. y, base_y,
    dy: the joint multipliers like R, p and dx (empty without joints). tangent: the
    chains' tangent blocks evaluated at the last pass's trial (at (R, p) once done)."""
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


_RUNNING = -1


def level_tolerance(model: Model, settings: StaticSettings):
    """The tolerance of the intermediate load levels (see :class:`StaticSettings`)."""
    if model.structure.has_friction:
        return settings.tolerance
    return jnp.maximum(settings.level_tolerance, settings.tolerance)


def max_load_step(model: Model, settings: StaticSettings):
    """The largest load increment of the continuation (see :class:`StaticSettings`)."""
    first = 1.0 / settings.load_steps
    if settings.max_load_step is None or model.structure.has_friction:
        return first
    return jnp.maximum(settings.max_load_step, first)


def newton_pass(model: Model, settings: StaticSettings, lam, ref, c: _NewtonState,
                previous=None) -> _NewtonState:
    """One pass of :func:`_newton` at load level ``lam`` (load scale ``ref``): residual,
    tangent and Newton step at the trial state, then accept or backtrack (see there);
    ``previous``: the frames (R, p) of the last converged level (the reference of the
    quasi-static friction)."""
    tol = jnp.where(lam < 1.0, level_tolerance(model, settings), settings.tolerance) * ref
    identity = model.structure.identity_nodes()
    r, blocks = residual_and_tangent(model, c.R, c.p, lam, settings.tangent, previous)
    tangent = blocks
    if model.structure.joints:    # rods, bodies and joints: the bordered system
        res, dx, dy = _mechanism_step(model, ref, c.R, c.p, c.y, r, blocks)
    elif model.structure.self_contact:   # rod-rod contact: the bordered system
        r, blocks, cpl = rod_pairs.system(model, c.R, c.p, r, blocks)
        dx, _ = solve_coupled(factorize_coupled(blocks, *cpl, identity), -r,
                             jnp.zeros(cpl.D.shape[0]))
        res, dy = weighted_norm(model, r), c.dy
    else:
        res, dx, dy = weighted_norm(model, r), -block_solve(blocks, r, identity), c.dy
    rot = jnp.max(jnp.linalg.norm(dx[:, 3:], axis=1))
    cap = jnp.minimum(1.0, settings.max_rotation_step / jnp.maximum(rot, 1e-300))
    dx, dy = dx * cap, dy * cap
    size = _step_size(model, dx)
    finite = jnp.isfinite(res) & jnp.isfinite(size)
    exhausted = c.backtracks >= settings.line_search_steps
    accept = finite & ((size < settings.max_step_growth * c.size_base) | exhausted)
    # converged: residual below tolerance, or stagnating at the round-off floor (a stiff
    # axial term makes |r| ~ eps EA) well below the load scale
    converged = accept & ((res <= tol) | ((res <= settings.stagnation_level * ref)
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
    trial_R, trial_p = _update(base_R, base_p, step * dx)
    trial_y = base_y + step * dy
    iterations = c.iterations + accept
    # a non-finite trial from a base with no finite step (the first evaluation, or
    # after line_search_steps halvings) cannot be backtracked: the solve fails here
    nonfinite = ~finite & (exhausted | ~jnp.isfinite(c.size_base))
    status = jnp.where(converged | stalled, Status.CONVERGED, _RUNNING)
    status = jnp.where(nonfinite, Status.NONFINITE, status)
    status = jnp.where((status == _RUNNING) & (iterations > settings.max_iterations),
                       Status.MAX_ITERATIONS, status)
    status = jnp.where((status == _RUNNING) & ~jnp.all(jnp.isfinite(trial_p)),
                       Status.NONFINITE, status)
    done = status != _RUNNING
    return _NewtonState(
        R=jnp.where(done, c.R, trial_R), p=jnp.where(done, c.p, trial_p),
        base_R=base_R, base_p=base_p, dx=dx, y=jnp.where(done, c.y, trial_y),
        base_y=base_y, dy=dy, step=step,
        size_base=jnp.where(accept, size, c.size_base), res=res,
        res_base=jnp.where(accept, res, c.res_base),
        backtracks=jnp.where(accept, 0, c.backtracks + 1),
        iterations=iterations, status=status, tangent=tangent)


def newton_start(R, p, y) -> _NewtonState:
    """The Newton carry before the first pass, from the predicted frames (R, p) and joint
    multipliers y."""
    inf, zero = jnp.array(jnp.inf), jnp.array(0)
    return _NewtonState(R=R, p=p, base_R=R, base_p=p, dx=jnp.zeros(p.shape[:1] + (6,)),
                        y=y, base_y=y, dy=jnp.zeros_like(y),
                        step=jnp.array(1.0), size_base=inf, res=inf, res_base=inf,
                        backtracks=zero, iterations=zero, status=jnp.array(_RUNNING),
                        tangent=_no_tangent(p))


def _no_tangent(p):
    """Zero tangent blocks ``(diag, upper, lower)`` for the N nodes of positions p (N,3)."""
    n = p.shape[0]
    return (jnp.zeros((n, 6, 6), p.dtype),) + (jnp.zeros((n - 1, 6, 6), p.dtype),) * 2


def newton_outcome(c: _NewtonState):
    """(R, p, y, Newton steps, residual norm, status code, tangent blocks at (R, p)) of a
    finished Newton carry."""
    return (c.R, c.p, c.y, jnp.maximum(c.iterations - 1, 0), c.res, c.status,
            c.tangent)


def _mechanism_step(model: Model, ref, R, p, y, r, blocks):
    """Residual norm and Newton step ``(dx (N,6), dy (M,))`` of the bordered system of rods,
    bodies and joints (:mod:`simsoft_jax.mechanisms`). The norm adds the bodies' force
    residuals and the joints' gaps (/ char_length) and rotations times the load scale
    ``ref``, so a converged solve holds its joints to ``tolerance`` of the length."""
    system = mechanisms.couple(model, R, p, y, r, blocks)
    x, z = solve_coupled(factorize_coupled(system.blocks, system.B, system.C, system.D,
                                          model.structure.identity_nodes()),
                         -system.r, -system.r_z)
    forces, gaps = mechanisms.violation_norm(model, system.r_z)
    res = jnp.sqrt(weighted_norm(model, system.r) ** 2 + forces ** 2 + (ref * gaps) ** 2)
    return (res,) + mechanisms.split(model.structure, x, z)


def _newton(model: Model, settings: StaticSettings, R, p, y, lam, ref, previous=None):
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
    norm, status code, tangent blocks at (R, p)). ``previous``: as in
    :func:`newton_pass`.
    """
    c = jax.lax.while_loop(lambda c: c.status == _RUNNING,
                           lambda c: newton_pass(model, settings, lam, ref, c, previous),
                           newton_start(R, p, y))
    return newton_outcome(c)


def _secant(R, p, R_prev, p_prev, ratio):
    """Lie-group secant predictor ``H exp(ratio log(H_prev^-1 H))`` per node (spec 5)."""
    def one(Ri, pi, Rq, pq):
        d = lie.log_se3(lie.relative_pose(Rq, pq, Ri, pi))
        return lie.compose_exp(Ri, pi, ratio * d)
    return jax.vmap(one)(R, p, R_prev, p_prev)


class _ContinuationState(NamedTuple):
    """Carry of :func:`_continuation`: the last accepted frames (R, p) at load level lam,
    the ones before (R_prev, p_prev at lam_prev) for the secant predictor, the next load
    increment dlam, counters, the residual at the last accepted level, and the status of
    the last failed Newton solve (cause); y, y_prev: the joint multipliers at lam and
    lam_prev; tangent: the chains' tangent blocks at (R, p) (zero before a level is
    accepted)."""
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


def trial_level(c: _ContinuationState):
    """The next load level of the continuation and the secant prediction of its frames and
    joint multipliers: ``(lam_try, R, p, y)``."""
    lam_try = c.lam + c.dlam
    lam_try = jnp.where(lam_try > 1.0 - 1e-9, 1.0, lam_try)  # no sliver step from round-off
    ratio = (lam_try - c.lam) / jnp.maximum(c.lam - c.lam_prev, 1e-300)
    ratio = jnp.where(c.accepted >= 1, ratio, 0.0)
    Rs, ps = _secant(c.R, c.p, c.R_prev, c.p_prev, ratio)
    return lam_try, Rs, ps, c.y + ratio * (c.y - c.y_prev)


def after_newton(model: Model, settings: StaticSettings, c: _ContinuationState, lam_try, R,
                 p, y, its, res, status, tangent) -> _ContinuationState:
    """The continuation carry after the Newton solve at ``lam_try`` ended with ``status``:
    a converged level is accepted and the increment grows by 1.5 after an easy solve (fewer
    than 5 steps), up to :func:`max_load_step`; a failed one halves the increment."""
    ok = status == Status.CONVERGED
    grow = jnp.where(its < 5, 1.5, 1.0)
    keep = lambda new, old: jnp.where(ok, new, old)  # noqa: E731
    return _ContinuationState(
        R=keep(R, c.R), p=keep(p, c.p), R_prev=keep(c.R, c.R_prev),
        p_prev=keep(c.p, c.p_prev), y=keep(y, c.y), y_prev=keep(c.y, c.y_prev),
        lam_prev=keep(c.lam, c.lam_prev),
        lam=keep(lam_try, c.lam),
        dlam=jnp.where(ok, jnp.minimum(c.dlam * grow, max_load_step(model, settings)),
                       0.5 * c.dlam),
        accepted=c.accepted + ok, failures=c.failures + (~ok),
        iterations=c.iterations + its, attempts=c.attempts + 1,
        residual=keep(res, c.residual), cause=keep(c.cause, status),
        tangent=jax.tree_util.tree_map(keep, tangent, c.tangent))


def continuing(settings: StaticSettings, c: _ContinuationState):
    """Whether the continuation goes on: loads not reached, increment above its minimum
    (``min_step_fraction / load_steps``), attempts left."""
    dlam_min = (1.0 / settings.load_steps) * settings.min_step_fraction
    return (c.lam < 1.0) & (c.dlam >= dlam_min) & (c.attempts < settings.max_attempts)


def continuation_start(model: Model, settings: StaticSettings) -> _ContinuationState:
    """The continuation carry at load level 0 (the start frames of ``model``)."""
    zero = jnp.array(0)
    y = jnp.zeros(mechanisms.multiplier_count(model.structure), model.p0.dtype)
    return _ContinuationState(
        R=model.R0, p=model.p0, R_prev=model.R0, p_prev=model.p0, y=y, y_prev=y,
        lam=jnp.array(0.0),
        lam_prev=jnp.array(0.0), dlam=jnp.asarray(1.0 / settings.load_steps, jnp.float64),
        accepted=zero, failures=zero, iterations=zero, attempts=zero,
        residual=jnp.array(jnp.inf), cause=jnp.array(int(Status.NOT_RUN)),
        tangent=_no_tangent(model.p0))


def continuation_result(settings: StaticSettings, c: _ContinuationState) -> Equilibrium:
    """The :class:`Equilibrium` of a finished continuation carry."""
    converged = c.lam >= 1.0
    status = jnp.where(converged, Status.CONVERGED,
                       jnp.where(c.attempts >= settings.max_attempts, Status.MAX_ATTEMPTS,
                                 Status.STEP_TOO_SMALL))
    return Equilibrium(c.R, c.p, converged, c.iterations, c.residual, c.lam, c.accepted,
                       c.failures, status, c.cause, c.y if c.y.size else None,
                       previous=(c.R_prev, c.p_prev), tangent=c.tangent)


def _continuation(model: Model, settings: StaticSettings) -> Equilibrium:
    """Adaptive load continuation lam: 0 -> 1 with Newton at each level (spec section 5)."""
    ref = load_scale(model)

    def body(c: _ContinuationState) -> _ContinuationState:
        lam_try, Rs, ps, ys = trial_level(c)
        outcome = _newton(model, settings, Rs, ps, ys, lam_try, ref, (c.R, c.p))
        return after_newton(model, settings, c, lam_try, *outcome)

    c = jax.lax.while_loop(lambda c: continuing(settings, c), body,
                           continuation_start(model, settings))
    return continuation_result(settings, c)


@partial(jax.custom_jvp, nondiff_argnums=(0,))
def _implicit(tangent: str, model: Model, converged, R, p, y, previous):
    """Identity on a converged equilibrium (frames R, p and joint multipliers y); its
    derivative is the IFT one (see module doc). Held dofs follow the start frames
    ``model.R0, model.p0`` (a clamp holds its node there). Where the solve did not
    converge the derivative is NaN: there is no equilibrium to differentiate, and a
    finite number would be wrong. With quasi-static friction (``previous``: the frames of
    the level before the last, else None) the derivative is that of the last level's
    equilibrium with ``previous`` held fixed: the history of the earlier levels is not
    differentiated (exact for stations sliding in a direction the parameters do not turn,
    as the friction (F1) is then ``mu f_n`` whatever the slip's size; an approximation
    for sticking stations)."""
    return R, p, y


@_implicit.defjvp
def _implicit_jvp(tangent, primals, tangents):
    model, converged, R, p, y, previous = primals
    dmodel = tangents[0]
    held = 1.0 - model.structure.free_mask()
    # body-frame motion of the held dofs: translations R^T dp0, rotations vee(R^T dR0)
    dA = jnp.einsum("nji,njk->nik", R, dmodel.R0)
    moved = held * jnp.concatenate([jnp.einsum("nji,nj->ni", R, dmodel.p0),
                                    0.5 * jnp.stack([dA[:, 2, 1] - dA[:, 1, 2],
                                                     dA[:, 0, 2] - dA[:, 2, 0],
                                                     dA[:, 1, 0] - dA[:, 0, 1]], axis=1)], axis=1)

    def perturbed(m, x):
        Rx, px = _update(R, p, x)
        r = residual(m, Rx, px, 1.0, previous)
        if m.structure.self_contact:
            r = r + rod_pairs.residual(m, Rx, px)
        return mechanisms.residual(m, Rx, px, y, r) if m.structure.joints else (r, y)

    _, (dr, dr_z) = jax.jvp(perturbed, (model, jnp.zeros_like(moved)), (dmodel, moved))
    r, blocks = residual_and_tangent(model, R, p, 1.0, tangent, previous)
    identity = model.structure.identity_nodes()
    if model.structure.joints:
        system = mechanisms.couple(model, R, p, y, r, blocks)
        x, z = implicit_solve_coupled(system.blocks, system.B, system.C, system.D, -dr,
                                      -dr_z, identity)
        x, dy = mechanisms.split(model.structure, x, z)
    elif model.structure.self_contact:
        r, blocks, cpl = rod_pairs.system(model, R, p, r, blocks)
        x, _ = implicit_solve_coupled(blocks, *cpl, -dr, jnp.zeros(cpl.D.shape[0]), identity)
        dy = jnp.zeros_like(y)
    else:
        x, dy = implicit_solve(blocks, -dr, identity), jnp.zeros_like(y)
    nan_if_failed = jnp.where(converged, 1.0, jnp.nan)
    dxi = jnp.where(held > 0, moved, x) * nan_if_failed
    # d/dt [R exp(t dxi)] at t = 0: (R skew(dxi_w), R dxi_u)
    dR = jnp.einsum("nij,njk->nik", R, jax.vmap(lie.skew)(dxi[:, 3:]))
    dp = jnp.einsum("nij,nj->ni", R, dxi[:, :3])
    return (R, p, y), (dR, dp, dy * nan_if_failed)


def equilibrium(model: Model, settings: StaticSettings, continuation=None,
                keep_tangent: bool = False) -> Equilibrium:
    """The continuation (default :func:`_continuation`; the batched sweeps pass their
    flattened one) under the full loads, with the implicit derivative attached. With
    displacement-controlled tendons, their tensions are solved first
    (:func:`~simsoft_jax.tendon_control.solve_tensions`). ``keep_tangent``: return the
    last Newton pass's tangent blocks as ``Equilibrium.tangent`` (not differentiated;
    for the stability count), else None."""
    model = full_loads(model)

    def solve(m, st):
        eq = (continuation or _continuation)(jax.lax.stop_gradient(m),
                                             jax.lax.stop_gradient(st))
        # None without tendons (a zero-size output would trouble batched maps)
        tension = m.tendon_tension if m.structure.tendon_names else None
        eq = eq._replace(previous=eq.previous if m.structure.has_friction else None,
                         tangent=eq.tangent if keep_tangent else None)
        if eq.multipliers is None:       # no joints
            R, p, _ = _implicit(st.tangent, m, eq.converged, eq.R, eq.p, jnp.zeros(0),
                                eq.previous)
            return eq._replace(R=R, p=p, tendon_tension=tension)
        R, p, y = _implicit(st.tangent, m, eq.converged, eq.R, eq.p, eq.multipliers,
                            eq.previous)
        return eq._replace(R=R, p=p, multipliers=y, tendon_tension=tension)

    if not any(model.structure.tendon_displaced):
        return solve(model, settings)
    model, ok = tendon_control.solve_tensions(
        solve, model, settings, settings.step_tolerance * model.char_length)
    eq = solve(model, settings)
    failed = eq.converged & ~ok
    return eq._replace(converged=eq.converged & ok,
                       status=jnp.where(failed, Status.MAX_ITERATIONS, eq.status))


@jit
def _solve_static(model: Model, settings: StaticSettings) -> Equilibrium:
    return equilibrium(model, settings)


def solve_static(model: Model, settings: StaticSettings = StaticSettings(),
                 throw: bool = False) -> Equilibrium:
    """Static equilibrium of ``model`` under its full loads (spec S70-S71).

    Returns an :class:`Equilibrium`; when ``converged`` is False, ``status``/``cause``
    and :meth:`Equilibrium.message` say why, ``load_level`` how far the continuation got,
    and R, p hold the last converged state. Compiled once per model structure and set of
    integer settings (float settings are traced). Differentiable in all Model arrays
    (implicit function theorem); the derivative of a non-converged solve is NaN.
    ``throw=True`` raises :class:`~simsoft_jax.status.SolveError` instead of returning a
    failed solve.
    """
    eq = _solve_static(model, as_traced(settings))
    if throw:
        raise_if_failed("static", eq.converged, eq.status, eq.cause, eq.load_level,
                        eq.residual_norm)
    return eq


def settings_from_scene(solver) -> StaticSettings:
    """StaticSettings from a scene's ``[solver]`` table."""
    return StaticSettings(tolerance=float(solver.tolerance),
                          max_iterations=int(solver.max_iterations),
                          load_steps=int(solver.load_steps),
                          level_tolerance=float(solver.level_tolerance),
                          max_load_step=solver.max_load_step, tangent=solver.tangent)
