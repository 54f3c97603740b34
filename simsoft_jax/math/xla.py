"""``jit`` with the XLA compile options chosen for this package's solver programs.

XLA's CPU backend compiles fused element-wise code with its newer MLIR "fusion emitters"
by default. For the solver programs here (a few thousand small element-level operations
inside nested while loops) the classic emitters compile 1.5-1.9x faster and run as fast
or faster (benchmarks/README.md: Princeton static 3.1 -> 2.1 s, helical synthetic
dynamic 2.9 -> 1.8 s, run times unchanged or 5-10 % lower). Its Eigen kernels (matrix
products) run single-threaded: the products here are 6x6 to 66x66, too small to gain
from threads, and a sweep over several host devices then keeps one thread per core
(1000 Princeton cases on two devices 1.16 -> 1.04 s, one device 1.81 -> 1.69 s; the
helical rollout unchanged; benchmarks/README.md, "Fewer load levels for the Princeton
cases"). It generates a program's machine code as one LLVM module rather than split
into several for parallel compilation (``xla_cpu_parallel_codegen_split_count=1``):
each part pays the module's set-up again, and the solver programs' compile CPU time
falls 10-17 % (static solver 3.1 -> 2.8 s, rollout 4.4 -> 4.0 s, rollout gradient
5.2 -> 4.4 s; wall time lower too on 2 cores), run times unchanged (benchmarks/README.md,
"`first_answer`"). It compiles no YNNPACK library fusions
(``xla_cpu_experimental_ynn_fusion_type`` empty): by default XLA hands dot products
to that library, whose calls cost more than the small products here (cosseratbench
pile: 4.8 -> 3.9-4.1 ms of CPU per Newton iteration; Princeton static 0.61-0.87, helical
rollouts 0.98 and a vmapped Princeton sweep 0.78 of the CPU time with them;
benchmarks/README.md, "`library_fusions`"). These are CPU debug
options (ignored by other backends); those the installed jaxlib does not know are left
out (with none known, plain ``jax.jit`` is used).

``jit(..., optimization_level=1)`` compiles with LLVM's O1 pipeline instead of its
default: for the gradient programs (the implicit derivative of a static solve, the
rollout's backward pass) 10-15 % less compile CPU time (2.5 -> 2.2 s, 4.4 -> 4.0 s) at
the same run time, for the rollout 4.0 -> 3.3 s at a run time about 2.5 % longer, for
the static solver 2.8 -> 2.4 s (cantilever) and 3.3 -> 2.7 s (Princeton) at a run time
3-6 % longer (the fastest of 60 alternated runs: 1.08 -> 1.14 ms, 2.08 -> 2.19 ms).
A level set in ``XLA_FLAGS`` wins over it.

``jit(..., loop_invariant_motion=False)`` also skips XLA's loop-invariant code motion,
for a program that computes its invariants before its loops itself: run 14 times over the
nested Newton loops of the dynamic rollout it was the costliest HLO pass (0.25 s of
1.2 s) and hoisted nothing that saves run time there (compile 2.55 -> 2.2 s, run time
unchanged). Not for every program: a sweep of static solves (``lax.map``) runs 1.35x
slower without it (benchmarks/README.md, "The compile, session 12").
"""
from __future__ import annotations

import functools
import os

import jax
import numpy as np

CANDIDATE_OPTIONS = {"xla_cpu_use_fusion_emitters": False, "xla_cpu_multi_thread_eigen": False,
                     "xla_cpu_parallel_codegen_split_count": 1,
                     "xla_cpu_experimental_ynn_fusion_type": ""}
_NO_LOOP_INVARIANT_MOTION = {"xla_disable_hlo_passes": "while-loop-invariant-code-motion"}
_OPTIONS: dict | None = None


def accepted(options: dict) -> bool:
    """Whether this jax and jaxlib compile a trivial function with ``options``."""
    try:
        jax.jit(lambda x: x + 1.0, compiler_options=options).lower(1.0).compile()
        return True
    except Exception:  # unknown option or no ``compiler_options`` in this jax
        return False


