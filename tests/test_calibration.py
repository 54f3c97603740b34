"""Calibration (simsoft_jax.studies.calibration, measurements, ``simsoft-jax calibrate``).

* the sensitivity matrix J = dr/dx (forward mode through the IFT) against central finite
  differences of the residuals;
* identifiability (issue 5, 3a): positions simulated with known stiffness factors plus
  noise of 1 % of the rms deflection; the fit recovers each factor within 2 sigma;
* ANSYS solid predictions (3-D elasticity) as measurements (3b): fitted EI_y, EI_z, GJ on
  theta = 0, 30, 60, 90 lower the error on the held-out 15, 45, 75 cases;
* dynamic identification (4): viscosity and EI_y from a noisy tip trajectory;
* measurement files and the command line, with their errors.
"""
import json

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import simsoft_jax as sj
from simsoft_jax.studies import calibration as cal
from simsoft_jax.apps import princeton as pr
from simsoft_jax.cli import main
from simsoft_jax.studies.measurements import static_targets

ELEMENTS = 8
NAMES = ("EIy", "EIz", "GJ")

# ANSYS solid-element tip deflections (m) of the Princeton geometry without gravity,
# (flap, edge) for theta = 0, 15, ..., 90 deg: simsoft_jax/data/princeton/model_predictions_tip.csv
# rows ANSYS_solid_F2 / F3 (Obrezkov, Mikkola, Matikainen et al., Nonlinear Dyn. 109, 2022).
ANSYS_SOLID = {
    8.896: [(0.0, 0.01069752828), (0.04101165651, 0.01057180106), (0.07696749069, 0.009938278402),
            (0.105976311, 0.008686786771), (0.127251299, 0.006500006282),
            (0.13959474, 0.003481999513), (0.143848652, 0.0)],
    13.345: [(0.0, 0.01603700622), (0.06270699533, 0.01637026068), (0.113752002, 0.01640440775),
             (0.153554457, 0.0148505521), (0.179978534, 0.01127173264),
             (0.192972233, 0.006062461977), (0.197669499, 0.0)],
}


@pytest.fixture(scope="module")
def beam():
    return sj.build_model(pr.scene(ELEMENTS, gravity=False))


def test_parameter_names_are_checked():
    assert cal.check_parameters("EIy, EIz,GJ") == NAMES
    for bad, match in (("", "at least one"), ("EI", "unknown parameter 'EI'"),
                       ("E,EIy", "'EIy' and 'E' both scale"), ("viscosity", "unknown")):
        with pytest.raises(ValueError, match=match):
            cal.check_parameters(bad)
    assert cal.check_parameters(["viscosity", "E"], dynamic=True) == ("viscosity", "E")


def released_cantilever():
    """A soft viscous cantilever released under gravity (dynamic)."""
    return sj.Scene.from_dict({
        "name": "released_cantilever", "solver": {"kind": "dynamic", "t_end": 0.4, "dt": 0.01},
        "gravity": {"vector": [0.0, 0.0, -9.81]},
        "rods": [{"name": "rod", "material": {"E": 2e6, "nu": 0.45, "density": 1100.0,
                                              "viscosity": 2e3},
                  "section": {"shape": "circle", "diameter": 0.01}, "elements": 4,
                  "geometry": {"kind": "straight", "length": 0.2}}],
        "constraints": [{"kind": "clamp", "rod": "rod", "node": 0}]})


def test_scales_multiply_their_columns(beam):
    """Each parameter scales its columns; viscosity of a model built without it (the
    Princeton beam: Model.viscosity None) is refused, naming it."""
    factor = np.array([2.0, 1.0, 1.0, 3.0, 2.0, 2.0])
    scaled = cal.apply_scales(beam, ("E", "GJ"), jnp.log(jnp.array([2.0, 3.0])))
    np.testing.assert_allclose(scaled.stiffness, np.asarray(beam.stiffness) * factor, rtol=1e-15)
    viscous = sj.build_model(released_cantilever())
    scaled = cal.apply_scales(viscous, ("E", "GJ", "viscosity"),
                              jnp.log(jnp.array([2.0, 3.0, 5.0])))
    np.testing.assert_allclose(scaled.stiffness, np.asarray(viscous.stiffness) * factor,
                               rtol=1e-15)
    np.testing.assert_allclose(scaled.viscosity, np.asarray(viscous.viscosity) * 5.0, rtol=1e-15)
    assert np.all(np.asarray(viscous.viscosity)[:, 3:] > 0.0)
    with pytest.raises(ValueError, match="params: 'viscosity': the model was built without"):
        cal.apply_scales(beam, ("viscosity",), jnp.zeros(1))


