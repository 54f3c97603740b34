"""One generalized-alpha step: modified Newton on ``F(w) = 0`` (spec S66), its implicit
derivative, and sub-stepping of a macro step on failure.

The factorized iteration matrix ``S_t`` (S61) is kept in a :class:`~.memory.NewtonMemory`
and reused over iterations and steps while the iteration contracts; the starting guess
comes from :func:`~.memory.predicted_increment` (globalized: the guess with the least
residual, and a line search, :func:`newton_step`). Held dofs (clamps, pins, drives) are
eliminated: their ``w`` is prescribed (spec 4.5). Each failed Newton solve records why
(:class:`~simsoft_jax.solvers.status.Status`: iteration limit, non-finite, off the rotation branch).
"""
from __future__ import annotations

import dataclasses
from typing import NamedTuple

import jax
import jax.numpy as jnp

from ...couplings import coupling, rod_pairs
from ...physics import stick_slip
from ...physics.terms.contact import STICK_LIMIT
from ..batched import select
from ...math import lie
from ...math.lanes import any_lane
from ...math.linalg import CoupledFactors, factorize_coupled, implicit_solve_coupled
from ...couplings.drives import drive_turn, held_increments, slide_maps
from ..newton import (RUNNING, capped, coupled_step, implicit, iterate, ladder, step_norm,
                      weighted_norm)
from .. import swept_check
from ..status import Status
from .contact_time import unresolved
from .memory import NewtonMemory, predicted_increment, remember_step
from .residual import step_functions
from .scheme import alpha_parameters

# A reused iteration matrix is kept while each correction is at most this fraction of the
# previous one (linear contraction theta of modified Newton); otherwise it is rebuilt for
# the next iteration (see newton_step for which corrections are kept).
_REBUILD_CONTRACTION = 0.2
# The distance-to-solution estimate |dw| theta / (1 - theta) of the convergence test is
# used only below this contraction (|dw| itself above it).
_CONTRACTION_LIMIT = 0.1
# The matrix is also rebuilt at the start of the next step when the last correction of a
# step contracted by more than this: a matrix that old would make the next step take a
# third iteration and soon a rebuild mid-step (followed by a renewal: two builds).
# Measured on the paper's helical scenes (300 steps; benchmarks/README.md, "Fewer matrix
# builds"): with the 0.1 rebuild limit used before, renewal at 0.03 took the synthetic
# scene from 894 to 778 Newton iterations and silicone from 1051 to 871 (0.01-0.05 all
# gain); with it, a rebuild limit of 0.2 saves builds (synthetic 16.2 -> 15.0 ms).
_RENEW_CONTRACTION = 0.03
# Rod-rod contact: the candidate pairs are found once per step at the predicted state,
# for stations moving up to the predicted motion plus this fraction of the largest
# contact radius (m) from there; again only where an iterate moves one further.
_PAIR_MOTION_FLOOR = 0.1
# Line search (settings.globalized): a fresh correction is halved while the merit at the
# iterate it leads to exceeds the merit where it started and the fraction of it applied
# is above this (1, 1/2, ..., 1/16; the last is kept whatever its merit).
_MIN_FRACTION = 0.1
# Stick-slip friction: a step whose fresh corrections had to be halved this many times
# (newton_step) is cycling between sliding directions and ends as at the iteration
# limit, to be sub-stepped, unless it is already the shortest sub-step. Measured on
# cosseratbench's pile (200 steps of 22 ms, docs/cosseratbench.md): 84 of its 86 steps
# that ran to the 25-iteration limit had halved 3 times or more, at 2-4 % of the
# residual they started from; of the 337 that converged, 13 had halved 3 times, 5 had
# 4 times, 0 had 6 times.
_CYCLE_HALVINGS = 4


