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

from typing import NamedTuple

import jax
import jax.numpy as jnp

from . import lie
from ._xla import jit
from .assembly import block_solve, implicit_solve, residual, residual_and_tangent
from .model import Model


class StaticSettings(NamedTuple):
    """Solver settings (hashable: part of the compiled structure).

    tolerance: converged when the weighted residual norm is below ``tolerance`` times the
      load scale (forces in N, moments divided by the model's ``char_length``).
    max_iterations: Newton iterations per load step before the step is halved.
    load_steps: minimum number of continuation steps (the largest load increment is
      ``1/load_steps``; increments are halved on failure down to ``min_step_fraction`` of it,
      and grow back by 1.5 after easy steps).
    max_rotation_step: cap (rad) on the nodal rotation of one Newton update (spec 4.7.6).
    line_search_steps, max_step_growth: a trial state is rejected (and the step from the
      base halved, at most line_search_steps times) when its Newton step is more than
      max_step_growth times the step that led to it — a divergence guard.
    step_tolerance: converged when the next Newton step is below it (translations /
      char_length, rotations in rad).
    stagnation_level: also converged when the residual stops halving below this fraction
      of the load scale (round-off floor of stiff axial terms, ~ eps EA).
    """
    tolerance: float = 1e-10
    max_iterations: int = 50
    load_steps: int = 10
    min_step_fraction: float = 2.0**-12
    max_attempts: int = 2000
    line_search_steps: int = 8
    max_rotation_step: float = 0.5 * jnp.pi
    step_tolerance: float = 1e-11
    stagnation_level: float = 1e-6
    max_step_growth: float = 4.0


class Equilibrium(NamedTuple):
    """Result of :func:`solve_static`. R (N,3,3), p (N,3): nodal frames (world); the rest
    are scalars: converged (bool), iterations (total Newton iterations), residual_norm
    (weighted, N), load_level (fraction of the loads reached, 1 when converged),
    load_steps (accepted continuation steps), step_failures (halvings)."""
    R: jax.Array
    p: jax.Array
    converged: jax.Array
    iterations: jax.Array
    residual_norm: jax.Array
    load_level: jax.Array
    load_steps: jax.Array
    step_failures: jax.Array


def _weighted_norm(model, r):
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
    total = jnp.sum(_weighted_norm(model, nodal * mask) ** 2)
    q = jnp.zeros_like(model.distributed_world)
    if s.has_gravity:
        q = q + model.inertia[:, :1] * model.gravity
    if s.has_distributed_world:
        q = q + model.distributed_world
    if s.has_distributed_local:
        q = q + jnp.abs(model.distributed_local)
    total = total + jnp.sum((model.length[:, None] * q) ** 2)
    return jnp.sqrt(total)


def _update(R, p, dx):
    return jax.vmap(lie.compose_exp)(R, p, dx)


def _newton(model: Model, settings: StaticSettings, R, p, lam, ref):
    """Newton iterations at load level ``lam`` from (R, p) (spec S71) with damping.

    One loop evaluates residual, tangent and Newton step at a trial state. The trial is
    accepted unless its Newton step exceeds ``max_step_growth`` times the step that led
    to it (a natural-level divergence guard in the spirit of Deuflhard's monotonicity
    test: it measures the distance to the solution in the unknowns, so the huge axial
    stiffness of a rod cannot make a good step look bad, as a residual-based Armijo test
    does; a strict theta < 1 test rejects good steps of stiff rods); a rejected trial
    halves the step from the base. Returns (R, p, Newton steps, residual norm, converged).
    """
    tol = settings.tolerance * ref

    def body(c):
        r, blocks = residual_and_tangent(model, c["R"], c["p"], lam)
        res = _weighted_norm(model, r)
        dx = -block_solve(blocks, r)
        rot = jnp.max(jnp.linalg.norm(dx[:, 3:], axis=1))
        dx = dx * jnp.minimum(1.0, settings.max_rotation_step / jnp.maximum(rot, 1e-300))
        size = _step_size(model, dx)
        finite = jnp.isfinite(res) & jnp.isfinite(size)
        accept = finite & ((size < settings.max_step_growth * c["size_base"])
                           | (c["backtracks"] >= settings.line_search_steps))
        # converged: residual below tolerance, or stagnating at the round-off floor (a stiff
        # axial term makes |r| ~ eps EA) well below the load scale
        converged = accept & ((res <= tol) | ((res <= settings.stagnation_level * ref)
                                              & (res >= 0.5 * c["res_base"])))
        # the next Newton step is below step_tolerance: the state is that accurate, even
        # where round-off keeps the residual above tol (stiff axial terms, spec (S64))
        stalled = accept & (step_norm(model, dx) <= settings.step_tolerance)
        base_R = jnp.where(accept, c["R"], c["base_R"])
        base_p = jnp.where(accept, c["p"], c["base_p"])
        dx = jnp.where(accept, dx, c["dx"])
        step = jnp.where(accept, 1.0, 0.5 * c["step"])
        trial_R, trial_p = _update(base_R, base_p, step * dx)
        iterations = c["iterations"] + accept
        status = jnp.where(converged | stalled, 1, 0)
        status = jnp.where((status == 0) & ((iterations > settings.max_iterations)
                                            | ~jnp.all(jnp.isfinite(trial_p))), 2, status)
        done = status != 0
        return dict(
            R=jnp.where(done, c["R"], trial_R), p=jnp.where(done, c["p"], trial_p),
            base_R=base_R, base_p=base_p, dx=dx, step=step,
            size_base=jnp.where(accept, size, c["size_base"]), res=res,
            res_base=jnp.where(accept, res, c["res_base"]),
            backtracks=jnp.where(accept, 0, c["backtracks"] + 1),
            iterations=iterations, status=status)

    init = dict(R=R, p=p, base_R=R, base_p=p, dx=jnp.zeros(p.shape[:1] + (6,)),
                step=jnp.array(1.0), size_base=jnp.array(jnp.inf), res=jnp.array(jnp.inf),
                res_base=jnp.array(jnp.inf),
                backtracks=jnp.array(0), iterations=jnp.array(0), status=jnp.array(0))
    c = jax.lax.while_loop(lambda c: c["status"] == 0, body, init)
    return c["R"], c["p"], c["iterations"] - 1, c["res"], c["status"] == 1


