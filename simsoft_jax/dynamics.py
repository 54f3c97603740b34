"""Lie-group generalized-alpha time integration (spec algorithm.md section 4).

Unknowns per step: the nodal increments ``w = h Delta q`` (N,6); everything else is
eliminated (spec S66): ``a(w) = (w/h - v_n - (1/2 - beta) h a_n)/(beta h)``,
``v(w) = v_n + (1 - gamma) h a_n + gamma h a(w)``,
``vdot(w) = ((1 - alpha_m) a(w) + alpha_m a_n - alpha_f vdot_n)/(1 - alpha_f)``,
``q_{n+1} = q_n o exp(w)`` (S54). Newton on ``F(w) = r(q(w), v(w), vdot(w), t_{n+1})``
with the exact iteration matrix ``M beta' + C_t gamma' + K_t T_SE3(w)`` (S61, S66) built
from element blocks (closed-form stress and dead-load tangents, ``jacfwd`` of the
gyroscopic and follower-load terms; block-tridiagonal), factorized once and reused over
iterations and steps while the iteration contracts (modified Newton, see
:func:`_newton_step`), starting from a predictor chosen from the recent accelerations
(:func:`newton_memory.predicted_increment`). Parameters from rho_inf (S53).
Held dofs (clamps, pins, drives) are eliminated: their ``w`` is prescribed (spec 4.5).
A step whose Newton solve fails is retried with halved sub-steps before the run stops
and reports where. Rollouts are ``lax.scan``; gradients go through each step's Newton
solve by the implicit function theorem (``differentiable=True``, see :func:`simulate`).
"""
from __future__ import annotations

import dataclasses
import time
from functools import partial
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from . import element, inertia, lie
from ._xla import jit
from .assembly import (_nodal_load, apply_constraints, assemble_blocks, assemble_vector,
                       block_solve, dead_distributed_force, element_force_and_tangent,
                       element_load_force, factorize, follower_distributed_load,
                       implicit_solve, nodal_load_and_tangent, solve_factored)
from .drives import held_increments, reduce, slide_maps
from .loads import LoadChannels, build_channels, loaded_model
from .model import Model
from .newton_memory import (NewtonMemory, empty_newton_memory, predicted_increment,
                            remember_step)
from .statics import step_norm


class DynamicSettings(NamedTuple):
    """Static settings of a rollout (hashable). dt (s); steps: number of time steps;
    rho_inf in [0, 1]; save_every: keep every k-th state; tolerance: Newton stops when the
    largest nodal correction is below it (translations / char_length, rotations in rad);
    max_halvings: sub-stepping depth before a step is declared failed."""
    dt: float
    steps: int
    rho_inf: float = 0.9
    save_every: int = 1
    tolerance: float = 1e-10
    max_iterations: int = 25
    max_halvings: int = 6


def alpha_parameters(rho_inf: float):
    """``(alpha_m, alpha_f, gamma, beta)`` of the generalized-alpha scheme (spec S53)."""
    alpha_m = (2.0 * rho_inf - 1.0) / (rho_inf + 1.0)
    alpha_f = rho_inf / (rho_inf + 1.0)
    gamma = 0.5 + alpha_f - alpha_m
    return alpha_m, alpha_f, gamma, 0.25 * (gamma + 0.5) ** 2


@dataclasses.dataclass(frozen=True)
class Dynamics:
    """Dynamic data of a scene beyond the Model. maps (E,G,6,12), masses (E,12,12):
    element inertia (see :mod:`simsoft_jax.inertia`); channels: time-dependent loads;
    v0 (N,6): initial nodal body velocities; drive_times (D,S), drive_displacement (D,S,3),
    drive_rotation (D,S,3): drive tables (world frame, relative to the start pose);
    drive_slide (D,3): unit world direction along which a drive's node slides freely
    (``slides_along``; zeros for drives that hold all six dofs).
    Static: inertia_kind, drive_nodes (tuple of node indices), slide_drives (tuple of the
    indices, into the drives, of the sliding ones)."""
    maps: jax.Array
    masses: jax.Array
    channels: LoadChannels
    v0: jax.Array
    drive_times: jax.Array
    drive_displacement: jax.Array
    drive_rotation: jax.Array
    drive_slide: jax.Array
    inertia_kind: str = "consistent"
    drive_nodes: tuple = ()
    slide_drives: tuple = ()