def least_residual(model, fns, guesses, mu):
    """The guess of ``guesses`` (K,N,6) whose step residual (``fns.system_residual`` with
    multipliers mu (M,)) has the smallest :func:`merit`; held dofs are set afterwards.

    A slack, nearly inextensible rope's nodal rotations carry almost no inertia: their
    accelerations swing from step to step, and extrapolated
    (:func:`~.memory.predicted_increment`) they turn nodes by radians in one step (up to
    18 rad measured on a slack rope pinned at both ends, 40 ms steps), so that the first
    correction leaves the rotation branch or Newton wanders off and the step is halved
    again and again; the constant-velocity or zero increment starts within reach
    (benchmarks/README.md, "Newton on slack ropes")."""
    return guesses[jnp.argmin(jax.lax.map(
        lambda w: merit(model, *fns.system_residual(w, mu)), guesses))]


def merit(model, r, r_z):
    """Size (N) of a step's residual ``(r (N,6), r_z (m,))``: the chains'
    :func:`~simsoft_jax.solvers.newton.weighted_norm` (forces in N, moments / char_length)
    and the coupling nodes' forces (:func:`~simsoft_jax.couplings.coupling.violation`; the
    joints' gaps are held by the convergence test)."""
    res = weighted_norm(model, r)
    violation = coupling.violation(model, r_z)
    return res if violation is None else jnp.sqrt(res ** 2 + violation[0] ** 2)


class _NewtonCarry(NamedTuple):
    """Carry of :func:`newton_step`: the increment w, iterations so far, status (-1
    running, else a Status code), the factors in use and whether to rebuild them (fresh),
    the size of the last kept correction (previous), whether the matrix was rebuilt in
    this step (rebuilt), the weighted residual norm at the last iterate, the joint
    multipliers mu (M,), the last observed contraction theta (0 before there is one), and
    the rod-rod contact's candidate pairs (:class:`~simsoft_jax.couplings.rod_pairs.Tracked`,
    None without rod contact); for the line search (``settings.globalized``) the iterate
    and multipliers the last fresh correction started from (base, base_mu), its merit
    there (base_merit), that correction (step (N,6), step_mu (M,)) and the fraction of
    it applied (0: no correction on trial); halvings: the fresh corrections halved so far
    (stick-slip friction); trials: the stick-slip stations' trial line loads and caps at w
    (:func:`~simsoft_jax.physics.stick_slip.trials`, for :func:`reversal_cut`; None without
    stick-slip friction)."""
    w: jax.Array
    iterations: jax.Array
    status: jax.Array
    factors: CoupledFactors
    fresh: jax.Array
    previous: jax.Array
    rebuilt: jax.Array
    residual: jax.Array
    mu: jax.Array
    theta: jax.Array
    tracked: object = None
    base: jax.Array = None
    base_mu: jax.Array = None
    base_merit: jax.Array = None
    step: jax.Array = None
    step_mu: jax.Array = None
    fraction: jax.Array = None
    halvings: jax.Array = None
    trials: tuple = None


class StepResult(NamedTuple):
    """Outcome of one Newton solve: increment w (N,6), iterations, status (Status code),
    residual (weighted norm at the last iterate, N), memory (with the matrix in use and,
    after a converged solve, its joint multipliers)."""
    w: jax.Array
    iterations: jax.Array
    status: jax.Array
    residual: jax.Array
    memory: NewtonMemory


def reversal_cut(start, end):
    """The fraction (scalar) of a Newton correction at which no stick-slip station that
    slides at both its ends with opposite trial line loads (S1) has passed its point
    nearest to its anchor (on the straight path between its two trials): 1 when none
    reverses. ``start``, ``end``: the stations' trial line loads (E,S,K,3) N/m and caps
    (E,S,K) N/m at the correction's two ends (:func:`~simsoft_jax.physics.stick_slip.trials`).
    Such a correction was made with the station's saturated slope along its slip (g' ~ 0
    in (S2)) while the solution sticks; cut there, the next iterate has it sticking, where
    the slope is its spring's."""
    (t0, c0), (t1, c1) = start, end
    n0 = jnp.sqrt(jnp.sum(t0**2, -1))
    n1 = jnp.sqrt(jnp.sum(t1**2, -1))
    dt = t1 - t0
    reverses = ((n0 > STICK_LIMIT * c0) & (n1 > STICK_LIMIT * c1) & (c0 > 0) & (c1 > 0)
                & (jnp.sum(t0 * t1, -1) < 0.0))
    tau = -jnp.sum(t0 * dt, -1) / jnp.where(reverses, jnp.sum(dt**2, -1), 1.0)
    return jnp.min(jnp.where(reverses, jnp.clip(tau, 0.0, 1.0), 1.0), initial=1.0)


