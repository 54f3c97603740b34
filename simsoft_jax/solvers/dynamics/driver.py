"""Host driver of long rollouts (``sj.run``, the command line): one compiled program per
model structure, called in chunks of a fixed number of saved states.

The program computes the start state (spec S67-S68) at its first call and advances
``CHUNK_STEPS`` steps' worth of save blocks (``save_every`` steps each); the step size of
every block is an input, so any ``dt`` and ``t_end`` (and the shorter closing block that
ends a run exactly at ``t_end``) reuse it: it is compiled once per model structure and
integer settings. The blocks that pad the last chunk to full length are not run. Chunks are queued without waiting (JAX dispatches asynchronously), so
the device never waits for the host; with a ``progress`` function the host reads each
chunk's end time while the next one runs. Blocks after a failed step are skipped. The
results are copied to the host once, at the end (one packed vector per chunk), and
assembled with NumPy. A KeyboardInterrupt (Ctrl-C) keeps the chunks completed so far.
A newly compiled or loaded program is run once on a throw-away problem first
(:func:`_warm_up`), so its first execution's one-off costs count as loading, not solving.
"""
from __future__ import annotations

import functools
import time

import jax
import jax.numpy as jnp
import numpy as np

from ...math.xla import jit
from ..compile_cache import compile_stored
from ...model.model import Model
from ...physics import stick_slip
from ..packing import Layout, pack
from ..statics import as_traced
from ..status import Status
from .residual import element_inertia
from .rollout import Trajectory, first_carry, initial_state, stepper
from .scheme import DynamicSettings, State

# Steps per chunk (rounded down to whole save blocks): progress is reported this often.
# Each chunk is one call of the program (~0.5 ms of host work: its ~90 arguments, its
# outputs); 400 steps make the paper's 300-step scenes one call (sj.run / sj.simulate on
# the synthetic helical scene 1.14 -> 1.07-1.10 with 200; benchmarks/README.md, "First
# execution of a program, fewer calls").
CHUNK_STEPS = 400


def with_arrays(model: Model) -> Model:
    """``model`` with every leaf an array: Python numbers given to ``Model.replace``
    become NumPy arrays (float64 for floats), as the compiled programs expect."""
    leaves, treedef = jax.tree_util.tree_flatten(model)
    if all(hasattr(x, "dtype") for x in leaves):
        return model
    return jax.tree_util.tree_unflatten(treedef, [
        x if hasattr(x, "dtype") else np.asarray(x, np.float64 if isinstance(x, float)
                                                   else None) for x in leaves])


def compile_key(model: Model, settings):
    """What a compiled program depends on: the model's structure and array shapes and the
    static settings (the settings that are numbers and the array values are traced)."""
    leaves, treedef = jax.tree_util.tree_flatten(model)
    return (treedef, tuple(x.shape for x in leaves), jax.tree_util.tree_structure(settings))


def step_count(t_end: float, dt: float) -> int:
    """Full steps of size ``dt`` before ``t_end``: ``floor(t_end/dt)``, rounded to the
    nearest integer when ``t_end/dt`` is within 1e-9 of one (round-off)."""
    ratio = t_end / dt
    return max(1, int(round(ratio)) if abs(ratio - round(ratio)) <= 1e-9 * ratio
               else int(ratio))


def block_steps(dt: float, t_end: float, save_every: int) -> tuple[np.ndarray, int]:
    """Step size (s) of every save block of a run from 0 to ``t_end``, and the
    ``save_every`` actually used (at most the step count).

    ``floor(t_end/dt) // save_every`` blocks of ``save_every`` steps of ``dt``; what is
    left before ``t_end`` (less than ``save_every`` steps of ``dt``) is one more block of
    ``save_every`` equal, shorter steps, whose last state is at ``t_end``."""
    steps = step_count(t_end, dt)
    save_every = min(save_every, steps)
    full = steps // save_every
    remaining = t_end - full * save_every * dt
    closing = [remaining / save_every] if remaining > 1e-9 * dt else []
    return np.array([dt] * full + closing, np.float64), save_every


