"""Rollouts: the start state (spec S67-S68), ``simulate`` (one compiled ``lax.scan`` over
the steps) and the energy of a state.

``simulate(model, settings, state=None)`` reads everything from the one Model: inertia
(element mass matrices computed inside the trace), loads and their time laws, drive
tables, initial velocities. Gradients go through each step's Newton solve by the implicit
function theorem (``differentiable=True``: reverse mode by the discrete adjoint,
:mod:`.adjoint`; ``"forward"``: each step's implicit derivative, forward and reverse).
Closed-loop control: a policy called at the start of every step returns the Model that
step is solved with (:func:`actuated`).
"""
from __future__ import annotations

import contextlib
import dataclasses
from typing import NamedTuple

import jax
import jax.numpy as jnp
from jax.ad_checkpoint import checkpoint_name

import numpy as np

from .. import compile_cache
from ...physics import element, stick_slip
from ...math import lie
from ...couplings import mechanisms
from ...math.xla import jit, traced
from ...physics.assembly import apply_constraints, assemble_blocks, attachments_and_tangents
from ...math.linalg import implicit_solve, implicit_solve_coupled
from ...couplings.drives import reduce, slide_maps
from ...model.loads import loads_at
from ...model.model import Model
from ..statics import as_traced
from ..status import Status, describe, poison_gradient, raise_if_failed
from .adjoint import Programs, Records, reverse_rollout
from .memory import empty_newton_memory
from .newton import advance, replay
from .residual import border_sizes, dynamic_residual, element_inertia
from .scheme import DynamicSettings, State


class Trajectory(NamedTuple):
    """Saved states (every save_every steps, the initial one first): time (T,), R (T,N,3,3),
    p (T,N,3), v (T,N,6). converged: every step converged; failed_at: time (s) at the start
    of the first failed step (nan if none); iterations (steps,): Newton iterations per step
    (all sub-steps); substeps (steps,); final: the last State; status: how the run ended
    (:class:`~simsoft_jax.solvers.status.Status` code); cause: why the failing Newton solve failed;
    residual: weighted residual norm (N) of the last Newton iterate of the failed step
    (nan if none). After a failure the state is frozen: the saved states after
    ``failed_at`` repeat the last good state (the host driver :func:`rollout` cuts them).
    multipliers (T,M): at the saved times, the joint multipliers, then the tensions (N) of
    displacement-controlled tendons (:func:`~.residual.border_sizes`; None without
    either); the start's row is 0 (not solved: the start accelerations take the tendons
    slack). control_memory: the controller's memory after the last step of a closed-loop
    rollout that carries one (:func:`simulate`; None otherwise)."""
    time: jax.Array
    R: jax.Array
    p: jax.Array
    v: jax.Array
    converged: jax.Array
    failed_at: jax.Array
    iterations: jax.Array
    substeps: jax.Array
    final: State
    status: jax.Array
    cause: jax.Array
    residual: jax.Array
    multipliers: jax.Array | None = None
    control_memory: object = None

    def message(self) -> str:
        """How the run ended, in words (concrete, unbatched results)."""
        where = float(self.failed_at) if not bool(self.converged) else float(self.time[-1])
        residual = float(self.residual) if not bool(self.converged) else 0.0
        return describe("dynamic", self.status, self.cause, where, residual)