def newton_step(model, inert, settings, state, h, memory: NewtonMemory) -> StepResult:
    """Modified Newton on F(w) = 0 (spec S66) from :func:`memory.predicted_increment`
    (or, with ``settings.globalized``, from the guess of :func:`least_residual`).

    The factorized iteration matrix ``S_t`` (S61) is reused from earlier iterations and
    earlier steps of the same size h; only the residual is evaluated at each iterate. A
    correction from a reused matrix that is smaller than the previous one but more than
    ``_REBUILD_CONTRACTION`` times it is applied and the matrix rebuilt at the new
    iterate; one that does not contract, is not finite or leaves the rotation branch is
    discarded and the matrix rebuilt at the current iterate; the matrix is also rebuilt
    at the start of a step when the previous step rebuilt it or ended with a contraction
    above ``_RENEW_CONTRACTION``. With a fresh matrix the iteration is exact Newton.
    Approximating ``S_t`` changes only the convergence rate, not the solution (spec 4.4).
    With rod-rod contact the predictor and every correction are cut back (halved) until
    they do not carry a rod through another rod
    (:mod:`simsoft_jax.solvers.swept_check`), and with stick-slip friction cut where a
    station sliding at both its ends would have its sliding direction reversed
    (:func:`reversal_cut`); a cut correction never counts as converged.
    Converged when the estimated distance to the solution, ``|dw| theta / (1 - theta)``
    with the observed contraction ``theta`` (``|dw|`` itself at the first iteration and
    for ``theta`` above ``_CONTRACTION_LIMIT``), is below the tolerance and every nodal
    rotation increment, held nodes' included, is below pi/2. Fails (status)
    when a fresh matrix gives a non-finite correction (NONFINITE) or one that takes a
    nodal rotation increment to pi/2 (OFF_BRANCH: the step turns a node too far to be
    resolved; :func:`advance` sub-steps it; also, before any iteration, when a drive
    turns by pi/2 or more in the step, :func:`~simsoft_jax.couplings.drives.drive_turn`), or at
    ``max_iterations``
    (MAX_ITERATIONS; with stick-slip friction also at the ``_CYCLE_HALVINGS``-th halved
    fresh correction of a step longer than the shortest sub-step: Newton cycling between
    a station's sliding directions, which a shorter step resolves). With
    ``settings.globalized``, a backtracking line search: when the iterate a fresh (exact
    Newton) correction led to has a larger :func:`merit` than the iterate it started from,
    the correction is halved from there (the matrix kept),
    while more than ``_MIN_FRACTION`` of it is applied; exact Newton on a slack, nearly inextensible rod
    overshoots (the linearized stretch of a turning element), and its residual then
    grows from iterate to iterate until the step is halved. With joints the unknowns are ``w`` and the
    joint multipliers (index-3 form, Arnold & Bruls 2007: the constraints ``g(q_{n+1}) = 0``
    and forces ``G^T mu`` at ``t_{n+1}``), solved in the bordered system of
    :mod:`simsoft_jax.couplings.mechanisms`; converged also needs the joints to hold to the
    tolerance at the current iterate. Rod-rod contact's candidate pairs are found once, at
    the predicted increment, widened for the stations' predicted motion in the step
    (``_PAIR_MOTION_FLOOR``), and found again only at an iterate where a station has moved
    further (:func:`~simsoft_jax.couplings.rod_pairs.refresh`): every residual and matrix is
    evaluated on pairs that hold every touching pair, so the solution is that of pairs
    found at every iterate.
    """
    functions = fns = step_functions(model, inert, settings.rho_inf, state, h,
                                     settings.tangent)
    mask = model.structure.free_mask()
    alpha_m, alpha_f, _, beta = alpha_parameters(settings.rho_inf)
    w0 = predicted_increment(state.v, state.vd, state.a, h, memory, alpha_m, alpha_f, beta)
    globalized = settings.globalized
    if globalized:
        w0 = least_residual(model, fns, jnp.stack([w0, h * state.v, jnp.zeros_like(w0)]),
                            memory.multipliers)
    w0 = jnp.where(mask > 0, w0, held_increments(model, state, fns.t1))
    # no update carries a rod through another rod: cut back (impacts on obstacles are
    # refused by the contact time, :mod:`.contact_time`)

    def frames(w):
        """Nodal frames ``(R, p)`` (N,3,3), (N,3) of the increment ``w`` (N,6) (S54)."""
        return jax.vmap(lie.compose_exp)(state.R, state.p, w)

    def positions(w):
        return frames(w)[1]

    w0 = jnp.where(mask > 0, swept_check.cut_back(
        model, state.p, lambda t: positions(jnp.where(mask > 0, t * w0, w0)), 1.0,
        obstacles_too=False) * w0, w0)
    sliding = bool(model.structure.slide_drives)
    identity = model.structure.identity_nodes()
    contact = model.structure.self_contact
    if contact:   # rod-rod contact's broad phase out of the loop (_PAIR_MOTION_FLOOR)
        guess = fns.new_state(w0)
        predicted = jnp.sqrt(jnp.max(jnp.sum(
            (rod_pairs.stations(model, guess.R, guess.p)
             - rod_pairs.stations(model, state.R, state.p)) ** 2, -1)))
        tracked = rod_pairs.track(model, guess.R, guess.p, predicted + _PAIR_MOTION_FLOOR
                                  * jnp.max(jnp.asarray(model.contact_radius)))
    # Stick-slip friction: exact Newton can cycle between a station's two sliding
    # directions (its friction saturated at mu f_n both ways, flat in between iterates,
    # while the solution sticks); halving a correction that does not shrink breaks the
    # cycle (the onset-of-contact block of tests/test_friction_dynamics.py)
    damped = stick_slip.active(model)
    # ... and one that keeps cycling (_CYCLE_HALVINGS) ends early where a sub-step can
    # take over (advance: the shortest sub-step is dt / 2**max_halvings)
    splittable = h > 1.5 * settings.dt / 2.0 ** settings.max_halvings

    def held(r_z):
        """The constraints hold at the current iterate: the joints' gaps / char_length and
        rotations and the displacement-controlled tendons' length mismatches /
        char_length (:func:`~simsoft_jax.couplings.coupling.violation`) below the tolerance
        (with a reused matrix the corrections of ``w`` can shrink long before the
        constraints are met, so they are tested too)."""
        violation = coupling.violation(model, r_z)
        return True if violation is None else violation[1] <= settings.tolerance

    def body(c: _NewtonCarry) -> _NewtonCarry:
        fns, tracked = functions, c.tracked
        if contact:   # the pairs hold at w (found again if a station moved too far)
            now = functions.new_state(c.w)
            tracked = rod_pairs.refresh(model, c.tracked, now.R, now.p)
            fns = step_functions(model, inert, settings.rho_inf, state, h, settings.tangent,
                                 tracked.pairs)
        r, r_z = fns.system_residual(c.w, c.mu)  # once; the branch builds only the matrix
        now_merit = merit(model, r, r_z)
        back = ((c.fraction > _MIN_FRACTION) & (now_merit > c.base_merit) if globalized
                else jnp.array(False))
        # a branch also under vmap (any_lane): lanes that keep their matrix select it back
        factors = jax.lax.cond(
            any_lane(c.fresh),
            lambda w, mu, f: select(c.fresh,
                                    factorize_coupled(*fns.system(w, mu)[1:5], identity), f),
            lambda _, __, f: f, c.w, c.mu, c.factors)
        dw, dmu = coupled_step(model, factors, r, r_z)
        if sliding:  # back from slide unknowns to increments (spec: slides_along)
            dw = jnp.einsum("nij,nj->ni", slide_maps(model, state.R, c.w)[1], dw)
        # cap nodal rotation corrections at pi/4 (spec 4.7.6): keeps Newton on the branch
        dw, dmu = capped(0.25 * jnp.pi, dw, dmu)
        fraction = swept_check.cut_back(model, positions(c.w),
                                        lambda t: positions(c.w + t * dw), 1.0,
                                        obstacles_too=False)
        dw, dmu = fraction * dw, fraction * dmu
        halvings = c.halvings
        if damped:   # no station's sliding direction reversed by a correction
            ends = stick_slip.trials(fns.loaded, *frames(c.w + dw))
            turn = reversal_cut(c.trials, ends)
            dw, dmu, fraction = turn * dw, turn * dmu, turn * fraction
        size = full = step_norm(model, dw)
        if damped:   # a fresh correction no smaller than the last full one, not cut, is halved
            halve = c.fresh & (turn == 1.0) & (size >= c.previous)
            dw, dmu = jnp.where(halve, 0.5 * dw, dw), jnp.where(halve, 0.5 * dmu, dmu)
            size = jnp.where(halve, 0.5 * size, size)
            halvings = halvings + halve
        finite = jnp.all(jnp.isfinite(dw))
        off_branch = jnp.max(jnp.linalg.norm((c.w + dw)[:, 3:], axis=1)) > 0.5 * jnp.pi
        bad = ~finite | off_branch
        theta = size / c.previous
        reject = ~c.fresh & (bad | (theta >= 1.0))
        rebuild = reject | (~c.fresh & (theta > _REBUILD_CONTRACTION))
        keep = reject | ~finite
        w_new = jnp.where(keep, c.w, c.w + jnp.where(finite, dw, 0.0))
        mu_new = jnp.where(keep, c.mu, c.mu + jnp.where(finite, dmu, 0.0))
        estimate = jnp.where(jnp.isfinite(c.previous) & (theta < _CONTRACTION_LIMIT),
                             size * theta / (1.0 - theta), size)
        # an increment off the branch is never accepted, however well it solves F = 0: a
        # step that turns a node by pi/2 or more is not resolved (sub-stepped or reported)
        converged = (~reject & finite & ~off_branch & (estimate <= settings.tolerance)
                     & held(r_z) & (fraction == 1.0))   # a cut correction is no estimate
        status = ladder(converged, ((c.fresh & ~finite, Status.NONFINITE),
                                    (c.fresh & off_branch, Status.OFF_BRANCH),
                                    ((c.iterations + 1 >= settings.max_iterations)
                                     | (splittable & (halvings >= _CYCLE_HALVINGS)),
                                     Status.MAX_ITERATIONS)))
        trial = c.fresh & ~keep
        half = 0.5 * c.fraction
        w_next = jnp.where(back, c.base + half * c.step, w_new)
        trials = None
        if damped:   # at w_next: those at the correction's end where it was applied whole
            stay, whole = ~back & keep, ~back & ~keep & (turn == 1.0) & ~halve
            kept = select(stay, c.trials, ends)
            again = ~stay & ~whole
            trials = jax.lax.cond(
                any_lane(again),
                lambda w: select(again, stick_slip.trials(fns.loaded, *frames(w)), kept),
                lambda _: kept, w_next)
        limit = jnp.where(c.iterations + 1 >= settings.max_iterations, Status.MAX_ITERATIONS,
                          RUNNING)
        return _NewtonCarry(
            w_next,
            c.iterations + 1, jnp.where(back, limit, status), factors, ~back & rebuild,
            jnp.where(back | reject, c.previous, full), c.rebuilt | (~back & rebuild),
            weighted_norm(model, r), jnp.where(back, c.base_mu + half * c.step_mu, mu_new),
            jnp.where(back | reject | ~jnp.isfinite(c.previous), c.theta, theta), tracked,
            jnp.where(back | ~trial, c.base, c.w), jnp.where(back | ~trial, c.base_mu, c.mu),
            jnp.where(back | ~trial, c.base_merit, now_merit),
            jnp.where(back | ~trial, c.step, w_new - c.w),
            jnp.where(back | ~trial, c.step_mu, mu_new - c.mu),
            jnp.where(back, half, jnp.where(trial, 1.0, 0.0)), halvings, trials)

    stale = memory.renew | (jnp.abs(memory.h - h) > 1e-9 * h)
    # drives that turn by pi/2 or more in the step: off the branch before any iteration
    start = (jnp.where(drive_turn(model, state.t, fns.t1) >= 0.5 * jnp.pi, Status.OFF_BRANCH,
                       RUNNING) if model.structure.drive_nodes else RUNNING)
    init = _NewtonCarry(w0, jnp.array(0), jnp.asarray(start), memory.factors, stale,
                        jnp.array(jnp.inf), jnp.array(False), jnp.array(jnp.inf),
                        memory.multipliers, jnp.array(0.0), tracked if contact else None,
                        w0, memory.multipliers, jnp.array(jnp.inf), jnp.zeros_like(w0),
                        jnp.zeros_like(memory.multipliers), jnp.array(0.0), jnp.array(0),
                        stick_slip.trials(functions.loaded, *frames(w0)) if damped else None)
    c = iterate(body, init)
    memory = memory._replace(
        factors=c.factors, h=jnp.asarray(h, jnp.float64),
        renew=c.rebuilt | (c.theta > _RENEW_CONTRACTION),
        multipliers=jnp.where(c.status == Status.CONVERGED, c.mu, memory.multipliers))
    return StepResult(c.w, c.iterations, c.status, c.residual, memory)


