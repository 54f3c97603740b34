"""One backend compilation per model structure for every public entry point (issue 16,
item 4): ``sj.run`` (static and dynamic), the command line, ``sj.simulate``,
``sj.solve_static`` and ``sweeps.static_sweep`` compile once, and runs of the same
structure with other numbers (loads, stiffness, gravity, time-law parameters, dt, t_end,
tolerances) compile nothing, not even the small programs of model building. One program
per structure and purpose: ``sj.solve_static`` and ``sj.simulate`` on the Model of a scene
that ``sj.run`` ran compile nothing more.

Compilations are counted with JAX's monitoring events (one
``/jax/core/compile/backend_compile_duration`` event per XLA compilation, or per program
read from the persistent cache, which the tests' cache folder may serve, and one
``compile_cache.LOADED_EVENT`` per solver program loaded from that folder). The numbers of
each run are checked against independent references: exact pure bending (statics) and
the similarity law of dynamics (stiffness, loads and gravity times 4, time halved: the
same motion twice as fast).
"""
import collections
import contextlib
import json

import jax
import numpy as np
import pytest

import simsoft_jax as sj
from conftest import arc, pure_bending_scene
from simsoft_jax import cli
from simsoft_jax.solvers import compile_cache
from simsoft_jax.studies import sweeps
from simsoft_jax.solvers.statics import settings_from_scene

COMPILE_EVENT = "/jax/core/compile/backend_compile_duration"
COUNTS_COMPILATIONS = True   # conftest: start this module with no program in memory


@contextlib.contextmanager
def compilations():
    """Counter of the backend compilations inside the block, by program name."""
    names = collections.Counter()

    def listen(event, duration, **kwargs):
        if event in (COMPILE_EVENT, compile_cache.LOADED_EVENT):
            names[kwargs.get("fun_name", "?")] += 1

    jax.monitoring.register_event_duration_secs_listener(listen)
    try:
        yield names
    finally:
        jax.monitoring.unregister_event_duration_listener(listen)


def pendulum(scale=1.0, t_end=0.05, dt=0.01):
    """The issue's case: 25 elements, pinned at one end, gravity, dynamic; a tip force
    ramped by a smoothstep law. ``scale`` multiplies stiffness, gravity and the force
    and divides times by sqrt(scale) (similarity: same shapes at scaled times)."""
    k = np.sqrt(scale)
    return {
        "name": "pendulum",
        "solver": {"kind": "dynamic", "dt": dt / k, "t_end": t_end / k, "rho_inf": 0.9},
        "gravity": {"vector": [0.0, 0.0, -9.81 * scale]},
        "rods": [{"name": "rod", "elements": 25, "geometry": {"kind": "straight", "length": 1.0},
                  "stiffness": {n: v * scale for n, v in dict(
                      EA=1e4, GAy=1e4, GAz=1e4, GJ=5.0, EIy=5.0, EIz=5.0).items()},
                  "inertia": {"rhoA": 0.5, "rhoJ": 1e-3, "rhoIy": 5e-4, "rhoIz": 5e-4}}],
        "constraints": [{"kind": "pin", "rod": "rod", "node": 0}],
        "loads": [{"kind": "force", "rod": "rod", "node": -1, "frame": "world",
                   "vector": [0.0, 1.0 * scale, 0.0],
                   "profile": {"kind": "smoothstep", "t0": 0.0, "t1": 0.04 / k}}],
    }


def test_run_dynamic_compiles_once_per_structure():
    """The pendulum of the issue: the first run compiles one solver program and nothing
    else; runs with other stiffness, gravity, load, time law, dt and t_end compile
    nothing, and follow the similarity law to round-off."""
    with compilations() as first:
        base = sj.run(pendulum())
    assert first["jit(_chunk)"] == 1
    # nothing else: model building is NumPy (the compile-option probe, once per process)
    assert set(first) <= {"jit(_chunk)", "jit(<lambda>)"} and first["jit(<lambda>)"] <= 1, first
    with compilations() as again:
        fast = sj.run(pendulum(scale=4.0))
        longer = sj.run(pendulum(t_end=0.033))        # t_end/dt = 3.3: a closing block
    assert sum(again.values()) == 0, again
    assert base.converged and fast.converged and longer.converged
    np.testing.assert_allclose(fast.time, base.time / 2.0, rtol=0, atol=1e-15)
    np.testing.assert_allclose(fast.positions("rod"), base.positions("rod"), rtol=0,
                               atol=1e-9)
    np.testing.assert_allclose(fast.velocities("rod"), 2.0 * base.velocities("rod"),
                               rtol=0, atol=1e-8)
    assert longer.time[-1] == 0.033 and len(longer.time) == 5
    np.testing.assert_allclose(longer.positions("rod")[:4], base.positions("rod")[:4],
                               rtol=0, atol=1e-14)


def test_cli_reuses_the_program_of_run(tmp_path, capsys):
    """The command line runs the same program: after ``sj.run`` of this structure, runs
    with other numbers (with and without progress) compile nothing."""
    sj.run(pendulum())   # compiled here or in the test above (same process)
    paths = []
    with compilations() as seen:
        for k, (scale, flags) in enumerate([(2.0, []), (3.0, ["--no-progress"])]):
            scene, out = tmp_path / f"p{k}.json", tmp_path / f"out{k}.json"
            scene.write_text(json.dumps(pendulum(scale=scale)))
            assert cli.main(["run", str(scene), "-o", str(out), *flags]) == 0
            paths.append(out)
    assert sum(seen.values()) == 0, seen
    printed = capsys.readouterr()
    assert "compile 0.00 s" in printed.out and printed.err.count("t = ") == 1
    for scale, out in zip((2.0, 3.0), paths):
        d = json.loads(out.read_text())
        np.testing.assert_allclose(np.asarray(d["time"]) * np.sqrt(scale),
                                   [0.0, 0.01, 0.02, 0.03, 0.04, 0.05], rtol=0, atol=1e-14)


