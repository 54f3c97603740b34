"""simsoft_jax.math.xla.jit: the solver entry points compile with the package's XLA options
(when this jaxlib accepts them) and give the same numbers as a plain ``jax.jit``."""
import jax
import numpy as np
import pytest

import simsoft_jax as sj
from simsoft_jax.math import xla
from simsoft_jax.solvers.statics import static_program, as_traced


def test_compiler_options_are_a_dict_accepted_by_this_jaxlib():
    options = xla.compiler_options()
    assert isinstance(options, dict)
    jax.jit(lambda x: 2.0 * x, **({"compiler_options": options} if options else {})
            ).lower(1.0).compile()


def test_solve_static_matches_plain_jit():
    scene = sj.Scene.from_dict({
        "name": "cantilever",
        "solver": {"kind": "static"},
        "rods": [{"name": "rod", "elements": 6, "geometry": {"kind": "straight", "length": 1.0},
                  "stiffness": {"EA": 1e4, "GAy": 1e4, "GAz": 1e4, "GJ": 1.0, "EIy": 2.0,
                                "EIz": 2.0},
                  "inertia": {"rhoA": 0.1, "rhoJ": 1e-3, "rhoIy": 5e-4, "rhoIz": 5e-4}}],
        "constraints": [{"kind": "clamp", "rod": "rod", "node": 0}],
        "loads": [{"kind": "force", "rod": "rod", "node": -1, "vector": [0.0, 1.5, 4.0]}]})
    model = sj.build_model(scene)
    ours = sj.solve_static(model)
    settings = as_traced(sj.StaticSettings())
    plain = jax.jit(static_program.__wrapped__)(model, settings)
    assert bool(ours.converged) and bool(plain.converged)
    assert int(ours.iterations) == int(plain.iterations)
    np.testing.assert_allclose(np.asarray(ours.p), np.asarray(plain.p), rtol=0, atol=1e-13)
    assert static_program.lower(model, settings).compile() is not None
    # inside a user's jit (JAX takes compile options on the outermost jit only)
    nested = jax.jit(lambda m: sj.solve_static(m).p)(model)
    np.testing.assert_allclose(np.asarray(nested), np.asarray(plain.p), rtol=0, atol=1e-13)


def test_a_program_without_loop_invariant_motion_gives_the_same_numbers():
    """``jit(..., loop_invariant_motion=False)`` (the rollout's chunk program) compiles
    with this jaxlib and gives the loop's closed form (sum of k sin(x), k < 10)."""
    def f(x):
        return jax.lax.fori_loop(0, 10, lambda k, c: c + k * jax.numpy.sin(x), 0.0)

    ours = xla.jit(f, loop_invariant_motion=False)
    assert ours.lower(1.3).compile() is not None
    np.testing.assert_allclose(float(ours(1.3)), 45.0 * np.sin(1.3), rtol=1e-15)


def test_products_compile_without_library_fusions_where_xla_makes_them():
    """A 66 x 66 product (the size of a rod-pair border block) that XLA hands to its
    YNNPACK library by default compiles to XLA's own code under the package's options;
    the numbers are the same."""
    a = np.random.default_rng(0).standard_normal((66, 66))
    plain = jax.jit(lambda m: m @ m).lower(a).compile()
    if "__ynn_fusion" not in plain.as_text():
        pytest.skip("this jaxlib makes no YNNPACK fusion of the product")
    ours = xla.jit(lambda m: m @ m).lower(a).compile()
    assert "__ynn_fusion" not in ours.as_text()
    np.testing.assert_allclose(np.asarray(ours(a)), a @ a, rtol=1e-13, atol=1e-12)