@dataclasses.dataclass(frozen=True)
class StepProblem:
    """One generalized-alpha step as an implicit problem for
    :func:`simsoft_jax.solvers.newton.implicit`: ``params = (model, inert, settings, state, h)``,
    ``solution = (w, mu)``, the step's increment (N,6) and multipliers (M,) solving
    ``F(w, mu) = 0`` (spec S66; with joints the bordered system of
    :mod:`simsoft_jax.couplings.mechanisms`): ``[dw_free; dmu] = -J^-1 dF``, the held dofs following
    their prescribed motion (clamps, drives)."""

    def prescribed(self, params, solution):
        """The held dofs' prescribed increments (clamps, drives); a sliding drive's node
        moves by its prescribed increment plus its solved slide ``ds`` (held fixed) along
        the slide column ``b`` of :func:`~simsoft_jax.couplings.drives.slide_maps`, whose
        derivative ``d w_h + db ds`` is its prescribed motion (the change of slide
        ``d ds`` is solved)."""
        model, _, _, state, h = params
        held = 1.0 - model.structure.free_mask()
        w_h = held_increments(model, state, state.t + h)
        if model.structure.slide_drives:
            b = slide_maps(model, state.R, w_h)[1][:, :3, 0]     # (N,3); used at slides
            slide = jax.lax.stop_gradient(
                jnp.sum((solution[0][:, :3] - w_h[:, :3]) * b, axis=1)
                / jnp.maximum(jnp.sum(b * b, axis=1), 1e-300))
            sliding = jnp.zeros(b.shape[0]).at[
                jnp.asarray(model.structure.drive_nodes, int)[
                    jnp.asarray(model.structure.slide_drives, int)]].set(1.0)
            w_h = w_h.at[:, :3].add((sliding * slide)[:, None] * b)
        return held * w_h, jnp.zeros_like(solution[1])

    def residual(self, params, solution, delta):
        model, inert, settings, state, h = params
        return step_functions(model, inert, settings.rho_inf, state, h).system_residual(
            solution[0] + delta[0], solution[1] + delta[1])

    def linear_solve(self, params, solution, rhs):
        return self.system_solve(params, self.residual_and_system(params, solution,
                                                                  (0.0, 0.0))[1], rhs)

    def residual_and_system(self, params, solution, delta):
        """``((r, r_z), system)``: :meth:`residual` and the bordered iteration matrix
        (:class:`~simsoft_jax.couplings.mechanisms.Coupled`) at the solution moved by
        ``delta``, from one evaluation of the element blocks (the matrix's kinematics are
        the residual's): the reverse mode differentiates the residual and keeps the
        matrix (:func:`simsoft_jax.solvers.newton.implicit_cotangent`)."""
        model, inert, settings, state, h = params
        system = step_functions(model, inert, settings.rho_inf, state, h,
                                settings.tangent).system(solution[0] + delta[0],
                                                         solution[1] + delta[1])
        return (system.r, system.r_z), system

    def system_solve(self, params, system, rhs):
        """``J^-1 rhs`` on the free unknowns, ``J`` the ``system`` of
        :meth:`residual_and_system`, split into increments and multipliers."""
        model = params[0]
        x, z = implicit_solve_coupled(system.blocks, system.B, system.C, system.D, *rhs,
                                      model.structure.identity_nodes())
        return coupling.split(model.structure, x, z)

    def merge(self, params, solution, free, moved):
        """The free dofs' increments, the held ones' prescribed motion, and for a sliding
        drive its prescribed motion plus the solved change of slide along its direction
        (the slide unknown is the node's first dof, mapped back as in
        :func:`newton_step`)."""
        model, state = params[0], params[3]
        mask = model.structure.free_mask()
        dw = jnp.where(mask > 0, free[0], moved[0])
        if model.structure.slide_drives:
            _, B, slide_mask = slide_maps(model, state.R, solution[0])
            slid = jnp.where((mask == 0) & (slide_mask > 0), free[0], 0.0)
            dw = dw + jnp.einsum("nij,nj->ni", B, slid)
        return dw, free[1]

    def push(self, params, solution, delta):
        return delta

    def valid(self, params):
        return True