jax.tree_util.register_dataclass(
    Dynamics, data_fields=["maps", "masses", "channels", "v0", "drive_times",
                           "drive_displacement", "drive_rotation", "drive_slide"],
    meta_fields=["inertia_kind", "drive_nodes", "slide_drives"])


class State(NamedTuple):
    """Nodal frames R (N,3,3), p (N,3); body velocities v, accelerations vd and the
    generalized-alpha pseudo-acceleration a (N,6); time t (s)."""
    R: jax.Array
    p: jax.Array
    v: jax.Array
    vd: jax.Array
    a: jax.Array
    t: jax.Array


class Trajectory(NamedTuple):
    """Saved states (every save_every steps, the initial one first): time (T,), R (T,N,3,3),
    p (T,N,3), v (T,N,6). converged: every step converged; failed_at: time of the first
    failed step (nan if none); iterations (steps,): Newton iterations per step (all
    sub-steps); substeps (steps,); final: the last State."""
    time: jax.Array
    R: jax.Array
    p: jax.Array
    v: jax.Array
    converged: jax.Array
    failed_at: jax.Array
    iterations: jax.Array
    substeps: jax.Array
    final: State


# ------------------------------------------------------------------------------ building

def build_dynamics(model: Model, scene, inertia_kind: str | None = None) -> Dynamics:
    """Inertia, load channels, initial velocities and drives of a dynamic scene."""
    kind = inertia_kind or getattr(scene.solver, "inertia", "consistent")
    maps, masses = inertia.element_inertia(model.d0, model.length, model.inertia, kind)
    s = model.structure
    rods = {r.name: r for r in s.rods}
    R0, p0 = np.asarray(model.R0), np.asarray(model.p0)
    v0 = np.zeros((s.n_nodes, 6))
    for iv in scene.initial_velocity:
        info = rods[iv.rod]
        base = p0[info.first_node]
        for i in range(info.first_node, info.first_node + info.nodes):
            v_world = iv.linear + np.cross(iv.angular, p0[i] - base)
            v0[i] = np.concatenate([R0[i].T @ v_world, R0[i].T @ iv.angular])
    for rod in scene.rods:  # a restart (initial.result): the saved body velocities
        if getattr(rod, "initial_velocities", None) is not None:
            first = rods[rod.name].first_node
            v0[first:first + rod.nodes] = rod.initial_velocities
    drives = [c for c in scene.constraints if c.kind == "drive"]
    width = max([1] + [len(c.times) for c in drives])

    def hold_last(values):  # pad a (S, ...) table to width rows, holding the last row
        return np.concatenate([values, np.repeat(values[-1:], width - len(values), axis=0)])

    k = len(drives)
    times = np.array([np.concatenate([c.times, c.times[-1] + 1.0 + np.arange(width - len(c.times))])
                      for c in drives]).reshape(k, width)
    disp = np.array([hold_last(c.displacement) for c in drives]).reshape(k, width, 3)
    rot = np.array([hold_last(c.rotation) for c in drives]).reshape(k, width, 3)
    nodes = tuple(rods[c.rod].first_node + c.node for c in drives)
    slide = np.zeros((k, 3))
    for j, c in enumerate(drives):
        if c.slides_along is not None:
            e = np.asarray(c.slides_along, float)
            slide[j] = e / np.linalg.norm(e)
    sliding = tuple(j for j, c in enumerate(drives) if c.slides_along is not None)
    f64 = lambda a: jnp.asarray(a, jnp.float64)  # noqa: E731
    return Dynamics(maps, masses, build_channels(scene, s), f64(v0), f64(times), f64(disp),
                    f64(rot), f64(slide), kind, nodes, sliding)