@jit(loop_invariant_motion=False, optimization_level=1)   # xla: less compile, ~same run time
def _chunk(model: Model, settings: DynamicSettings, carry, h, fresh):
    """Save blocks of step sizes ``h`` (B,) from ``carry``, or from the start state of
    ``model`` when ``fresh``; trailing blocks of size 0 (the padding of the last chunk)
    are not run. Returns the carry at the end and, packed into one float64 vector (one
    copy to the host, :func:`_unpack`), per block ``(t, R, p, v, iterations (B,
    save_every), substeps (B, save_every), multipliers)`` (zeros for blocks not run)
    followed by the final state and the carry's failure fields."""
    inert = element_inertia(model)
    carry = jax.lax.cond(fresh, lambda c: first_carry(model, initial_state(model, 0.0, inert)),
                         lambda c: c, carry)

    def block(i, c_out):
        c, out = c_out
        # a step of size 0 does nothing (no Newton iteration): every block after a failure
        h_block = jnp.where(c.failed, 0.0, h[i])
        step = stepper(model, inert, settings.replace(dt=h_block), False)
        c, (its, subs) = jax.lax.scan(step, c, None, length=settings.save_every)
        st = c.state
        saved = (st.t, st.R, st.p, st.v, its.astype(jnp.int32), subs.astype(jnp.int32),
                 c.memory.multipliers)
        return c, tuple(o.at[i].set(x) for o, x in zip(out, saved))

    out = tuple(jnp.zeros(shape, dtype) for shape, dtype in
                _block_outputs(carry, h.shape[0], settings.save_every))
    # padding (h = 0) only follows the run's blocks: run the leading nonzero ones
    carry, out = jax.lax.fori_loop(0, jnp.count_nonzero(h), block, (carry, out))
    return carry, pack(_host_fields(out, carry))


def _block_outputs(carry, blocks: int, save_every: int) -> list:
    """Shapes and types of what :func:`_chunk` saves per block, for ``blocks`` blocks of
    ``save_every`` steps from a carry of the shapes of ``carry``: ``t, R, p, v,
    iterations, substeps, multipliers``."""
    st, mu = carry.state, carry.memory.multipliers
    return [((blocks,), st.t.dtype), ((blocks,) + st.R.shape, st.R.dtype),
            ((blocks,) + st.p.shape, st.p.dtype), ((blocks,) + st.v.shape, st.v.dtype),
            ((blocks, save_every), np.int32), ((blocks, save_every), np.int32),
            ((blocks,) + mu.shape, mu.dtype)]


def _host_fields(out, carry) -> list:
    """What the host reads after a chunk, in the packing order of :func:`_chunk`."""
    state = [x for x in carry.state if x is not None]   # anchors only with stick-slip
    return list(out) + state + [carry.failed, carry.status, carry.cause, carry.failed_at,
                                carry.residual]


def _unpack(packed: np.ndarray, layout) -> tuple:
    """Inverse of :func:`_chunk`'s packing: ``(out (7 arrays), state, (failed, status,
    cause, failed_at, residual))`` as NumPy arrays of the shapes and types in
    ``layout`` (:func:`_layout`)."""
    fields = layout.unpack(packed)
    return tuple(fields[:7]), State(*fields[7:-5]), tuple(fields[-5:])


def _layout(carry, blocks: int, save_every: int) -> Layout:
    """The :class:`~simsoft_jax.solvers.packing.Layout` of the packed fields of a chunk of
    ``blocks`` save blocks from a carry of the shapes of ``carry`` (host placeholder), in
    :func:`_host_fields` order."""
    fields = _block_outputs(carry, blocks, save_every) + [
        (np.shape(x), np.asarray(x).dtype) for x in _host_fields((), carry)]
    return Layout([jax.ShapeDtypeStruct(shape, dtype) for shape, dtype in fields])


def _placeholder_carry(model: Model):
    """Host arrays of the shapes and types of the carry (read only when not ``fresh``)."""
    s = model.structure
    zeros6 = np.zeros((s.n_nodes, 6))
    state = State(model.R0, model.p0, zeros6, zeros6, zeros6, np.float64(0.0),
                  stick_slip.initial(model, model.R0, model.p0, 0.0))
    shapes = jax.eval_shape(functools.partial(first_carry, model), state)
    return jax.tree_util.tree_map(lambda x: np.zeros(x.shape, x.dtype), shapes)