class Attempt(NamedTuple):
    """One step attempt: the new state, Newton iterations, status, residual, memory, and
    the solved increment (N,6) with its multipliers (M,)."""
    state: object
    iterations: jax.Array
    status: jax.Array
    residual: jax.Array
    memory: NewtonMemory
    increment: jax.Array
    multipliers: jax.Array


def attempt(model, inert, settings, state, h, memory) -> Attempt:
    """One generalized-alpha step of size h (no derivative: :func:`replay` gives it); an
    accepted step becomes the predictor's history. A converged step that an impact makes
    too long for its contact time ends with status ``CONTACT_UNRESOLVED``
    (:func:`~.contact_time.unresolved`)."""
    m, ine, se, st, hh, mem = jax.lax.stop_gradient((model, inert, settings, state, h, memory))
    res = newton_step(m, ine, se, st, hh, mem)
    state1 = step_functions(m, ine, se.rho_inf, st, hh).new_state(res.w)
    # a converged step that an impact makes too long is refused (.contact_time)
    status = jnp.where((res.status == Status.CONVERGED) & unresolved(m, st, state1, hh),
                       Status.CONTACT_UNRESOLVED, res.status)
    if m.structure.self_contact:   # a non-finite residual from too many rod-rod pairs
        status = jax.lax.cond(status == Status.NONFINITE,
                              lambda: jnp.where(rod_pairs.overflows(m, state1.R, state1.p),
                                                Status.CONTACT_PAIRS, status),
                              lambda: status)
    memory = remember_step(res.memory, st.vd, hh, status == Status.CONVERGED)
    return Attempt(state1, res.iterations, status, res.residual, memory, res.w,
                   res.memory.multipliers)