def compiler_options() -> dict:
    """The compile options used by :func:`jit`: those of the candidates this jaxlib
    accepts (all of them, or else each tried alone); decided once per process by
    compiling a trivial function."""
    global _OPTIONS
    if _OPTIONS is None:
        _OPTIONS = (dict(CANDIDATE_OPTIONS) if accepted(CANDIDATE_OPTIONS) else
                    {k: v for k, v in CANDIDATE_OPTIONS.items() if accepted({k: v})})
    return _OPTIONS


class _Jitted:
    """A ``jax.jit``-ed function created at its first use (so importing the package
    neither starts the XLA backend nor compiles anything); forwards calls and ``lower``.

    JAX accepts compile options on the outermost ``jit`` only, so a call with traced
    arguments (inside a user's ``jit``, ``vmap`` or ``grad``) goes to a plain ``jax.jit``
    of the same function, and the enclosing computation is compiled with its own options.
    """

    def __init__(self, fun, kwargs, loop_invariant_motion: bool = True,
                 optimization_level: int | None = None):
        self._fun, self._kwargs = fun, kwargs
        self._motion, self._level = loop_invariant_motion, optimization_level
        self._top, self._nested = None, None
        functools.update_wrapper(self, fun)

    def compiler_options(self) -> dict:
        """The compile options of this program (:func:`compiler_options`, and those of
        ``loop_invariant_motion=False`` and ``optimization_level``); empty when this
        jaxlib rejects them."""
        options = compiler_options()
        if options and not self._motion:
            options = {**options, **_NO_LOOP_INVARIANT_MOTION}
        if options and self._level is not None and not level_in_environment():
            options = {**options, "xla_backend_optimization_level": self._level}
        return options

    def _top_level(self):
        if self._top is None:
            options = self.compiler_options()
            extra = {"compiler_options": options} if options else {}
            self._top = jax.jit(self._fun, **self._kwargs, **extra)
        return self._top

    def __call__(self, *args, **kwargs):
        if traced(args, kwargs):
            if self._nested is None:
                self._nested = jax.jit(self._fun, **self._kwargs)
            return self._nested(*args, **kwargs)
        return self._top_level()(*args, **kwargs)

    def lower(self, *args, **kwargs):
        return self._top_level().lower(*args, **kwargs)


def traced(*trees) -> bool:
    """Whether any leaf of ``trees`` is a tracer: the call is inside a user's ``jit``,
    ``vmap`` or ``grad`` (its program is compiled with the enclosing computation)."""
    return any(isinstance(x, jax.core.Tracer) for x in jax.tree_util.tree_leaves(trees))


def level_in_environment() -> bool:
    """Whether ``XLA_FLAGS`` sets the backend optimization level (for instance the test
    suite's fast-compile flags): then ``optimization_level`` leaves it as set there."""
    return "--xla_backend_optimization_level" in os.environ.get("XLA_FLAGS", "")


def jit(fun=None, loop_invariant_motion: bool = True, optimization_level: int | None = None,
        **kwargs):
    """``jax.jit(fun, **kwargs)`` with :func:`compiler_options` (and without XLA's
    loop-invariant code motion when ``loop_invariant_motion`` is False; with XLA's
    backend optimization level ``optimization_level``, 0-3, when given: module
    docstring); usable as a decorator with or without arguments (``@jit`` or
    ``@jit(static_argnames=...)``)."""
    if fun is None:
        return lambda f: _Jitted(f, kwargs, loop_invariant_motion, optimization_level)
    return _Jitted(fun, kwargs, loop_invariant_motion, optimization_level)


def take_rows(x, rows):
    """``x[rows]`` for static, non-negative row indices ``rows`` (numpy integers, any
    shape): a slice where they are consecutive, else a gather with unsigned indices.
    ``x[rows]`` itself wraps negative indices, four more operations per gather traced
    into the program (``jnp`` cannot know that static indices are non-negative)."""
    rows = np.asarray(rows)
    if rows.ndim == 1 and rows.size and np.array_equal(rows, rows[0] + np.arange(rows.size)):
        return x[int(rows[0]):int(rows[0]) + rows.size]
    return x[rows.astype(np.uint32)]