def initial_state(model: Model, t0=0.0, inert=None) -> State:
    """Start state: model.R0/p0, velocities model.v0 and consistent accelerations from
    ``M vdot_0 = -g(q_0, v_0, t_0)`` (spec S67); ``a_0 = vdot_0`` (S68). With joints the
    accelerations also meet the joints' acceleration constraint, with multipliers ``mu``:
    ``M vdot_0 + G^T mu = -g``, ``G vdot_0 = -g''[v_0, v_0]``
    (:func:`simsoft_jax.couplings.mechanisms.constraint_curvature`). ``inert``: the model's
    :func:`~.residual.element_inertia` when the caller has it already (a program that
    computes it once compiles faster). With stick-slip friction the anchors are the start
    stations (:func:`simsoft_jax.physics.stick_slip.initial`: no friction force yet)."""
    t0 = jnp.asarray(t0, jnp.float64)
    inert = element_inertia(model) if inert is None else inert
    zeros = jnp.zeros_like(model.v0)
    g = dynamic_residual(loads_at(model, t0), inert, model.R0, model.p0, model.v0, zeros,
                         masked=False)
    s = model.structure
    blocks = assemble_blocks(s.n_nodes, s.element_nodes, inert.masses)
    attached = attachments_and_tangents(model, 1.0, model.R0, model.v0, zeros, dynamic=True)
    if attached is not None:   # attached masses' spatial inertia at their nodes
        blocks = (blocks[0] + attached[3],) + tuple(blocks[1:])
    mask = s.free_mask()
    if s.slide_drives:  # a sliding node accelerates along its direction (w = 0: B = C^T)
        C, B, mask = slide_maps(model, model.R0, zeros)
        g, blocks = reduce(C, B, g, blocks)
    g, blocks = apply_constraints(mask, g, blocks)
    if s.joints:
        mu = jnp.zeros(mechanisms.multiplier_count(s), g.dtype)
        system = mechanisms.couple(model, model.R0, model.p0, mu, g, blocks)
        nb = 6 * len(s.coupling_nodes)
        r_z = system.r_z.at[nb:].set(
            mechanisms.constraint_curvature(model, model.R0, model.p0, model.v0))
        x, z = implicit_solve_coupled(*system[1:5], -system.r, -r_z, s.identity_nodes())
        vd0 = mechanisms.split(s, x, z)[0]
    else:
        vd0 = -implicit_solve(blocks, g, s.identity_nodes())
    if s.slide_drives:
        vd0 = jnp.einsum("nij,nj->ni", B, vd0)
    return State(model.R0, model.p0, model.v0, vd0, vd0, t0,
                 stick_slip.initial(model, model.R0, model.p0, t0))


def simulate(model: Model, settings: DynamicSettings, state: State | None = None,
             differentiable: bool | str = False, throw: bool = False, control=None,
             control_params=None, control_memory=None) -> Trajectory:
    """Roll out ``settings.steps`` steps of size ``settings.dt`` (``lax.scan``).

    Compiled once per model structure and static settings (``steps``, ``save_every``,
    ``max_halvings``, ``tangent``): ``dt``, ``rho_inf``, ``tolerance`` and
    ``max_iterations`` are traced, so a study over them does not recompile. Called on
    arrays (not inside ``jit``, ``vmap`` or ``grad``) from the start state, without
    ``differentiable`` or ``control``, it runs the program of :func:`~simsoft_jax.run`
    for this structure (:func:`~.driver.rollout`, in chunks: one compile for both and
    for any ``steps``, said on stderr, kept in the cache folder) and returns NumPy
    arrays; the saved states after a failure then take no Newton iteration. Otherwise
    :func:`rollout_program` runs (JAX's persistent cache keeps it,
    :func:`~simsoft_jax.solvers.compile_cache.enable`; its first call on arrays for a structure
    says so too, :func:`~simsoft_jax.solvers.compile_cache.first_call`). ``steps`` not a
    multiple of ``save_every``: the last ``steps % save_every`` steps are not taken.
    A step whose Newton solve fails is retried with halved sub-steps (down to
    ``dt / 2**max_halvings``). ``differentiable`` differentiates every accepted
    (sub-)step by the implicit function theorem at its solution; derivatives of a
    failed rollout are NaN. ``True`` (or ``"reverse"``): reverse mode only (``jax.grad``,
    ``jax.vjp``, ``jax.jacrev``; ``jax.jvp`` raises JAX's TypeError about a custom_vjp)
    by the discrete adjoint (:func:`~.adjoint.reverse_rollout`): the forward pass is the
    plain rollout (called on arrays with ``save_every == 1``, from the start state or a
    given one, the program of :func:`~simsoft_jax.run` itself: no new compile), the backward pass a
    program of its own, a reverse scan over the steps with one transposed solve each
    (memory: the states of every step). ``"forward"``: each step carries its implicit
    derivative (:func:`~.newton.replay`; checkpointed scan, memory O(saved states)),
    for ``jax.jvp`` / ``jax.jacfwd`` (reverse mode works too, with a longer first
    compile); closed-loop ``control`` always takes this path. After the first failure the
    state is frozen and ``converged`` is False, ``failed_at`` the time of the failing step,
    ``status``/``cause``/:meth:`Trajectory.message` say why. ``throw=True`` raises
    :class:`~simsoft_jax.solvers.status.SolveError` instead. ``state`` defaults to
    :func:`initial_state`; it is cast to float64 first, so weakly typed inputs do not
    trigger a recompilation; with stick-slip friction a ``state`` without anchors gets
    its stations as anchors (:func:`simsoft_jax.physics.stick_slip.initial`).

    Closed-loop control: ``control(t, state, model, control_params) -> Model`` is called
    at the start of every step with the :class:`State` there and the step is solved with
    the Model it returns (zero-order hold over the step; sub-steps too), see
    :func:`actuated`. With ``control_memory`` (any pytree: an integrator, a filter) the
    call is ``control(t, state, model, control_params, memory) -> (Model, memory)`` and
    the last memory is ``Trajectory.control_memory``. Gradients in ``control_params``
    (and ``control_memory``) go through the whole loop with ``differentiable=True``.
    ``control`` is part of the compiled program: pass the same function object to reuse
    it (a new closure or lambda per call compiles again); put what changes in
    ``control_params``. The default start state has the accelerations of the model the
    policy returns for it (:func:`initial_state`; the policy is called once more there,
    its memory update discarded).
    """
    compile_cache.enable()
    if state is not None:
        state = State(*(None if x is None else jnp.asarray(x, jnp.float64)
                        for x in state))
        if state.anchor is None:   # stick-slip from a state without anchors: unstretched
            state = state._replace(anchor=stick_slip.initial(model, state.R, state.p, state.t))
    if control is None and (control_params is not None or control_memory is not None):
        raise ValueError("control: control_params and control_memory need a control policy")
    if differentiable not in (False, True, "reverse", "forward"):
        raise ValueError(f"differentiable: expected False, True, 'reverse' or 'forward', "
                         f"got {differentiable!r}")
    if _chunked(model, settings, state, differentiable, control):
        traj = driven(model, settings)
    elif differentiable in (True, "reverse") and control is None:
        traj = reverse_rollout(ADJOINT, model, as_traced(settings), state)
    else:
        args = (model, as_traced(settings), state, control_params, control_memory)
        with (contextlib.nullcontext() if traced(args) else
              compile_cache.first_call("rollout", args, differentiable, control)):
            traj = rollout_program(*args, differentiable=bool(differentiable),
                                   control=control)
    if throw:
        raise_if_failed("dynamic", traj.converged, traj.status, traj.cause, traj.failed_at,
                        traj.residual)
    return traj