class SubSteps(NamedTuple):
    """The accepted sub-steps of one macro step, in order, for :func:`replay`: fractions
    (K,) of dt (0 past ``count``), increments (K,N,6) and multipliers (K,M); K =
    ``2**max_halvings``, the most sub-steps a macro step can take."""
    fractions: jax.Array
    increments: jax.Array
    multipliers: jax.Array


def replay(model, inert, settings, state, sub: SubSteps, count):
    """The end state of a macro step from ``state`` through its ``count`` accepted
    sub-steps ``sub`` (found by :func:`advance`), each increment carrying the implicit
    derivative of its step (:class:`StepProblem`): the value is the solved one, and
    ``jax.grad`` / ``jax.jvp`` through it are those of the sub-stepped solution. A step
    taken whole (``count == 1``, the common case) is one increment; only a sub-stepped one
    runs the scan over the slots, where unused slots are skipped (``lax.cond``: no work,
    forward or backward)."""
    def sub_step(st, fraction, w, mu):
        h = fraction * settings.dt
        w_d = implicit(StepProblem(), (model, inert, settings, st, h), (w, mu))[0]
        return step_functions(model, inert, settings.rho_inf, st, h).new_state(w_d)

    def slot(st, xs):
        i, fraction, w, mu = xs
        return jax.lax.cond(i < count, lambda st: sub_step(st, fraction, w, mu),
                            lambda st: st, st), None

    def whole(st):
        return sub_step(st, sub.fractions[0], sub.increments[0], sub.multipliers[0])

    def in_pieces(st):
        k = sub.fractions.shape[0]
        return jax.lax.scan(slot, st, (jnp.arange(k), sub.fractions, sub.increments,
                                       sub.multipliers))[0]

    return jax.lax.cond(count == 1, whole, in_pieces, state)