# ------------------------------------------------------------------------------ residual

def _element_args(model: Model, dyn: Dynamics, R, p, v, vd):
    a = jnp.asarray(model.structure.element_nodes)
    d = jax.vmap(element.relative_twist)(R[a], p[a], R[a + 1], p[a + 1])
    ve = jnp.concatenate([v[a], v[a + 1]], axis=1)
    vde = jnp.concatenate([vd[a], vd[a + 1]], axis=1)
    return (R[a], d, ve, vde, dyn.maps, dyn.masses, model.d0, model.length, model.stiffness,
            model.inertia, model.viscosity, model.distributed_world, model.distributed_local)


def _element_residual(model: Model, dyn: Dynamics, damped: bool):
    """Dynamic element residual (12,): inertia + gyroscopic + elastic + viscous - loads."""
    dead, follower = dead_distributed_force(model, 1.0), follower_distributed_load(model, 1.0)

    def residual(RA, d, ve, vde, maps, mass, d0, length, stiffness, inert, visc, qw, ql):
        P = element.strain_map(d)
        r = mass @ vde + inertia.gyroscopic_force(maps, length, inert, ve, dyn.inertia_kind, mass)
        r = r + element.internal_force(P, d, d0, length, stiffness)
        if damped:
            r = r + element.viscous_force(P, ve, length, visc)
        return r + element_load_force(RA, d, P, length, dead, follower, inert[0], qw, ql)

    return residual


def dynamic_residual(model: Model, dyn: Dynamics, R, p, v, vd, damped: bool, masked=True):
    """Global dynamic residual (N,6) (spec S47), held dofs zeroed (unless ``masked=False``)."""
    s = model.structure
    f = jax.vmap(_element_residual(model, dyn, damped))(*_element_args(model, dyn, R, p, v, vd))
    r = assemble_vector(s.n_nodes, s.element_nodes, f)
    if s.has_nodal_dead or s.has_nodal_follower:
        r = r + jax.vmap(_nodal_load(model, 1.0))(R, model.nodal_dead, model.nodal_follower)
    return r * s.free_mask() if masked else r


def residual_and_iteration_matrix(model, dyn, R, p, v, vd, w, beta_p, gamma_p, damped,
                                  slide=None):
    """Residual (N,6) and block-tridiagonal ``M beta' + C_t gamma' + K_t T(w)`` (S61, S66).
    ``slide = (C, B, mask)`` (see :func:`drives.slide_maps`) reduces sliding drive nodes to their
    slide unknown before the held dofs are eliminated."""
    s = model.structure
    n = s.n_nodes
    a = jnp.asarray(s.element_nodes)
    dead, follower = dead_distributed_force(model, 1.0), follower_distributed_load(model, 1.0)
    T = jax.vmap(lie.tangent_se3)(w)

    def value_and_blocks(RA, d, ve, vde, maps, mass, d0, length, stiffness, inert, visc, qw, ql):
        # K_t: closed-form stress and load tangents (spec S42, S44), in the chart of S37;
        # C_t: gyroscopic (jacfwd in the 12 velocities) and viscous P^T Ups P / L (S42)
        P = element.strain_map(d)
        stress, stress_jac = stiffness * (d - d0) / length, jnp.diag(stiffness / length)
        gyro = lambda u: inertia.gyroscopic_force(  # noqa: E731
            maps, length, inert, u, dyn.inertia_kind, mass)
        C, g = jax.jacfwd(lambda u: (gyro(u),) * 2, has_aux=True)(ve)
        if damped:
            rate = lambda dd: element.strain_map(dd) @ ve / length  # noqa: E731
            stress = stress + visc * rate(d)
            stress_jac = stress_jac + visc[:, None] * jax.jacfwd(rate)(d)
            C = C + P.T @ (visc[:, None] * P) / length
        f, K = element_force_and_tangent(P, d, stress, stress_jac, RA, length, dead, follower,
                                         inert[0], qw, ql)
        return f + mass @ vde + g, K, C, mass

    f_el, K_el, C_el, M_el = jax.vmap(value_and_blocks)(*_element_args(model, dyn, R, p, v, vd))
    TA, TB = T[a], T[a + 1]
    K_el = jnp.concatenate([K_el[:, :, :6] @ TA, K_el[:, :, 6:] @ TB], axis=2)
    S_el = M_el * beta_p + C_el * gamma_p + K_el
    r = assemble_vector(n, s.element_nodes, f_el)
    diag, upper, lower = assemble_blocks(n, s.element_nodes, S_el)
    if s.has_nodal_dead or s.has_nodal_follower:
        f_n, k_n = nodal_load_and_tangent(model, 1.0, R)
        r = r + f_n
        diag = diag + k_n @ T
    if slide is not None:
        C, B, mask = slide
        r, blocks = reduce(C, B, r, (diag, upper, lower))
        return apply_constraints(mask, r, blocks)
    return apply_constraints(s.free_mask(), r, (diag, upper, lower))