def _targets(beam, cases, nodes, log_scale=None, noise=0.0, seed=0):
    """Targets with positions simulated at ``log_scale`` (+ Gaussian noise of std
    ``noise`` times the rms displacement)."""
    nodes = np.asarray(nodes)
    models = [pr.case_model(beam, th, k * pr.F0) for th, k in cases]
    if log_scale is None:
        positions = [np.zeros((len(nodes), 3)) for _ in models]
    else:
        positions = [np.asarray(sj.solve_static(cal.apply_scales(m, NAMES, jnp.asarray(log_scale))).p[nodes])
                     for m in models]
    rms = np.sqrt(np.mean(np.concatenate([p - np.asarray(beam.p0[nodes]) for p in positions]) ** 2))
    rng = np.random.default_rng(seed)
    targets = [cal.StaticTarget(m, np.asarray(nodes), p + noise * rms * rng.standard_normal(p.shape),
                                np.ones((len(nodes), 3), bool)) for m, p in zip(models, positions)]
    return targets, noise * rms


@pytest.mark.slow
def test_sensitivity_matches_finite_differences(beam):
    targets, _ = _targets(beam, [(30.0, 3.0), (75.0, 1.5)], [4, 8])
    residual = jax.jit(cal.static_residual_fn(targets, NAMES))
    x = jnp.log(jnp.array([1.1, 0.9, 1.2]))
    J = np.asarray(jax.jit(jax.jacfwd(lambda y: residual(y)[0]))(x))
    h = 1e-5
    for j in range(3):
        e = jnp.zeros(3).at[j].set(h)
        fd = (np.asarray(residual(x + e)[0]) - np.asarray(residual(x - e)[0])) / (2 * h)
        np.testing.assert_allclose(J[:, j], fd, rtol=1e-6, atol=1e-9 * np.abs(fd).max())


@pytest.mark.slow
def test_identifiability_recovers_known_factors_within_two_sigma(beam):
    """Issue 5, 3a: seven load cases, four stations each, noise 1 % of the rms deflection."""
    true = np.array([1.2, 0.85, 1.1])
    cases = [(0.0, 4.0), (15.0, 4.0), (30.0, 4.0), (45.0, 3.0), (60.0, 2.0), (75.0, 1.5), (90.0, 1.5)]
    targets, sigma = _targets(beam, cases, [2, 4, 6, 8], np.log(true), noise=0.01)
    fit = cal.fit_static(targets, NAMES)
    assert fit.converged and fit.loss_history[-1] < fit.loss_history[0]
    assert np.all(np.abs(fit.scale - true) < 2.0 * fit.std), (fit.scale, fit.std)
    assert np.all(fit.std < 0.05 * true)              # the data do pin the parameters down
    assert fit.rms == pytest.approx(sigma, rel=0.2)   # residuals at the noise level
    assert fit.values["EIy"] == pytest.approx(float(beam.stiffness[0, 4]) * fit.scale[0])


def _ansys_targets(beam, angles):
    """ANSYS solid tip deflections of ``angles`` as Princeton measurements at r = L."""
    rows = [(float(th), load, flap, edge) for load, table in ANSYS_SOLID.items()
            for th, (flap, edge) in zip(range(0, 91, 15), table) if th in angles]
    theta, load, flap, edge = np.array(rows).T
    measured = pr.Measurements(theta, load, np.full(len(rows), pr.LENGTH),
                               -np.stack([flap, edge], axis=1))
    return pr.calibration_targets(measured, beam)


@pytest.mark.slow
def test_ansys_solid_calibration_lowers_the_held_out_error(beam):
    """Issue 5, 3b: from the seed's section constants, fit EI_y, EI_z, GJ on theta = 0,
    30, 60, 90 (both loads); the eq. (112)-style tip error on 15, 45, 75 falls."""
    train, held = _ansys_targets(beam, (0, 30, 60, 90)), _ansys_targets(beam, (15, 45, 75))
    fit = cal.fit_static(train, NAMES)

    def tip_errors(scale):   # (|dy| + |dz|) / L in % per held-out case
        r = cal.evaluate(held, NAMES, scale).reshape(-1, 2)
        return 100.0 * np.abs(r).sum(axis=1) / pr.LENGTH
    before, after = tip_errors(None), tip_errors(fit.scale)
    assert after.mean() < 0.5 * before.mean(), (before, after)
    assert after.max() < before.max()
    assert np.all(np.abs(np.log(fit.scale)) < 0.5)      # physically plausible corrections