def test_simulate_runs_the_program_of_run():
    """``sj.simulate`` on the Model of a scene that ``sj.run`` ran runs the same program
    (other step count, ``max_iterations`` and tolerance included): it compiles nothing and
    saves the states of the run; other stiffness, gravity, dt, rho_inf and tolerance reuse
    the program, and the similarity law holds on it too."""
    run = sj.run(pendulum())   # compiled here or in a test above (same process)
    model = sj.build_model(sj.Scene.from_dict(pendulum()))
    settings = sj.DynamicSettings(dt=0.01, steps=4, tolerance=1e-12, max_iterations=30)
    with compilations() as first:
        a = sj.simulate(model, settings)
    assert sum(first.values()) == 0, first
    assert a.converged and a.p.shape == (5,) + run.positions("rod").shape[1:]
    np.testing.assert_allclose(a.time, run.time[:5], rtol=0, atol=1e-15)
    np.testing.assert_allclose(a.p, run.positions("rod")[:5], rtol=0, atol=1e-10)
    fast_model = model.replace(stiffness=4.0 * model.stiffness, gravity=4.0 * model.gravity,
                               channels=sj.build_model(sj.Scene.from_dict(
                                   pendulum(scale=4.0))).channels)
    with compilations() as again:
        b = sj.simulate(fast_model, settings.replace(dt=0.005))
        sj.simulate(model, settings.replace(rho_inf=0.5, tolerance=1e-10))
    assert sum(again.values()) == 0, again
    np.testing.assert_allclose(np.asarray(b.p), np.asarray(a.p), rtol=0, atol=1e-9)


S = np.linspace(0.0, 1.0, 5)


def test_run_static_and_solve_static_compile_once():
    """``sj.run`` of a static scene compiles its solver (with the stability check: one
    program) once; ``sj.solve_static`` on the Model of that scene runs the same program
    (nothing compiled); other loads, stiffness and tolerances compile nothing."""
    with compilations() as first:
        r1 = sj.run(pure_bending_scene(1.0, 2.0))
    # compiled, or loaded from the tests' program folder when an earlier module ran this
    # structure (stored under the program's kind)
    assert first["jit(solve_static_checked)"] + first["jit(static)"] == 1, first
    assert "jit(negative_eigenvalues)" not in first
    with compilations() as again:
        r2 = sj.run(pure_bending_scene(0.5, 0.5))
    assert sum(again.values()) == 0, again
    for r, kappa in ((r1, 0.5), (r2, 1.0)):
        assert r.converged and r.stability["stable"]
        np.testing.assert_allclose(r.positions("rod"), arc(kappa, S)[0], rtol=0, atol=1e-9)
    model = sj.build_model(sj.Scene.from_dict(pure_bending_scene(1.0, 2.0)))
    with compilations() as shared:
        eq = sj.solve_static(model)
    assert sum(shared.values()) == 0, shared
    stiffer = model.replace(stiffness=2.0 * model.stiffness)
    with compilations() as again:
        eq2 = sj.solve_static(stiffer, sj.StaticSettings(tolerance=1e-11))
    assert sum(again.values()) == 0, again
    np.testing.assert_allclose(eq.p, arc(0.5, S)[0], rtol=0, atol=1e-9)
    np.testing.assert_allclose(eq2.p, arc(0.25, S)[0], rtol=0, atol=1e-9)


def test_run_builds_an_equal_scene_once_and_notices_a_changed_one():
    """``sj.run`` keeps the built Model of a scene: the same Scene, or an equal dict, reuses
    it (read-only arrays), with the result of a fresh build's solve; a changed moment or
    stiffness builds a new model, whose result follows exact pure bending."""
    scene = sj.Scene.from_dict(pure_bending_scene(1.0, 2.0))
    a, b, c = sj.run(scene), sj.run(scene), sj.run(pure_bending_scene(1.0, 2.0))
    assert b.model is a.model and c.model is a.model and not a.model.p0.flags.writeable
    fresh = sj.solve_static(sj.build_model(scene), settings_from_scene(scene.solver))
    np.testing.assert_allclose(b.positions("rod"), np.asarray(fresh.p), rtol=0, atol=1e-12)
    for d, kappa in ((pure_bending_scene(2.0, 2.0), 1.0), (pure_bending_scene(1.0, 4.0), 0.25)):
        r = sj.run(d)
        assert r.model is not a.model
        np.testing.assert_allclose(r.positions("rod"), arc(kappa, S)[0], rtol=0, atol=1e-9)


def scale_moment(model, q):
    return model.replace(nodal_follower=q["m"] * model.nodal_follower)


@pytest.mark.slow
def test_static_sweep_compiles_once():
    """``sweeps.static_sweep`` (its public API): a second sweep of the same size with
    other points compiles nothing."""
    model = sj.build_model(sj.Scene.from_dict(pure_bending_scene(1.0, 2.0)))
    with compilations() as first:
        eq = sweeps.static_sweep(model, scale_moment, {"m": np.array([0.5, 1.0])})
    assert sum(first.values()) >= 1
    with compilations() as again:
        eq2 = sweeps.static_sweep(model, scale_moment, {"m": np.array([1.5, 2.0])})
    assert sum(again.values()) == 0, again
    for m, p in zip([0.5, 1.0, 1.5, 2.0], [*eq.p, *eq2.p]):
        np.testing.assert_allclose(p, arc(0.5 * m, S)[0], rtol=0, atol=1e-9)
