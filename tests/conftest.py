"""Shared test infrastructure.

* Repository paths, computed from this file, so that every test finds the examples, scenes
  and notebooks whatever folder pytest is started from.
* The checkout's own package first on the import path, in this process and in the
  subprocesses the tests start (examples, notebooks, the command line): an installed copy
  elsewhere (another checkout's editable install) is never the one under test.
* JAX's persistent compilation cache (on by default for ``sj.run`` and the command line,
  :mod:`simsoft_jax.solvers.compile_cache`) in a folder of this test session, never the user's
  home, for every program of the session (JAX's own variables, so also for tests that
  never call ``sj.run``); set in the environment, so the subprocesses share it. Programs
  dropped by ``jax.clear_caches()`` (when the process holds many memory maps, see
  ``_release_compiled_programs``) are read back from it by later modules and by the
  subprocesses. ``SIMSOFT_JAX_CACHE=0`` runs the tests without it.
* XLA compile options that halve the suite's compilation time (``XLA_FLAGS``, set in the
  environment, so also for the examples, notebooks and command-line subprocesses):
  LLVM at optimization level 0 without its expensive passes, and the classic CPU
  emitters for every program (the package uses them for its top-level solver programs
  already, :mod:`simsoft_jax.math.xla`; the gradients a test takes around a solver are
  compiled by a plain ``jax.jit``). The suite compiles far more than it runs: the
  compilation of a 50-step rollout and of a static gradient (tests/test_one_model.py's
  scenes) took about 30 and 45 s of CPU time with XLA's defaults and 17-20 and 18-21 s
  with these flags; positions and gradients agree to round-off (3e-16 m, 1e-13
  relative), so no tolerance depends on them. A flag that ``XLA_FLAGS`` sets already is kept; ``SIMSOFT_TEST_XLA_DEFAULTS=1``
  compiles with XLA's defaults.
* Independent NumPy references used by several test modules (elementary rotations, the
  skew matrix, the exact pure-bending arc) and the pure-bending scene they check.

pytest puts this folder on ``sys.path`` (its default ``prepend`` import mode, no
``__init__.py`` here), so test modules import the helpers with ``from conftest import ...``.
"""
import atexit
import functools
import gc
import os
import shutil
import sys
import tempfile
from pathlib import Path

import numpy as np
import pytest

REPO_ROOT = Path(__file__).resolve().parents[1]
EXAMPLES_DIR = REPO_ROOT / "examples"
SCENES_DIR = EXAMPLES_DIR / "scenes"
NOTEBOOKS_DIR = REPO_ROOT / "notebooks"

sys.path.insert(0, str(REPO_ROOT))
os.environ["PYTHONPATH"] = os.pathsep.join(
    [str(REPO_ROOT)] + [p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep) if p])
if os.environ.get("SIMSOFT_JAX_CACHE", "1") != "0":
    COMPILE_CACHE_DIR = tempfile.mkdtemp(prefix="simsoft_jax_xla_")
    atexit.register(shutil.rmtree, COMPILE_CACHE_DIR, ignore_errors=True)
    for name in ("SIMSOFT_JAX_CACHE_DIR", "JAX_COMPILATION_CACHE_DIR"):
        os.environ[name] = COMPILE_CACHE_DIR
    os.environ["JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS"] = "0"

FAST_COMPILE_FLAGS = {"--xla_backend_optimization_level": "0",
                      "--xla_llvm_disable_expensive_passes": "true",
                      "--xla_cpu_use_fusion_emitters": "false"}
if os.environ.get("SIMSOFT_TEST_XLA_DEFAULTS", "0") != "1":
    _given = os.environ.get("XLA_FLAGS", "").split()
    _names = {flag.split("=")[0] for flag in _given}
    os.environ["XLA_FLAGS"] = " ".join(
        _given + [f"{name}={value}" for name, value in FAST_COMPILE_FLAGS.items()
                  if name not in _names])


def _memory_maps() -> int | None:
    """The number of memory maps of this process (Linux), or None where it cannot be read."""
    try:
        with open("/proc/self/maps", "rb") as maps:
            return sum(1 for _ in maps)
    except OSError:
        return None


# Release compiled programs past this many maps: well below the kernel's default limit
# (65530), which leaves room for the largest module's own programs (measured: ~370 maps per
# static solver; 6 statics modules in one process grow from 900 to 12000 maps).
MAP_BUDGET = 24000


def _release():
    import jax

    jax.clear_caches()
    gc.collect()