def _secant(R, p, R_prev, p_prev, ratio):
    """Lie-group secant predictor ``H exp(ratio log(H_prev^-1 H))`` per node (spec 5)."""
    def one(Ri, pi, Rq, pq):
        d = lie.log_se3(lie.relative_pose(Rq, pq, Ri, pi))
        return lie.compose_exp(Ri, pi, ratio * d)
    return jax.vmap(one)(R, p, R_prev, p_prev)


def _continuation(model: Model, settings: StaticSettings) -> Equilibrium:
    """Adaptive load continuation lam: 0 -> 1 with Newton at each level (spec section 5)."""
    dlam_max = 1.0 / settings.load_steps
    dlam_min = dlam_max * settings.min_step_fraction
    ref = load_scale(model)

    def body(c):
        lam_try = c["lam"] + c["dlam"]
        lam_try = jnp.where(lam_try > 1.0 - 1e-9, 1.0, lam_try)  # no sliver step from round-off
        ratio = (lam_try - c["lam"]) / jnp.maximum(c["lam"] - c["lam_prev"], 1e-300)
        use_secant = c["accepted"] >= 1
        Rs, ps = _secant(c["R"], c["p"], c["R_prev"], c["p_prev"], jnp.where(use_secant, ratio, 0.0))
        R, p, its, res, ok = _newton(model, settings, Rs, ps, lam_try, ref)
        grow = jnp.where(its < 5, 1.5, 1.0)
        new = dict(c)
        new["R"] = jnp.where(ok, R, c["R"])
        new["p"] = jnp.where(ok, p, c["p"])
        new["R_prev"] = jnp.where(ok, c["R"], c["R_prev"])
        new["p_prev"] = jnp.where(ok, c["p"], c["p_prev"])
        new["lam_prev"] = jnp.where(ok, c["lam"], c["lam_prev"])
        new["lam"] = jnp.where(ok, lam_try, c["lam"])
        new["dlam"] = jnp.where(ok, jnp.minimum(c["dlam"] * grow, dlam_max), 0.5 * c["dlam"])
        new["accepted"] = c["accepted"] + ok
        new["failures"] = c["failures"] + (~ok)
        new["iterations"] = c["iterations"] + its
        new["residual"] = jnp.where(ok, res, c["residual"])
        new["attempts"] = c["attempts"] + 1
        return new

    def running(c):
        return ((c["lam"] < 1.0) & (c["dlam"] >= dlam_min)
                & (c["attempts"] < settings.max_attempts))

    zero_i = jnp.array(0)
    init = dict(R=model.R0, p=model.p0, R_prev=model.R0, p_prev=model.p0,
                lam=jnp.array(0.0), lam_prev=jnp.array(0.0), dlam=jnp.array(dlam_max),
                accepted=zero_i, failures=zero_i, iterations=zero_i, attempts=zero_i,
                residual=jnp.array(jnp.inf))
    c = jax.lax.while_loop(running, body, init)
    return Equilibrium(c["R"], c["p"], c["lam"] >= 1.0, c["iterations"], c["residual"],
                       c["lam"], c["accepted"], c["failures"])


@jax.custom_jvp
def _implicit(model: Model, R, p):
    """Identity on a converged equilibrium; its derivative is the IFT one (see module doc)."""
    return R, p


@_implicit.defjvp
def _implicit_jvp(primals, tangents):
    model, R, p = primals
    dmodel = tangents[0]
    _, dr = jax.jvp(lambda m: residual(m, R, p, 1.0), (model,), (dmodel,))
    _, blocks = residual_and_tangent(model, R, p, 1.0)
    dxi = implicit_solve(blocks, -dr)
    # d/dt [R exp(t dxi)] at t = 0: (R skew(dxi_w), R dxi_u)
    dR = jnp.einsum("nij,njk->nik", R, jax.vmap(lie.skew)(dxi[:, 3:]))
    dp = jnp.einsum("nij,nj->ni", R, dxi[:, :3])
    return (R, p), (dR, dp)


@jit(static_argnames="settings")
def solve_static(model: Model, settings: StaticSettings = StaticSettings()) -> Equilibrium:
    """Static equilibrium of ``model`` under its full loads (spec S70-S71).

    Returns an :class:`Equilibrium`; when ``converged`` is False, ``load_level`` says how
    far the continuation got and R, p hold the last converged state. Differentiable in
    all Model arrays (implicit function theorem; valid where ``converged`` is True).
    """
    eq = _continuation(jax.lax.stop_gradient(model), settings)
    R, p = _implicit(model, eq.R, eq.p)
    return eq._replace(R=R, p=p)


def settings_from_scene(solver) -> StaticSettings:
    """StaticSettings from a scene's ``[solver]`` table."""
    return StaticSettings(tolerance=float(solver.tolerance),
                          max_iterations=int(solver.max_iterations),
                          load_steps=int(solver.load_steps))