# ------------------------------------------------------------------------------ one step

def _fields(settings: DynamicSettings, state: State, w, h):
    """``a, v, vdot`` of the new state as functions of ``w`` (spec S66)."""
    alpha_m, alpha_f, gamma, beta = alpha_parameters(settings.rho_inf)
    a1 = (w / h - state.v - (0.5 - beta) * h * state.a) / (beta * h)
    v1 = state.v + (1.0 - gamma) * h * state.a + gamma * h * a1
    vd1 = ((1.0 - alpha_m) * a1 + alpha_m * state.a - alpha_f * state.vd) / (1.0 - alpha_f)
    return a1, v1, vd1


def _step_functions(model, dyn, settings, state, h, damped):
    """F(w) pieces for one step of size h from ``state``."""
    alpha_m, alpha_f, gamma, beta = alpha_parameters(settings.rho_inf)
    beta_p = (1.0 - alpha_m) / (h * h * beta * (1.0 - alpha_f))
    gamma_p = gamma / (h * beta)
    t1 = state.t + h
    loaded = loaded_model(model, dyn.channels, t1)

    def new_state(w):
        a1, v1, vd1 = _fields(settings, state, w, h)
        R1, p1 = jax.vmap(lie.compose_exp)(state.R, state.p, w)
        return State(R1, p1, v1, vd1, a1, t1)

    def residual(w):
        s1 = new_state(w)
        return dynamic_residual(loaded, dyn, s1.R, s1.p, s1.v, s1.vd, damped)

    def newton_residual(w):  # the residual of residual_and_matrix, without the matrix
        if not dyn.slide_drives:
            return residual(w)
        s1 = new_state(w)
        C, _, mask = slide_maps(model, dyn, state.R, w)
        r = dynamic_residual(loaded, dyn, s1.R, s1.p, s1.v, s1.vd, damped, masked=False)
        return jnp.einsum("nij,nj->ni", C, r) * mask

    def residual_and_matrix(w):
        s1 = new_state(w)
        slide = slide_maps(model, dyn, state.R, w) if dyn.slide_drives else None
        return residual_and_iteration_matrix(loaded, dyn, s1.R, s1.p, s1.v, s1.vd, w,
                                             beta_p, gamma_p, damped, slide)

    return new_state, residual, newton_residual, residual_and_matrix, t1


# A reused iteration matrix is kept while each correction is at most this fraction of the
# previous one (linear contraction of modified Newton); otherwise it is rebuilt for the
# next iteration (see _newton_step for which corrections are kept).
_CONTRACTION_LIMIT = 0.1


