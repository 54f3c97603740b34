"""Batched sweeps (simsoft_jax.studies.sweeps): grid order, vmapped and warm-started static sweeps
against single solves and the linear cantilever, a dynamic sweep against single rollouts,
and input errors."""

import jax.numpy as jnp
import numpy as np
import pytest

import simsoft_jax as sj
from simsoft_jax.studies import sweeps
from conftest import SCENES_DIR
from sweeps_subprocess import L, strip_scene

ELEMENTS = 6
SCENE = strip_scene(ELEMENTS)


def vary_force_and_stiffness(model, q):
    """Tip force along y (N) and a factor on EI_z."""
    nodal = model.nodal_dead.at[-1, 1].set(q["force"])
    return model.replace(nodal_dead=nodal, stiffness=model.stiffness.at[:, 5].multiply(q["stiff"]))


def test_grid_varies_the_last_axis_fastest():
    g = sweeps.grid(a=[1.0, 2.0], b=[10.0, 20.0, 30.0])
    np.testing.assert_array_equal(g["a"], [1, 1, 1, 2, 2, 2])
    np.testing.assert_array_equal(g["b"], [10, 20, 30, 10, 20, 30])
    with pytest.raises(ValueError, match="axis 'b' must be a non-empty 1-D"):
        sweeps.grid(a=[1.0], b=[])


@pytest.fixture(scope="module")
def model():
    return sj.build_model(sj.Scene.from_dict(SCENE))


def test_static_sweeps_match_single_solves_and_the_linear_limit(model):
    points = sweeps.grid(stiff=[0.5, 1.0, 2.0], force=[1e-3, 2.0, 8.0])
    vmapped = sweeps.static_sweep(model, vary_force_and_stiffness, points)
    warm = sweeps.static_sweep(model, vary_force_and_stiffness, points, warm_start=True)
    assert vmapped.converged.all() and warm.converged.all()
    assert int(warm.iterations.sum()) < int(vmapped.iterations.sum())   # continuation pays
    for k in (0, 4, 8):
        q = {name: value[k] for name, value in points.items()}
        single = sj.solve_static(vary_force_and_stiffness(model, q))
        np.testing.assert_allclose(vmapped.p[k], single.p, atol=1e-12)
        np.testing.assert_allclose(warm.p[k], single.p, atol=1e-9)
    # small load: Timoshenko cantilever F L^3/(3 EI) + F L/(GA), to the O(h^2) mesh error
    K = np.asarray(model.stiffness[0])
    small = points["force"] == 1e-3
    linear = 1e-3 * (L**3 / (3 * K[5] * points["stiff"][small]) + L / K[1])
    np.testing.assert_allclose(np.asarray(vmapped.p[small, -1, 1]), linear, rtol=1e-2)


def test_static_sweep_rejects_bad_points(model):
    with pytest.raises(ValueError, match="'force' has no leading batch axis"):
        sweeps.static_sweep(model, vary_force_and_stiffness, {"force": 1.0, "stiff": [1.0]})
    with pytest.raises(ValueError, match="same leading length"):
        sweeps.static_sweep(model, vary_force_and_stiffness, {"force": [1.0, 2.0], "stiff": [1.0]})


def vary_load_scale(model, q):
    """Scale the amplitude of every nodal dead-load channel (the time laws stay)."""
    channels = model.channels.replace(nodal_dead=model.channels.nodal_dead * q["scale"])
    return model.replace(channels=channels)


def test_dynamic_sweep_matches_single_rollouts():
    scene = sj.load_scene(SCENES_DIR / "helical_synthetic.json").to_dict()
    scene["rods"][0]["elements"] = 3
    scene = sj.Scene.from_dict(scene)
    model = sj.build_model(scene)
    settings = sj.DynamicSettings(dt=0.01, steps=20, save_every=10)
    points = {"scale": np.array([0.5, 1.0])}
    batch = sweeps.dynamic_sweep(model, vary_load_scale, points, settings)
    assert batch.p.shape == (2, 3, 4, 3) and batch.converged.all()
    # early in the ramp the response is linear: twice the load, twice the tip displacement
    moved = np.asarray(batch.p[:, -1, -1, 1:] - batch.p[:, 0, -1, 1:])
    np.testing.assert_allclose(moved[1], 2.0 * moved[0], rtol=0.05)
    for k, scale in enumerate(points["scale"]):
        single = sj.simulate(vary_load_scale(model, {"scale": jnp.asarray(scale)}), settings)
        np.testing.assert_allclose(batch.p[k], single.p, atol=1e-10)