def _assemble(model: Model, packed, layout, blocks: int, t_end: float, dt: float,
              interrupted: bool, cut: bool = True, state: State | None = None) -> Trajectory:
    """One host (NumPy) trajectory from the chunks' packed outputs (:func:`_unpack` with
    ``layout``): the start state (``state``, else the model's at t = 0), then the saved
    state of each of the first ``blocks`` blocks, the last at ``t_end`` after the start;
    cut after a failure when ``cut`` (else the saved states after it repeat the last good
    one, as :func:`~.rollout.simulate` returns them)."""
    if state is None:
        R0, p0, v0, t0 = model.R0, model.p0, model.v0, 0.0
    else:
        R0, p0, v0, t0 = state.R, state.p, state.v, float(state.t)
    R0, p0, v0 = (np.asarray(x) for x in (R0, p0, v0))
    t_end = t0 + t_end
    chunks = [_unpack(x, layout) for x in jax.device_get(packed)]
    final, (failed, status, cause, failed_at, residual) = chunks[-1][1:]
    t, R, p, v, its, subs, mu = (np.concatenate(x)[:blocks]
                                 for x in zip(*(out for out, _, _ in chunks)))
    time_ = np.concatenate([[t0], t])
    R, p, v = (np.concatenate([x0[None], x]) for x0, x in ((R0, R), (p0, p), (v0, v)))
    mu = np.concatenate([np.zeros((1,) + mu.shape[1:]), mu]) if mu.shape[-1] else None
    converged = not bool(failed)
    status, cause = int(status), int(cause)
    failed_at, residual = float(failed_at), float(residual)
    if not converged and cut:  # saved states after the failure repeat the last good one
        keep = int(np.searchsorted(time_, failed_at, side="left")) + 1
        time_, R, p, v = time_[:keep], R[:keep], p[:keep], v[:keep]
        mu = None if mu is None else mu[:keep]
    elif interrupted:
        converged, status, cause = False, int(Status.INTERRUPTED), int(Status.NOT_RUN)
        failed_at, residual = float(time_[-1]), np.nan
    elif abs(time_[-1] - t_end) <= 1e-9 * dt:
        time_[-1] = t_end  # round-off of the sum of the steps
    its, subs = (x.reshape(-1).astype(np.int64) for x in (its, subs))  # as simulate's
    return Trajectory(time_, R, p, v, np.bool_(converged), np.float64(failed_at), its, subs,
                      final, np.int64(status), np.int64(cause), np.float64(residual), mu)