def _newton_step(model, dyn, settings, state, h, damped, memory: NewtonMemory):
    """Modified Newton on F(w) = 0 (spec S66) from :func:`newton_memory.predicted_increment`.
    Returns (w, iterations, converged, memory), the memory with the matrix in use at the end.

    The factorized iteration matrix ``S_t`` (S61) is reused from earlier iterations and
    earlier steps of the same size h; only the residual is evaluated at each iterate. A
    correction from a reused matrix that contracts by less than ``_CONTRACTION_LIMIT``
    (but contracts) is applied and the matrix rebuilt at the new iterate; one that does
    not contract, is not finite or leaves the rotation branch is discarded and the matrix
    rebuilt at the current iterate; the matrix is also rebuilt at the start of a step when
    the previous step rebuilt it. With a fresh matrix the iteration is exact Newton.
    Approximating ``S_t`` changes only the convergence rate, not the solution (spec 4.4). Converged when the estimated
    distance to the solution, ``|dw| theta / (1 - theta)`` with the observed contraction
    ``theta`` (``|dw|`` itself at the first iteration), is below the tolerance.
    """
    _, _, newton_residual, residual_and_matrix, t1 = _step_functions(
        model, dyn, settings, state, h, damped)
    mask = model.structure.free_mask()
    alpha_m, alpha_f, _, beta = alpha_parameters(settings.rho_inf)
    w0 = predicted_increment(state.v, state.vd, state.a, h, memory, alpha_m, alpha_f, beta)
    w0 = jnp.where(mask > 0, w0, held_increments(model, dyn, state, t1))

    def body(c):
        w, it, _, _, factors, fresh, previous, rebuilt = c
        r = newton_residual(w)  # once in the program; the branch builds only the matrix
        factors = jax.lax.cond(fresh, lambda w, _: factorize(residual_and_matrix(w)[1]),
                               lambda _, f: f, w, factors)
        dw = -solve_factored(factors, r)
        if dyn.slide_drives:  # back from slide unknowns to increments (spec: slides_along)
            dw = jnp.einsum("nij,nj->ni", slide_maps(model, dyn, state.R, w)[1], dw)
        # cap nodal rotation corrections at pi/4 (spec 4.7.6): keeps Newton on the branch
        rot = jnp.max(jnp.linalg.norm(dw[:, 3:], axis=1))
        dw = dw * jnp.minimum(1.0, 0.25 * jnp.pi / jnp.maximum(rot, 1e-300))
        size = step_norm(model, dw)
        finite = jnp.all(jnp.isfinite(dw))
        bad = ~finite | (jnp.max(jnp.linalg.norm((w + dw)[:, 3:], axis=1)) > 0.5 * jnp.pi)
        theta = size / previous
        reject = ~fresh & (bad | (theta >= 1.0))
        rebuild = reject | (~fresh & (theta > _CONTRACTION_LIMIT))
        w_new = jnp.where(reject | ~finite, w, w + jnp.where(finite, dw, 0.0))
        estimate = jnp.where(jnp.isfinite(previous) & (theta < _CONTRACTION_LIMIT),
                             size * theta / (1.0 - theta), size)
        converged = ~reject & finite & (estimate <= settings.tolerance)
        failed = (fresh & bad) | (it + 1 >= settings.max_iterations)
        return (w_new, it + 1, converged, failed & ~converged, factors, rebuild,
                jnp.where(reject, previous, size), rebuilt | rebuild)

    stale = memory.renew | (jnp.abs(memory.h - h) > 1e-9 * h)
    init = (w0, jnp.array(0), jnp.array(False), jnp.array(False), memory.factors, stale,
            jnp.array(jnp.inf), jnp.array(False))
    w, it, ok, _, factors, _, _, rebuilt = jax.lax.while_loop(lambda c: ~(c[2] | c[3]),
                                                              body, init)
    return w, it, ok, memory._replace(factors=factors, h=jnp.asarray(h, jnp.float64),
                                      renew=rebuilt)