@pytest.mark.slow
def test_dynamic_identification_recovers_viscosity_and_stiffness():
    """Issue 5, part 4: a soft cantilever released under gravity; its tip trajectory
    (noise 0.1 mm) identifies the Kelvin-Voigt viscosity and EI_y through rollout
    gradients (IFT at every step)."""
    model = sj.build_model(released_cantilever())
    settings = sj.DynamicSettings(dt=0.01, steps=40, rho_inf=0.9, save_every=2)
    true = np.array([1.5, 1.2])
    truth = sj.simulate(cal.apply_scales(model, ("viscosity", "EIy"), jnp.log(jnp.asarray(true))),
                        settings, differentiable=True)
    assert bool(truth.converged)
    measured = np.asarray(truth.p[:, -1]) + 1e-4 * np.random.default_rng(1).standard_normal((21, 3))
    fit = cal.fit_trajectory(model, settings, -1, measured, ("viscosity", "EIy"))
    assert np.all(np.abs(fit.scale - true) < 2.5 * fit.std), (fit.scale, fit.std)
    assert np.all(np.abs(fit.scale - true) < 0.03 * true)
    with pytest.raises(ValueError, match=r"measured: expected shape \(21, 3\)"):
        cal.fit_trajectory(model, settings, -1, measured[:-1])


SCENE = {"solver": {"kind": "static"},
         "rods": [{"name": "arm", "material": "aluminum_7075",
                   "section": {"shape": "rectangle", "width": 4e-3, "height": 8e-3},
                   "elements": 4, "geometry": {"kind": "straight", "length": 0.4}}],
         "constraints": [{"kind": "clamp", "rod": "arm", "node": 0}]}


def _scene(name, force):
    data = json.loads(json.dumps(SCENE))
    data["name"] = name
    data["loads"] = [{"kind": "force", "rod": "arm", "node": -1, "vector": force, "frame": "world"}]
    return sj.Scene.from_dict(data)


@pytest.mark.slow
def test_calibrate_command_fits_files(tmp_path, capsys):
    """End to end: two scene files, measurements from known factors (no noise), the
    fitted factors come back to 1e-6."""
    scenes = [_scene("flap", [0.0, -20.0, 0.0]), _scene("edge", [0.0, 0.0, -60.0])]
    true = np.array([0.8, 1.25])
    lines = ["scene,rod,node,x,y,z"]
    for scene in scenes:
        sj.save_scene(scene, tmp_path / f"{scene.name}.json")
        model = sj.build_model(scene)
        p = sj.solve_static(cal.apply_scales(model, ("EIy", "EIz"), jnp.log(jnp.asarray(true)))).p
        for node in (2, -1):
            x, y, z = np.asarray(p[node]).tolist()
            lines.append(f"{scene.name},arm,{node},{x!r},{y!r},{z!r}")
    (tmp_path / "m.csv").write_text("\n".join(lines) + "\n")
    out = tmp_path / "fitted.json"
    args = ["calibrate", "--scenes", str(tmp_path / "flap.json"), str(tmp_path / "edge.json"),
            "--measurements", str(tmp_path / "m.csv"), "--params", "EIy,EIz", "-o", str(out)]
    assert main(args) == 0
    fitted = json.loads(out.read_text())
    np.testing.assert_allclose(fitted["scale"], true, rtol=1e-6)
    assert fitted["params"] == ["EIy", "EIz"] and len(fitted["residuals_m"]) == 12
    assert "EIy = " in capsys.readouterr().out
    (tmp_path / "bad.csv").write_text("scene,rod,node,x,y,z\nflop,arm,1,0,0,0\n")
    assert main(args[:5] + [str(tmp_path / "bad.csv")] + args[6:]) == 2
    assert "unknown scene 'flop'" in capsys.readouterr().err