def driven(model: Model, settings: DynamicSettings, state: State | None = None
           ) -> Trajectory:
    """The rollout from ``state`` (default: the start state) by the program of
    :func:`~simsoft_jax.run` for this structure (:func:`~.driver.rollout`, in chunks,
    kept in the cache folder), as :func:`simulate` returns it (NumPy arrays, not cut
    after a failure)."""
    from ..programs import PROGRAMS    # both import this module
    from .driver import rollout, with_arrays
    steps = settings.steps // settings.save_every * settings.save_every
    return rollout(with_arrays(model), float(settings.dt), steps * float(settings.dt),
                   float(settings.rho_inf), settings.save_every, compiled=PROGRAMS,
                   tolerance=float(settings.tolerance),
                   max_iterations=int(settings.max_iterations), tangent=settings.tangent,
                   max_halvings=settings.max_halvings, cut=False, state=state,
                   globalized=settings.globalized)[0]


def _chunked(model: Model, settings: DynamicSettings, state, differentiable: bool,
             control) -> bool:
    """Whether :func:`simulate` runs the rollout program of :func:`~simsoft_jax.run`
    (:func:`~.driver.rollout`, in chunks): called on arrays (not inside ``jit``, ``vmap``
    or ``grad``), from the start state, without differentiation or control, with scalar
    settings, a positive ``dt`` and at least one save block."""
    return (state is None and control is None and not differentiable
            and settings.steps >= settings.save_every and not traced(model, settings)
            and all(np.ndim(x) == 0 for x in jax.tree_util.tree_leaves(settings))
            and float(settings.dt) > 0.0)