@partial(jax.custom_jvp, nondiff_argnums=(0, 1))
def _implicit_increment(settings, damped, model, dyn, state, h, w):
    """Identity on a converged step increment ``w``; its derivative is the implicit-function
    one: ``dw_free = -J^-1 dF`` with the held dofs following the prescribed motion."""
    return w


@_implicit_increment.defjvp
def _implicit_increment_jvp(settings, damped, primals, tangents):
    model, dyn, state, h, w = primals
    dmodel, ddyn, dstate, dh, _ = tangents
    mask = model.structure.free_mask()

    def held(m, dy, st, hh):
        return held_increments(m, dy, st, st.t + hh)

    def F(m, dy, st, hh):  # residual with the free w frozen and the held w prescribed
        residual = _step_functions(m, dy, settings, st, hh, damped)[1]
        return residual(jnp.where(mask > 0, w, held(m, dy, st, hh)))

    primal_args, tangent_args = (model, dyn, state, h), (dmodel, ddyn, dstate, dh)
    _, dF = jax.jvp(F, primal_args, tangent_args)
    _, dheld = jax.jvp(held, primal_args, tangent_args)
    residual_and_matrix = _step_functions(model, dyn, settings, state, h, damped)[3]
    dw = implicit_solve(residual_and_matrix(w)[1], -dF)
    return w, jnp.where(mask > 0, dw, dheld)


def _attempt(model, dyn, settings, state, h, damped, differentiable, memory):
    """One generalized-alpha step of size h: (new state, iterations, converged, memory);
    an accepted step becomes the predictor's history."""
    new_state = _step_functions(model, dyn, settings, state, h, damped)[0]
    m, dy, st, hh, memory = jax.lax.stop_gradient((model, dyn, state, h, memory))
    if differentiable:
        w, it, ok, memory = _newton_step(m, dy, settings, st, hh, damped, memory)
        w = _implicit_increment(settings, damped, model, dyn, state, h, w)
    else:
        w, it, ok, memory = _newton_step(model, dyn, settings, state, h, damped, memory)
    memory = remember_step(memory, st.vd, hh, ok)
    return new_state(w), it, ok, memory


def _advance(model, dyn, settings, state, damped, memory):
    """One macro step of size dt, with sub-stepping on failure (halve, up to max_halvings).
    Returns (state, iterations, sub-steps, converged, Newton memory)."""
    dt = settings.dt
    t_target = state.t + dt
    h_min = dt / 2.0**settings.max_halvings

    def body(c):
        st, h, its, subs, failed, memory = c
        h_try = jnp.minimum(h, t_target - st.t)
        new, it, ok, memory = _attempt(model, dyn, settings, st, h_try, damped, False, memory)
        keep = lambda a, b: jax.tree_util.tree_map(  # noqa: E731
            lambda x, y: jnp.where(ok, x, y), a, b)
        st = keep(new, st)
        h = jnp.where(ok, jnp.minimum(2.0 * h, dt), 0.5 * h)
        return st, h, its + it, subs + ok, failed | (h < h_min * (1 - 1e-12)), memory

    def running(c):
        st, _, _, _, failed, _ = c
        return (st.t < t_target - 1e-12 * dt) & ~failed

    st, _, its, subs, failed, memory = jax.lax.while_loop(
        running, body, (state, jnp.asarray(dt), jnp.array(0), jnp.array(0), jnp.array(False),
                        memory))
    return st, its, subs, ~failed, memory