@pytest.mark.parametrize("rows, match", [
    ("scene,rod,node,x,y\n", r"lacks column\(s\) \['z'\]"),
    ("scene,rod,node,x,y,z\nflap,arm,1,0,0,0\nother,arm,1,0,0,0\n", "line 3, column scene: unknown scene 'other'"),
    ("scene,rod,node,x,y,z\nflap,hand,1,0,0,0\n", "column rod: scene 'flap' has no rod 'hand'"),
    ("scene,rod,node,x,y,z\nflap,arm,5,0,0,0\n", "column node: rod 'arm' has nodes 0..4"),
    ("scene,rod,node,x,y,z\nflap,arm,-6,0,0,0\n", "column node"),
    ("scene,rod,node,x,y,z\nflap,arm,one,0,0,0\n", "column node: not an integer"),
    ("scene,rod,node,x,y,z\nflap,arm,1,0,zero,0\n", "column y: not a number"),
    ("scene,rod,node,x,y,z\nflap,arm,1,,,\n", "no component measured"),
    ("scene,rod,node,x,y,z\nflap,arm,1,nan,0,0\n", "column x: not finite"),
    ("scene,rod,node,x,y,z\n", "no data rows"),
])
def test_bad_measurement_files_name_line_and_column(tmp_path, rows, match):
    (tmp_path / "m.csv").write_text(rows)
    with pytest.raises(ValueError, match=match):
        static_targets(tmp_path / "m.csv", [_scene("flap", [0.0, 0.0, -1.0])])


def test_measurements_map_rod_nodes_and_masks(tmp_path):
    (tmp_path / "m.csv").write_text("scene,rod,node,x,y,z\nflap,arm,-1,,0.1,-0.2\nflap,arm,2,0.2,0,0\n")
    (target,) = static_targets(tmp_path / "m.csv", [_scene("flap", [0.0, 0.0, -1.0])])
    np.testing.assert_array_equal(target.nodes, [4, 2])
    np.testing.assert_array_equal(target.mask, [[False, True, True], [True, True, True]])
    with pytest.raises(ValueError, match="scenes: two scenes are named 'flap'"):
        static_targets(tmp_path / "m.csv", [_scene("flap", [0, 0, -1.0])] * 2)


def test_fit_static_honours_each_scenes_solver_settings(tmp_path):
    """fit_static and evaluate solve each target with its scene's ``[solver]`` table
    (static_targets carries it): a loose tolerance gives the tip of a solve with that
    tolerance, not of the defaults; a scene allowed one Newton iteration in one load step
    cannot reach its equilibrium and the fit says so, while settings given explicitly
    override every scene's and recover the generating scale."""
    from simsoft_jax.solvers.statics import StaticSettings, settings_from_scene
    from test_calibration_groups import strip
    loose = strip("loose", 0.6, 0.0, solver={"kind": "static", "tolerance": 1e-2,
                                             "load_steps": 1, "max_load_step": 1.0})
    (tmp_path / "zero.csv").write_text("scene,rod,node,x,y,z\nloose,wing,-1,0,0,0\n")
    targets = static_targets(tmp_path / "zero.csv", [loose])
    assert targets[0].settings == settings_from_scene(loose.solver)
    model = sj.build_model(loose)
    own = np.asarray(sj.solve_static(model, settings_from_scene(loose.solver)).p[-1])
    default = np.asarray(sj.solve_static(model, StaticSettings()).p[-1])
    assert np.abs(own - default).max() > 1e-7          # the settings make a difference
    np.testing.assert_allclose(cal.evaluate(targets, "EIy"), own, rtol=0, atol=1e-13)

    hard = strip("hard", 0.8, 0.0, solver={"kind": "static", "tolerance": 1e-12,
                                           "max_iterations": 1, "load_steps": 1,
                                           "max_load_step": 1.0})
    tight = StaticSettings(tolerance=1e-12)
    p = sj.solve_static(cal.apply_scales(sj.build_model(hard), ("EIy",), jnp.log(jnp.array([1.2]))),
                        tight).p[-1]
    (tmp_path / "tip.csv").write_text("scene,rod,node,x,y,z\nhard,wing,-1,"
                                      + ",".join(repr(float(v)) for v in p) + "\n")
    targets = static_targets(tmp_path / "tip.csv", [hard])
    with pytest.raises(RuntimeError, match="did not converge"):
        cal.fit_static(targets, "EIy")
    fit = cal.fit_static(targets, "EIy", settings=tight)
    np.testing.assert_allclose(fit.scale, [1.2], rtol=1e-6)
