"""Settings and result of a static solve (:mod:`simsoft_jax.solvers.statics`):
:class:`StaticSettings` (float settings traced, :func:`as_traced`), the
:class:`Equilibrium` it returns, and :func:`settings_from_scene`."""
from __future__ import annotations

import dataclasses
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from ...physics.assembly import check_tangent
from ..status import describe


@dataclasses.dataclass(frozen=True)
class StaticSettings:
    """Solver settings. Numbers are traced (changing them never recompiles: the integers
    max_iterations, load_steps, max_attempts and line_search_steps are only bounds and
    divisors, so scenes and calls that differ in them share one program); ``tangent`` is
    static structure.
    ``level_tolerance=0`` (with ``max_load_step`` left None) solves every level to
    ``tolerance`` in at least ``load_steps`` levels (the strict continuation).

    tolerance: converged when the weighted residual norm is below ``tolerance`` times the
      load scale (forces in N, moments divided by the model's ``char_length``).
    max_iterations: Newton iterations per load step before the step is halved.
    load_steps: the first load increment of the continuation is ``1/load_steps`` of the
      full loads; increments are halved on failure down to ``min_step_fraction`` of it,
      and grow by 1.5 after easy steps (fewer than 5 Newton steps) up to
      ``max_load_step``. By default that cap is ``1/load_steps`` itself, so a solve
      takes at least ``load_steps`` increments (the scene format's "minimum
      continuation steps"). A level that converges to an unstable state right after a
      stable one is refused and halved too, down to the minimum, where the
      continuation switches to the stable branch (:mod:`simsoft_jax.solvers.statics.branch`).
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


_STATIC = ("tangent",)
jax.tree_util.register_dataclass(
    StaticSettings,
    data_fields=[f.name for f in dataclasses.fields(StaticSettings)
                 if f.name not in _STATIC],
    meta_fields=list(_STATIC))


def as_traced(settings):
    """``settings`` with every number a float64 array, so that Python numbers, NumPy
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
    (halvings), status (:class:`~simsoft_jax.solvers.status.Status` code: how the solve ended),
    cause (the reason of the last failed Newton solve, ``NOT_RUN`` if none), multipliers
    (M,): the joint multipliers (:mod:`~simsoft_jax.couplings.mechanisms`) and the
    displacement-controlled tendons' tensions (N) (the layout of
    :func:`~simsoft_jax.couplings.coupling.border_sizes`; None without either),
    tendon_tension (M,) the tendons' tensions (N): as given, or solved for
    displacement-controlled tendons (multipliers of their length constraints,
    :mod:`simsoft_jax.couplings.tendon_lengths`); None when the model has no tendons; previous: the frames (R, p) of the load level before the last
    one, the reference of the quasi-static friction there
    (:mod:`simsoft_jax.physics.terms.static_friction`); None without friction. tangent: the
    chains' tangent blocks ``(diag, upper, lower)`` at the equilibrium under the full
    loads, from the last Newton pass (see :func:`equilibrium`, ``keep_tangent``); None
    unless asked for. tangent_positive: whether the symmetric part of that tangent is
    positive definite, as the continuation's stability watch found it (bool; with
    ``keep_tangent`` for watched structures, :func:`~.branch.watched`), else None."""
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
    tangent_positive: jax.Array | None = None

    def message(self) -> str:
        """How the solve ended, in words (concrete, unbatched results)."""
        return describe("static", self.status, self.cause, float(self.load_level),
                        float(self.residual_norm))




def settings_from_scene(solver) -> StaticSettings:
    """StaticSettings from a scene's ``[solver]`` table."""
    return StaticSettings(tolerance=float(solver.tolerance),
                          max_iterations=int(solver.max_iterations),
                          load_steps=int(solver.load_steps),
                          level_tolerance=float(solver.level_tolerance),
                          max_load_step=solver.max_load_step, tangent=solver.tangent)