def initial_state(model: Model, dyn: Dynamics, t0=0.0, damped=None) -> State:
    """Start state: model.R0/p0, velocities dyn.v0 and consistent accelerations from
    ``M vdot_0 = -g(q_0, v_0, t_0)`` (spec S67); ``a_0 = vdot_0`` (S68)."""
    damped = _is_damped(model) if damped is None else damped
    t0 = jnp.asarray(t0, jnp.float64)
    loaded = loaded_model(model, dyn.channels, t0)
    zeros = jnp.zeros_like(dyn.v0)
    g = dynamic_residual(loaded, dyn, model.R0, model.p0, dyn.v0, zeros, damped,
                         masked=False)
    s = model.structure
    blocks = assemble_blocks(s.n_nodes, s.element_nodes, dyn.masses)
    if dyn.slide_drives:  # a sliding node accelerates along its direction (w = 0: B = C^T)
        C, B, mask = slide_maps(model, dyn, model.R0, zeros)
        g, blocks = apply_constraints(mask, *reduce(C, B, g, blocks))
        vd0 = jnp.einsum("nij,nj->ni", B, -block_solve(blocks, g))
    else:
        g, blocks = apply_constraints(s.free_mask(), g, blocks)
        vd0 = -block_solve(blocks, g)
    return State(model.R0, model.p0, dyn.v0, vd0, vd0, t0)


def _is_damped(model: Model) -> bool:
    try:
        return bool(np.any(np.asarray(model.viscosity) != 0.0))
    except jax.errors.TracerArrayConversionError:
        return True


def simulate(model: Model, dyn: Dynamics, settings: DynamicSettings, state: State | None = None,
             damped: bool = True, differentiable: bool = False) -> Trajectory:
    """Roll out ``settings.steps`` steps of size ``settings.dt`` (``lax.scan``).

    ``damped=False`` leaves the viscous terms out of the traced program (use it when all
    viscosities are zero). ``differentiable=True`` makes every step a single Newton solve
    differentiated by the implicit function theorem (checkpointed scan: memory O(saved
    states)); a step that fails is then reported (no sub-stepping). Otherwise failed steps
    are retried with halved sub-steps. After the first failure the state is frozen and
    ``converged`` is False, ``failed_at`` the time of the failing step. A given ``state``
    is cast to float64 first, so weakly typed inputs do not trigger a recompilation.
    """
    if state is not None:
        state = State(*(jnp.asarray(x, jnp.float64) for x in state))
    return _simulate(model, dyn, settings, state, damped=damped, differentiable=differentiable)


@jit(static_argnames=("settings", "damped", "differentiable"))
def _simulate(model: Model, dyn: Dynamics, settings: DynamicSettings, state: State | None,
              damped: bool = True, differentiable: bool = False) -> Trajectory:
    if differentiable and dyn.slide_drives:
        raise ValueError("constraints: differentiable=True does not support drives with "
                         "slides_along yet (the implicit-function derivative would be wrong)")
    state = initial_state(model, dyn, damped=damped) if state is None else state

    def step(carry, _):
        st, failed, failed_at, memory = carry
        if differentiable:
            new, its, ok, memory = _attempt(model, dyn, settings, st, settings.dt, damped, True,
                                            memory)
            subs = jnp.array(1)
        else:
            new, its, subs, ok, memory = _advance(model, dyn, settings, st, damped, memory)
        ok = ok & ~failed
        new = jax.tree_util.tree_map(lambda x, y: jnp.where(ok, x, y), new, st)
        failed_at = jnp.where(failed | ok, failed_at, st.t)
        return (new, failed | ~ok, failed_at, memory), (its, subs)

    def save_block(carry, _):
        carry, (its, subs) = jax.lax.scan(
            jax.checkpoint(step) if differentiable else step, carry, None,
            length=settings.save_every)
        st = carry[0]
        return carry, (st.t, st.R, st.p, st.v, its, subs)

    n_saves = settings.steps // settings.save_every
    carry0 = (state, jnp.array(False), jnp.array(jnp.nan), empty_newton_memory(model.structure.n_nodes))
    (final, failed, failed_at, _), (t, R, p, v, its, subs) = jax.lax.scan(
        save_block, carry0, None, length=n_saves)
    cat = lambda first, rest: jnp.concatenate([first[None], rest])  # noqa: E731
    return Trajectory(cat(state.t, t), cat(state.R, R), cat(state.p, p), cat(state.v, v),
                      ~failed, failed_at, its.reshape(-1), subs.reshape(-1), final)