def actuated(control, params, state: State, model: Model, memory):
    """The Model a step from ``state`` is solved with, and the controller's next memory:
    ``control(state.t, state, model, params)`` (memory None) or ``control(state.t, state,
    model, params, memory) -> (Model, memory)``. The policy must return ``model`` with
    arrays replaced (``model.replace(...)``): same structure, same shapes; a ValueError
    names the first field that differs."""
    if memory is None:
        out = control(state.t, state, model, params)
    else:
        out, memory = control(state.t, state, model, params, memory)
    if not isinstance(out, Model):
        raise ValueError(f"control: the policy returned {type(out).__name__}, not a Model "
                         "(return model.replace(...))")
    if out.structure != model.structure:
        raise ValueError("control: the policy changed model.structure (only arrays may be "
                         "replaced)")
    for field in dataclasses.fields(Model)[1:]:   # the arrays after the structure
        given, got = getattr(model, field.name), getattr(out, field.name)
        if (jax.tree_util.tree_structure(given) != jax.tree_util.tree_structure(got)
                or [jnp.shape(x) for x in jax.tree_util.tree_leaves(given)]
                != [jnp.shape(x) for x in jax.tree_util.tree_leaves(got)]):
            raise ValueError(f"control: the policy changed the shape of model.{field.name}")
    return out, memory


def _same_inertia(a: Model, b: Model) -> bool:
    """The arrays the element inertia is computed from are the same objects (trace time)."""
    return a.inertia is b.inertia and a.d0 is b.d0 and a.length is b.length


# The differentiable rollout's steps are checkpointed (memory O(saved states)), keeping
# each step's Newton solve (its accepted sub-steps, solved without derivative): the
# backward pass recomputes only the steps' implicit derivatives, not their solves.
SAVE_ADVANCE = jax.checkpoint_policies.save_only_these_names("advance")


class _StepCarry(NamedTuple):
    state: State
    failed: jax.Array
    failed_at: jax.Array
    status: jax.Array
    cause: jax.Array
    residual: jax.Array
    memory: object
    control: object = None


def first_carry(model: Model, state: State, control_memory=None) -> _StepCarry:
    """What the steps carry at the start of a rollout from ``state``: no failure yet, an
    empty Newton memory and the controller's memory (None without one)."""
    return _StepCarry(state, jnp.array(False), jnp.array(jnp.nan),
                      jnp.array(int(Status.CONVERGED)), jnp.array(int(Status.NOT_RUN)),
                      jnp.array(jnp.nan), empty_newton_memory(
                          model.structure.n_nodes, *border_sizes(model.structure),
                          model.structure.identity_nodes()), control_memory)


def stepper(model: Model, inert, settings: DynamicSettings, differentiable: bool,
            control=None, control_params=None, record: bool = False):
    """One time step of size ``settings.dt`` as a ``lax.scan`` body ``(carry, _) ->
    (carry, (iterations, substeps))``; after the first failure the state stays frozen and
    the carry keeps the time, status, cause and residual of that failure. With a
    ``control`` policy the step is solved with the Model of :func:`actuated` (the element
    inertia is computed again only when the policy replaced what it depends on).
    ``differentiable``: each step carries its implicit derivative (:func:`~.newton.replay`).
    ``record``: the outputs also hold the step's :class:`~.adjoint.Records` (its start
    state and accepted sub-steps, for the adjoint's backward pass)."""
    def step(c: _StepCarry, _):
        m, ine, control_memory = model, inert, c.control
        if control is not None:
            m, control_memory = actuated(control, control_params, c.state, model,
                                         c.control)
            ine = inert if _same_inertia(m, model) else element_inertia(m)
        adv = advance(*jax.lax.stop_gradient((m, ine, settings, c.state, c.memory)),
                      keep_substeps=differentiable or record)
        adv = checkpoint_name(adv, "advance")
        new, its, subs, memory = adv.state, adv.iterations, adv.substeps, adv.memory
        status, cause, residual = adv.status, adv.cause, adv.residual
        if differentiable:   # the same sub-steps again, each with its implicit derivative
            new = replay(m, ine, settings, c.state, adv.sub, adv.substeps)
        ok = (status == Status.CONVERGED) & ~c.failed
        hold = lambda x, y: jnp.where(ok, x, y)  # noqa: E731
        new = jax.tree_util.tree_map(hold, new, c.state)
        control_memory = jax.tree_util.tree_map(hold, control_memory, c.control)
        first = ~c.failed & ~ok
        keep = lambda now, before: jnp.where(first, now, before)  # noqa: E731
        out = (its, subs, Records(c.state, adv.sub, adv.substeps, ok)) if record else (its,
                                                                                      subs)
        return _StepCarry(new, c.failed | ~ok, keep(c.state.t, c.failed_at),
                          keep(status, c.status), keep(cause, c.cause),
                          keep(residual, c.residual), memory, control_memory), out
    return step