def rollout(model: Model, dt: float, t_end: float, rho_inf: float = 0.9,
            save_every: int = 1, progress=None, compiled=None,
            tolerance: float = 1e-10, max_iterations: int = 25, tangent: str = "closed_form",
            max_halvings: int = 6, cut: bool = True, state: State | None = None,
            globalized: bool = False):
    """Run from the start state to exactly ``t_end``, saving every ``save_every``-th state.

    Steps of ``dt`` (s); what is left before ``t_end`` when ``t_end/dt`` or ``save_every``
    does not divide evenly is one more block of ``save_every`` equal, shorter steps
    (:func:`block_steps`), whose last state, at ``t_end``, is saved; the last saved time
    is ``t_end`` itself. Compiled once per model structure and integer settings
    (``save_every``, ``max_halvings``, ``tangent``): any ``dt``, ``t_end``, ``rho_inf``,
    ``tolerance``, ``max_iterations`` and model array reuse the program.
    ``progress(t, t_end)`` is called after every chunk of ``CHUNK_STEPS`` steps; the run
    stops at the first failed step and the returned trajectory ends there (with ``cut``
    False, it keeps its length: the saved states after the failure repeat the last good
    one and take no Newton iteration). A KeyboardInterrupt after the first chunk (in
    ``progress`` or while waiting for a chunk) stops the run too: the trajectory holds the
    completed chunks, with converged False, status ``INTERRUPTED`` and failed_at the last
    computed time (one before the first chunk is complete is raised: nothing was computed;
    one after a failure keeps the failure). ``compiled`` may be a dict used as a cache of
    compiled programs. Returns ``(Trajectory, compile_seconds)``; the trajectory holds
    NumPy arrays (``final``: the state after the last computed block). ``state``: a
    :class:`State` to start from instead (concrete arrays, without stick-slip anchors);
    the run then lasts ``t_end`` from ``state.t``, with the same program. ``globalized``:
    Newton's globalization (:class:`~.scheme.DynamicSettings`; part of the program).
    """
    if not 0.0 < dt <= t_end:
        raise ValueError(f"solver.dt: must be in (0, t_end = {t_end:g}], got {dt:g}")
    h, save_every = block_steps(dt, t_end, save_every)
    per_chunk = max(1, CHUNK_STEPS // save_every)
    n_chunks = -(-len(h) // per_chunk)
    h = np.concatenate([h, np.zeros(n_chunks * per_chunk - len(h))])
    settings = as_traced(DynamicSettings(
        dt=float(dt), steps=per_chunk * save_every, rho_inf=float(rho_inf),
        save_every=save_every, tolerance=float(tolerance), max_iterations=int(max_iterations),
        max_halvings=int(max_halvings), tangent=tangent, globalized=globalized))
    compiled = {} if compiled is None else compiled
    key = ("rollout", per_chunk) + compile_key(model, settings)
    compile_seconds = 0.0
    if key not in compiled:  # the program, a placeholder carry of its shapes, the layout
        start = time.perf_counter()
        carry = _placeholder_carry(model)
        out_tree = jax.tree_util.tree_structure((carry, 0))
        program = compile_stored(_chunk, (model, settings, carry, h[:per_chunk], True),
                                 out_tree, "rollout")
        layout = _layout(carry, per_chunk, save_every)
        # the warm-up's carry, already on the device, is the placeholder from now on (a
        # first chunk ignores it; no transfer of its host zeros at every run)
        carry = _warm_up(program, model, settings, carry, per_chunk)
        compiled[key] = (program, carry, layout)
        compile_seconds = time.perf_counter() - start
    (program, carry, layout), outputs, reported = compiled[key], [], [0]
    if state is not None:   # the first chunk starts from it (host arrays of the carry's types)
        carry = jax.tree_util.tree_map(lambda x, like: np.asarray(x, like.dtype),
                                       first_carry(model, state), carry)
    interrupted = False
    try:
        for k in range(n_chunks):
            carry, out = program(model, settings, carry, h[k * per_chunk:(k + 1) * per_chunk],
                                 k == 0 and state is None)
            outputs.append((out, carry))
            # report the previous chunk while this one runs; stop after a failure
            if progress is not None and k > 0 and not _report(outputs[k - 1][1], reported,
                                                              progress, t_end):
                break
        else:
            if progress is not None:
                _report(outputs[-1][1], reported, progress, t_end)
        jax.block_until_ready(outputs[-1][1].state.t)  # a Ctrl-C while waiting: below
        done = len(outputs)
    except KeyboardInterrupt:
        done = reported[0] if progress is not None else _completed(outputs)
        if done == 0:
            raise
        interrupted = True
    kept = outputs[:done]
    blocks = min(len(kept) * per_chunk, int(np.count_nonzero(h)))
    traj = _assemble(model, [o for o, _ in kept], layout, blocks, t_end, dt,
                     interrupted and not bool(kept[-1][1].failed), cut, state)
    return traj, compile_seconds


def _warm_up(program, model: Model, settings, carry, per_chunk: int):
    """Run ``program`` once on a throw-away problem so that its first execution's one-off
    costs fall at load time, not in the first solve.

    The first execution of a compiled or loaded program in a process costs 4-15 ms more
    than later ones (JAX's call path, then XLA's runtime setting up the kernels the first
    time they run; benchmarks/README.md, "First execution of a program, fewer calls").
    The warm-up runs the start state and one save block of steps at an infinite
    tolerance (every Newton solve ends after its first iteration, the iteration matrix
    built once), so every kernel of the step runs once at the cost of a step or two; its
    output is discarded but for the carry it returns (device arrays of the carry's
    shapes)."""
    h = np.zeros(per_chunk)
    h[0] = settings.dt
    carry, _ = program(model, settings.replace(tolerance=np.float64(np.inf)), carry, h, True)
    return jax.block_until_ready(carry)


def _report(carry, reported: list, progress, t_end: float) -> bool:
    """Wait for a chunk, count it in ``reported[0]``, call ``progress`` with its end time;
    False when a step of it failed."""
    t = float(carry.state.t)
    reported[0] += 1
    progress(t, t_end)
    return not bool(carry.failed)


def _completed(outputs) -> int:
    """How many leading chunks have finished computing."""
    n = 0
    for _, carry in outputs:
        if not carry.state.t.is_ready():
            break
        n += 1
    return n