@pytest.fixture(autouse=True, scope="module")
def _release_compiled_programs(request):
    """Drop JAX's compiled programs after a test module once this process holds more than
    ``MAP_BUDGET`` memory maps (after every module where the count cannot be read). Each
    program holds a few hundred maps; the whole suite in one process would reach the
    kernel's limit (``vm.max_map_count``, 65530 by default) and abort inside the XLA
    compiler. Until then the programs stay in memory, so later modules that use the same
    structures (and the many small programs of model building) neither compile them again
    nor read them back from the persistent cache. A module that counts compilations sets
    ``COUNTS_COMPILATIONS = True`` and starts with none in memory (neither JAX's nor the
    programs and built models that ``sj.run`` keeps)."""
    if getattr(request.module, "COUNTS_COMPILATIONS", False):
        from simsoft_jax.pipeline import results

        results.forget_programs()
        _release()
    yield
    maps = _memory_maps()
    if maps is None or maps > MAP_BUDGET:
        _release()


# ----------------------------------------------------------------------------- tangent paths
def iteration_matrices(model, R, p, seed=4):
    """The dynamic residual (N,6) and dense iteration matrix of ``model`` (loads at their
    time already) at the frames ``R, p``, random nodal velocities, accelerations and step
    increments (seeded), rho_inf = 0.8, h = 0.01, by both element-block paths:
    ``[(r, S) closed_form, (r, S) autodiff]`` (NumPy)."""
    import jax
    import jax.numpy as jnp

    from simsoft_jax.math import linalg
    from simsoft_jax.solvers.dynamics import element_inertia
    from simsoft_jax.solvers.dynamics.residual import residual_and_iteration_matrix
    from simsoft_jax.solvers.dynamics.scheme import iteration_factors

    rng = np.random.default_rng(seed)
    v, vd, w = (jnp.asarray(0.3 * rng.standard_normal((model.structure.n_nodes, 6)))
                for _ in range(3))
    beta_p, gamma_p = iteration_factors(0.8, 0.01)
    inert = element_inertia(model)
    matrix = jax.jit(residual_and_iteration_matrix, static_argnums=10)
    out = []
    for tangent in ("closed_form", "autodiff"):
        r, blocks = matrix(model, inert, R, p, v, vd, w, beta_p, gamma_p, None, tangent)
        out.append((np.asarray(r), np.asarray(linalg.dense(blocks))))
    return out


# ----------------------------------------------------------------------------- references
def rot_x(a):
    """Rotation by ``a`` (rad) about x."""
    c, s = np.cos(a), np.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rot_y(a):
    """Rotation by ``a`` (rad) about y."""
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rot_z(a):
    """Rotation by ``a`` (rad) about z."""
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def skew(w):
    """The skew matrix ``w^`` (``w^ x = w cross x``), batched over leading axes."""
    w = np.asarray(w, float)
    out = np.zeros(w.shape[:-1] + (3, 3))
    out[..., 0, 1], out[..., 0, 2], out[..., 1, 2] = -w[..., 2], w[..., 1], -w[..., 0]
    out[..., 1, 0], out[..., 2, 0], out[..., 2, 1] = w[..., 2], -w[..., 1], w[..., 0]
    return out


def arc(kappa, s, axis="y"):
    """Clamped rod along +x bent with constant curvature ``kappa`` about local ``axis``
    (exact pure bending, spec S74-S75): positions (M, 3) and frames (M, 3, 3).

    The section frame is R(s) = exp(s kappa e_axis^); the centreline integrates its first
    column: about y the tangent is (cos, 0, -sin) (tip moves to -z for kappa > 0, S74),
    about z it is (cos, sin, 0) (tip moves to +y)."""
    s = np.asarray(s, float)
    c, sn = np.cos(kappa * s), np.sin(kappa * s)
    along, across = sn / kappa, (1.0 - c) / kappa
    zero = np.zeros_like(s)
    if axis == "y":
        p = np.stack([along, zero, -across], axis=1)
        R = np.stack([rot_y(kappa * si) for si in s])
    elif axis == "z":
        p = np.stack([along, across, zero], axis=1)
        R = np.stack([rot_z(kappa * si) for si in s])
    else:
        raise ValueError(axis)
    return p, R


def pure_bending_scene(moment, EI, elements=4):
    """Scene dict: a clamped unit rod along x under a tip moment about local y, bending
    stiffness EI: exact pure bending with kappa = moment / EI (:func:`arc`)."""
    return {"name": "bend", "solver": {"kind": "static", "load_steps": 2},
            "rods": [{"name": "rod", "elements": elements,
                      "geometry": {"kind": "straight", "length": 1.0},
                      "stiffness": {"EA": 1e5, "GAy": 1e5, "GAz": 1e5, "GJ": EI, "EIy": EI,
                                    "EIz": EI},
                      "inertia": {"rhoA": 1.0, "rhoJ": 1.0, "rhoIy": 1.0, "rhoIz": 1.0}}],
            "constraints": [{"kind": "clamp", "rod": "rod", "node": 0}],
            "loads": [{"kind": "moment", "rod": "rod", "node": -1, "frame": "local",
                       "vector": [0.0, moment, 0.0]}]}