def energy(model: Model, dyn: Dynamics, R, p, v):
    """Kinetic ``1/2 sum v_e^T M_e v_e`` plus strain energy ``sum (L/2) eps^T K eps`` (J)."""
    a = jnp.asarray(model.structure.element_nodes)
    ve = jnp.concatenate([v[a], v[a + 1]], axis=1)
    kinetic = 0.5 * jnp.einsum("ei,eij,ej->", ve, dyn.masses, ve)
    d = jax.vmap(element.relative_twist)(R[a], p[a], R[a + 1], p[a + 1])
    eps = (d - model.d0) / model.length[:, None]
    strain = 0.5 * jnp.sum(model.length[:, None] * model.stiffness * eps * eps)
    return kinetic + strain


_initial_state = jax.jit(initial_state, static_argnames="damped")


def _chunk_saves(total_saves: int, save_every: int, target_steps: int = 200) -> int:
    """Largest divisor of ``total_saves`` whose chunk has at most ~target_steps steps."""
    limit = max(1, target_steps // save_every)
    return max(k for k in range(1, min(total_saves, limit) + 1) if total_saves % k == 0)


def rollout(model: Model, dyn: Dynamics, dt: float, t_end: float, rho_inf: float = 0.9,
            save_every: int = 1, damped: bool | None = None, progress=None, compiled=None,
            tolerance: float = 1e-10, max_iterations: int = 25):
    """Run from the initial state to ``t_end`` in compiled chunks of the same length.

    Any ``t_end`` reuses one compiled chunk (no recompilation for longer runs or new
    numbers); ``progress(t, t_end)`` is called after every chunk; the run stops at the
    first failed step. ``compiled`` may be a dict used as a cache of compiled chunks.
    Returns ``(Trajectory, compile_seconds)`` with all saved states concatenated.
    """
    damped = _is_damped(model) if damped is None else damped
    steps = max(1, int(round(t_end / dt)))
    save_every = min(save_every, steps)
    total_saves = steps // save_every
    per_chunk = _chunk_saves(total_saves, save_every)
    settings = DynamicSettings(dt=float(dt), steps=per_chunk * save_every,
                               rho_inf=float(rho_inf), save_every=save_every,
                               tolerance=float(tolerance), max_iterations=int(max_iterations))
    compiled = {} if compiled is None else compiled
    key = (model.structure, settings, damped, jax.tree_util.tree_structure(dyn),
           tuple(x.shape for x in jax.tree_util.tree_leaves(dyn)))
    start = time.perf_counter()
    state = jax.block_until_ready(_initial_state(model, dyn, damped=damped))
    if key not in compiled:
        compiled[key] = _simulate.lower(model, dyn, settings, state, damped=damped).compile()
    compile_seconds = time.perf_counter() - start
    chunks = []
    for _ in range(total_saves // per_chunk):
        traj = compiled[key](model, dyn, state)
        chunks.append(traj if not chunks else traj._replace(
            time=traj.time[1:], R=traj.R[1:], p=traj.p[1:], v=traj.v[1:]))
        state = traj.final
        if progress is not None:
            progress(float(state.t), t_end)
        if not bool(traj.converged):
            break
    cat = lambda name: jnp.concatenate([getattr(c, name) for c in chunks])  # noqa: E731
    failed = [c for c in chunks if not bool(c.converged)]
    return Trajectory(cat("time"), cat("R"), cat("p"), cat("v"), jnp.asarray(not failed),
                      failed[0].failed_at if failed else jnp.asarray(jnp.nan),
                      cat("iterations"), cat("substeps"), state), compile_seconds