def _blocks(step, first: _StepCarry, settings: DynamicSettings):
    """The steps in blocks of ``save_every`` from the carry ``first``: the last carry, and
    per block the state at its end, the multipliers there, then the step outputs of
    ``step`` (stacked (blocks, save_every))."""
    def save_block(c, _):
        c, out = jax.lax.scan(step, c, None, length=settings.save_every)
        return c, (c.state, c.memory.multipliers) + out
    return jax.lax.scan(save_block, first, None,
                        length=settings.steps // settings.save_every)


def _run(model: Model, settings: DynamicSettings, state: State | None, control_params,
         control_memory, differentiable, control, record: bool = False):
    """The rollout of :func:`rollout_program` and, with ``record``, the steps'
    :class:`~.adjoint.Records` (else None)."""
    inert = element_inertia(model)
    if state is None:
        state = initial_state(model, 0.0, inert)
        if control is not None:   # accelerations consistent with the first step's model
            first_model = actuated(control, control_params, state, model, control_memory)[0]
            state = initial_state(first_model, 0.0, inert if _same_inertia(
                first_model, model) else None)
    first = first_carry(model, state, control_memory)
    step = stepper(model, inert, settings, bool(differentiable), control, control_params,
                   record)
    final, (saved, mu, its, subs, *records) = _blocks(
        jax.checkpoint(step, policy=SAVE_ADVANCE) if differentiable else step, first,
        settings)
    cat = lambda first, rest: jnp.concatenate([first[None], rest])  # noqa: E731
    converged = ~final.failed
    inputs = (model, state, control_params, control_memory)
    R, p, v = (poison_gradient(converged, x, inputs) for x in
               (cat(state.R, saved.R), cat(state.p, saved.p), cat(state.v, saved.v)))
    # None without multipliers: a zero-size output would trouble batched maps
    mu = cat(first.memory.multipliers, mu) if mu.shape[-1] else None
    return Trajectory(cat(state.t, saved.t), R, p, v, converged, final.failed_at,
                      its.reshape(-1), subs.reshape(-1), final.state, final.status,
                      final.cause, final.residual, mu, final.control), (
                          records[0] if record else None)


@jit(static_argnames=("differentiable", "control"))
def rollout_program(model: Model, settings: DynamicSettings, state: State | None,
              control_params=None, control_memory=None, differentiable=False,
              control=None) -> Trajectory:
    """The rollout of :func:`simulate` as one compiled program; ``differentiable``: each
    step carries its implicit derivative (:func:`~.newton.replay`, forward and reverse
    mode)."""
    return _run(model, settings, state, control_params, control_memory, differentiable,
                control)[0]


@jit
def recorded_program(model: Model, settings: DynamicSettings, state: State | None):
    """The rollout of :func:`rollout_program` without derivative and the steps'
    :class:`~.adjoint.Records`, for the adjoint's backward pass."""
    return _run(model, settings, state, None, None, False, None, record=True)


ADJOINT = Programs(plain=rollout_program, recorded=recorded_program, driven=driven,
                   initial=initial_state)
"""The rollout programs of the adjoint of :func:`simulate` (``differentiable=True``)."""


def energy(model: Model, R, p, v):
    """Kinetic ``1/2 sum v_e^T M_e v_e`` (plus ``1/2 V^T M6 V`` of attached masses,
    :mod:`~simsoft_jax.physics.terms.masses`) plus strain energy ``sum (L/2) eps^T K eps`` (J)."""
    a = jnp.asarray(model.structure.element_nodes)
    ve = jnp.concatenate([v[a], v[a + 1]], axis=1)
    kinetic = 0.5 * jnp.einsum("ei,eij,ej->", ve, element_inertia(model).masses, ve)
    if model.structure.mass_nodes:
        V = v[jnp.asarray(model.structure.mass_nodes)]
        M6 = jax.vmap(lie.spatial_inertia)(model.mass, model.mass_offset, model.mass_inertia)
        kinetic = kinetic + 0.5 * jnp.einsum("ki,kij,kj->", V, M6, V)
    d = jax.vmap(element.relative_twist)(R[a], p[a], R[a + 1], p[a + 1])
    strain = jnp.sum(jax.vmap(element.strain_energy)(d, model.d0, model.length,
                                                     model.stiffness))
    return kinetic + strain