class Advance(NamedTuple):
    """One macro step: state, Newton iterations (all sub-steps), accepted sub-steps,
    status (CONVERGED or STEP_TOO_SMALL), cause (last Newton failure, NOT_RUN if none),
    residual (at the last attempt), memory; sub: the accepted sub-steps (:class:`SubSteps`,
    only when asked for, else None)."""
    state: object
    iterations: jax.Array
    substeps: jax.Array
    status: jax.Array
    cause: jax.Array
    residual: jax.Array
    memory: NewtonMemory
    sub: SubSteps = None


class _AdvanceCarry(NamedTuple):
    state: object
    h: jax.Array
    iterations: jax.Array
    substeps: jax.Array
    failed: jax.Array
    cause: jax.Array
    residual: jax.Array
    memory: NewtonMemory
    sub: SubSteps


def advance(model, inert, settings, state, memory, keep_substeps: bool = False) -> Advance:
    """One macro step of size dt, with sub-stepping on failure (halve, up to max_halvings;
    after a success the sub-step doubles again, up to dt). ``keep_substeps``: also record
    the accepted sub-steps (:class:`SubSteps`) for :func:`replay`."""
    dt = settings.dt
    t_target = state.t + dt
    h_min = dt / 2.0**settings.max_halvings

    def body(c: _AdvanceCarry) -> _AdvanceCarry:
        h_try = jnp.minimum(c.h, t_target - c.state.t)
        att = attempt(model, inert, settings, c.state, h_try, c.memory)
        ok = att.status == Status.CONVERGED
        st = jax.tree_util.tree_map(lambda x, y: jnp.where(ok, x, y), att.state, c.state)
        h = jnp.where(ok, jnp.minimum(2.0 * c.h, dt), 0.5 * c.h)
        sub = c.sub
        if keep_substeps:
            slot = jnp.where(ok, c.substeps, sub.fractions.shape[0])   # out of range: dropped
            sub = SubSteps(sub.fractions.at[slot].set(h_try / dt, mode="drop"),
                           sub.increments.at[slot].set(att.increment, mode="drop"),
                           sub.multipliers.at[slot].set(att.multipliers, mode="drop"))
        return _AdvanceCarry(st, h, c.iterations + att.iterations, c.substeps + ok,
                             c.failed | (h < h_min * (1 - 1e-12)),
                             jnp.where(ok, c.cause, att.status), att.residual, att.memory,
                             sub)

    def running(c: _AdvanceCarry):
        return (c.state.t < t_target - 1e-12 * dt) & ~c.failed

    zero = jnp.array(0)
    sub = None
    if keep_substeps:
        k = 2 ** settings.max_halvings
        sub = SubSteps(jnp.zeros(k), jnp.zeros((k,) + state.p.shape[:1] + (6,)),
                       jnp.zeros((k,) + memory.multipliers.shape))
    c = jax.lax.while_loop(running, body, _AdvanceCarry(
        state, jnp.asarray(dt, jnp.float64), zero, zero, jnp.array(False),
        jnp.array(int(Status.NOT_RUN)), jnp.array(0.0), memory, sub))
    status = jnp.where(c.failed, Status.STEP_TOO_SMALL, Status.CONVERGED)
    return Advance(c.state, c.iterations, c.substeps, status, c.cause, c.residual, c.memory,
                   c.sub)