# ----------------------------------------------------------------------------- gradients
def primal(f, theta):
    """``f(theta)`` as reverse mode evaluates it (``jax.vjp``'s primal output; its
    backward pass is never run): the same value, by the forward programs of
    ``jax.grad(f)``. Called plainly, a rollout with ``differentiable=True`` compiles a
    rollout program of its own, while ``jax.grad``'s forward pass runs the program of
    ``sj.run`` (compiled once per structure): measured, a third to two thirds of a
    gradient test's compile time."""
    import jax

    return jax.vjp(f, theta)[0]


def assert_gradient_equals_central_differences(f, theta, h=1e-5, rtol=1e-5,
                                               every_component=True):
    """``jax.grad(f)(theta)`` equals the central differences of step ``h`` of the scalar
    ``f`` (theta (P,)) to ``rtol`` (and 1e-7 of the largest component), each component
    of the difference nonzero (so the check can fail; only the largest with
    ``every_component=False``, for a parameter the answer does not depend on).

    The differences take ``f``'s values as :func:`primal` evaluates them: the programs
    ``jax.grad`` runs forward already, none compiled for the differences alone."""
    import jax

    theta = np.asarray(theta, float)
    g = jax.grad(f)(theta)
    fd = np.array([(primal(f, theta + h * e) - primal(f, theta - h * e)) / (2 * h)
                   for e in np.eye(theta.size)])
    assert np.all(np.isfinite(np.asarray(g)))
    assert (np.abs(fd).min() if every_component else np.abs(fd).max()) > 1e-6
    np.testing.assert_allclose(g, fd, rtol=rtol, atol=1e-7 * np.abs(fd).max())


# ----------------------------------------------------------------------------- tendons
def tendon_length_changes(result):
    """The length changes (T, M), m, of the tendons from their stress-free shape along the
    rollout of ``result`` (an ``sj.run`` result):
    :func:`simsoft_jax.couplings.tendon_lengths.length_changes` at every saved state, one
    compiled program per structure (vmapped eagerly, each of its operations compiles on
    its own: about a hundred small programs)."""
    import jax.numpy as jnp

    return np.asarray(_vmapped_length_changes()(
        result.model, jnp.asarray(result.raw.R), jnp.asarray(result.raw.p)))


@functools.cache
def _vmapped_length_changes():
    import jax

    from simsoft_jax.couplings import tendon_lengths
    return jax.jit(jax.vmap(tendon_lengths.length_changes, in_axes=(None, 0, 0)))


# ----------------------------------------------------------------------- rod-rod contact
def crossing_rod(name, x0, length, elements, along_y=False, z=0.0):
    """Scene dict of a straight, axially stiff rod (EI = 1 N m^2) along x from (x0, 0, z),
    or along y from (0, x0, z) (``along_y``), for rod-rod contact tests."""
    return {"name": name, "elements": elements,
            "geometry": {"kind": "straight", "length": length},
            "base": {"position": [0.0, x0, z] if along_y else [x0, 0.0, z],
                     "rotation": [0.0, 0.0, np.pi / 2 if along_y else 0.0]},
            "stiffness": {"EA": 1e7, "GAy": 1e7, "GAz": 1e7, "GJ": 1.0, "EIy": 1.0,
                          "EIz": 1.0},
            "inertia": {"rhoA": 1.0, "rhoJ": 1e-6, "rhoIy": 1e-6, "rhoIz": 1e-6}}


# ----------------------------------------------------------------------------- scenes
def dropped_rod_scene(stiffness, h0=0.05, radius=0.02, dt=1e-2, t_end=0.6, g=9.81):
    """A straight rod (10 elements, 0.5 m, rhoA 0.5 kg/m) lying at height ``h0`` (m)
    above a floor plane that its centreline touches at z = 0 (plane at ``-radius``), let
    fall under gravity ``g`` (m/s^2) on a contact penalty of ``stiffness`` (N/m^2)."""
    return {"solver": {"kind": "dynamic", "t_end": t_end, "dt": dt},
            "gravity": {"vector": [0.0, 0.0, -g]},
            "rods": [{"name": "rod", "elements": 10,
                      "geometry": {"kind": "straight", "length": 0.5},
                      "base": {"position": [0.0, 0.0, h0]},
                      "stiffness": {"EA": 1e5, "GAy": 1e5, "GAz": 1e5, "GJ": 1.0, "EIy": 1.0,
                                    "EIz": 1.0},
                      "inertia": {"rhoA": 0.5, "rhoJ": 1e-4, "rhoIy": 5e-5, "rhoIz": 5e-5}}],
            "obstacles": [{"name": "floor", "kind": "plane", "point": [0.0, 0.0, -radius],
                           "normal": [0.0, 0.0, 1.0]}],
            "contact": {"radius": radius, "stiffness": stiffness}}
