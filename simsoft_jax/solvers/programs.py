"""The compiled solver programs of this process, one per model structure, static
settings (``tangent``, and a rollout's ``save_every`` and ``max_halvings``) and purpose, shared by every entry point: :func:`~simsoft_jax.run`,
:func:`~simsoft_jax.solve_static` and :func:`~simsoft_jax.simulate` (and the command
line) on models of the same structure run the same program, compiled once (or loaded
from the cache folder, :func:`~simsoft_jax.solvers.compile_cache.compile_stored`).

Two programs: the static solver with its stability check (:func:`solve_static_checked`,
:func:`compiled_static_solver`) and the dynamic rollout in chunks
(:func:`simsoft_jax.solvers.dynamics.driver.rollout`), both kept in :data:`PROGRAMS`. A call
inside a user's ``jit``, ``vmap`` or ``grad`` is compiled with the enclosing computation
instead (:func:`simsoft_jax.solvers.statics.static_program`,
:func:`simsoft_jax.solvers.dynamics.rollout.rollout_program`).
"""
from __future__ import annotations

import time

import jax
import jax.numpy as jnp
import numpy as np

from ..math.xla import jit
from ..model.built_models import Lru
from .compile_cache import compile_stored
from .dynamics.driver import compile_key
from ..couplings.coupling import border_sizes
from ..model.model import Model
from .packing import Layout, pack
from .stability import negative_eigenvalues
from .statics import Equilibrium, as_traced, equilibrium

# compiled programs by (purpose, compile_key): the static solver and the rollout's chunks
PROGRAMS = Lru()


@jit(optimization_level=1)   # xla: 0.4-0.5 s less compile, runs 3-6 % longer
def solve_static_checked(model: Model, settings, check):
    """The static solve and, when ``check`` (a traced bool) and it converged, the count
    of negative eigenvalues of the tangent at the equilibrium
    (:func:`~simsoft_jax.solvers.stability.negative_eigenvalues`; -1 when not counted), in one
    program. Returns ``(R, p, rest)``: the frames, and the other fields of the
    equilibrium with the count packed into one vector (:func:`~simsoft_jax.solvers.packing.pack`
    of ``(eq without R and p, count)``, :func:`static_layout`): three copies to the host
    instead of a dozen. (Packing the frames as well made the whole solve ~10 % slower:
    the loops then keep them in XLA's temporary buffers.) The equilibrium keeps the
    tangent blocks at the solution (``Equilibrium.tangent``): the gradient of the solve
    factorizes them instead of assembling them again
    (:func:`~simsoft_jax.solvers.statics.stored_static_gradient`)."""
    eq = equilibrium(model, settings, keep_tangent=True)
    tangent, positive = eq.tangent, eq.tangent_positive
    eq = eq._replace(tangent_positive=None)
    count = jax.lax.cond(check & eq.converged,
                         lambda: negative_eigenvalues(model, eq, tangent, positive).astype(int),
                         lambda: jnp.array(-1))
    return eq.R, eq.p, pack((eq._replace(R=None, p=None), count))


def static_layout(model) -> tuple:
    """Shapes and types of the packed ``(Equilibrium without R and p, count)`` of
    :func:`solve_static_checked` for ``model`` (:class:`jax.ShapeDtypeStruct` leaves,
    None for absent fields), to unpack its output without tracing it."""
    def like(shape, dtype=np.float64):
        return jax.ShapeDtypeStruct(shape, dtype)

    structure = model.structure
    n, count = structure.n_nodes, like((), np.int64)
    multipliers = border_sizes(structure)[1]
    frames = (like((n, 3, 3)), like((n, 3)))
    eq = Equilibrium(
        None, None, converged=like((), np.bool_), iterations=count, residual_norm=like(()),
        load_level=like(()), load_steps=count, step_failures=count, status=count,
        cause=count,
        multipliers=like((multipliers,)) if multipliers else None,
        tangent=(like((n, 6, 6)), like((n - 1, 6, 6)), like((n - 1, 6, 6))),
        tendon_tension=(like((len(structure.tendon_names),))
                        if structure.tendon_names else None),
        previous=frames if model.obstacle_friction is not None else None)
    return eq, count


def compiled_static_solver(model: Model, settings):
    """The compiled static solver with its stability check for ``model``'s structure and
    static settings (``tangent``), and the seconds spent compiling it now (0.0 when it was already
    compiled in this process). Call it as ``solver(model, as_traced(settings), check)``
    (``check`` a bool): it returns the :class:`~simsoft_jax.solvers.statics.Equilibrium` and the
    count of negative eigenvalues (-1: not counted), as NumPy arrays (one copy to the
    host); ``solver(..., tangent=True)``: the equilibrium with its tangent blocks at the
    solution (``Equilibrium.tangent``, for its gradient), else without (None)."""
    key = ("static",) + compile_key(model, settings)
    if key in PROGRAMS:
        return PROGRAMS[key], 0.0
    start = time.perf_counter()
    program = compile_stored(solve_static_checked,
                             (model, as_traced(settings), np.bool_(True)),
                             jax.tree_util.tree_structure((0, 0, 0)), "static")
    layout = Layout(static_layout(model))

    def compiled(*args, tangent=False):
        R, p, packed = jax.device_get(program(*args))
        eq, count = layout.unpack(packed)
        return eq._replace(R=R, p=p, tangent=eq.tangent if tangent else None), count
    # a program's first execution in a process costs more than later ones (one-off
    # set-up of its kernels): paid here, by a solve to an infinite tolerance (one Newton
    # pass per load level) with its stability check (dynamics.driver._warm_up)
    compiled(model, as_traced(settings.replace(tolerance=np.inf)), np.bool_(True))
    PROGRAMS[key] = compiled
    return compiled, time.perf_counter() - start
