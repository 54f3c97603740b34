"""Calibration that scales and reports honestly: a subset solves only its scenes,
predictions reuse the compiled programs, the scenes' solver settings are honoured (a failed
solve names its scene), splits by a column, priors, and the Gauss-Newton uncertainty and
identifiability checked against finite differences and exact degeneracies."""
import collections
import contextlib

import jax
import numpy as np
import pytest

import simsoft_jax as sj
from simsoft_jax.studies import observation_splits as splits
from simsoft_jax.studies.calibration_groups import Group, fit_groups, parse_groups, predict, prior_rows
from simsoft_jax.studies.calibration_report import metrics
from simsoft_jax.studies.measurements import observation_set
from simsoft_jax.solvers.statics import StaticSettings

from test_calibration_groups import strip

HEADER = "scene,rod,node,offset_x,offset_y,offset_z,quantity,value,std,reference,tip_mass\n"
COMPILE_EVENT = "/jax/core/compile/backend_compile_duration"


BEHIND = 0.05      # m: the weight hangs behind the axis (bending and twist)


MASSES = (0.2, 0.4, 0.6, 0.8)


def observations(tmp_path, values=None, masses=MASSES, std=0.0005):
    """Tip deflection and twist of each loaded strip relative to the unloaded one."""
    scenes = [strip("unloaded", 0.0, BEHIND)] + [strip(f"m{m}", m, BEHIND) for m in masses]
    rows = []
    for m in masses:
        rows.append(f"m{m},wing,-1,0,0,0,uz,0,{std},unloaded,{m}")
        rows.append(f"m{m},wing,-1,,,,twist,0,{std},unloaded,{m}")
    path = tmp_path / "obs.csv"
    path.write_text(HEADER + "\n".join(rows) + "\n")
    obs = observation_set(path, scenes)
    if values is not None:
        obs = obs._replace(value=np.asarray(values, float))
    return obs, scenes


@contextlib.contextmanager
def compilations():
    count = collections.Counter()

    def listen(event, duration, **kwargs):
        if event == COMPILE_EVENT:
            count["n"] += 1

    jax.monitoring.register_event_duration_secs_listener(listen)
    try:
        yield count
    finally:
        jax.monitoring.unregister_event_duration_listener(listen)


def test_subset_solves_only_its_scenes_and_predicts_the_same(tmp_path):
    obs, _ = observations(tmp_path)
    groups = parse_groups("EIy,GJ")
    full = predict(obs, groups, [1.2, 0.9])
    keep = obs.column("tip_mass") == 0.4
    sub = obs.subset(keep)
    assert set(sub.names) == {"m0.4", "unloaded"}
    assert len(sub.models) == 2 and len(sub.settings) == 2
    np.testing.assert_allclose(predict(sub, groups, [1.2, 0.9]), full[keep], rtol=1e-10,
                               atol=1e-14)
    # a second prediction of the same layout compiles nothing
    with compilations() as count:
        again = predict(sub, groups, [1.1, 1.0])
    assert count["n"] == 0 and not np.allclose(again, full[keep])


def test_scene_solver_settings_are_honoured_and_failures_name_the_scene(tmp_path):
    """A scene that allows one Newton iteration in one load step cannot converge: its
    prediction fails naming it and the status; the same rows with default settings
    given explicitly succeed."""
    hard = strip("m0.8", 0.8, BEHIND, solver={"kind": "static", "tolerance": 1e-12,
                                      "max_iterations": 1, "load_steps": 1,
                                      "max_load_step": 1.0})
    path = tmp_path / "obs.csv"
    path.write_text(HEADER + "m0.8,wing,-1,0,0,0,uz,0,1,,0.8\n")
    obs = observation_set(path, [hard])
    with pytest.raises(RuntimeError, match=r"m0\.8: .*"):
        predict(obs, parse_groups("EIy"))
    value = predict(obs, parse_groups("EIy"), settings=StaticSettings(tolerance=1e-12))
    assert value[0] < -0.01


def test_fit_recovers_scales_with_gauss_newton_std_from_finite_differences(tmp_path):
    """Synthetic data from known scales plus a fixed perturbation: the fit reaches a
    stationary point, and its covariance is ``(J^T J)^-1`` with J by central differences
    of the predictions (rows normalized by their std)."""
    obs, _ = observations(tmp_path)
    groups = parse_groups("EIy,GJ")
    true = np.array([1.15, 0.85])
    noise = 0.0005 * np.array([0.7, -1.1, 0.4, 0.9, -0.6, 0.2, -1.3, 0.5])
    data = obs._replace(value=predict(obs, groups, true) + noise)
    fit = fit_groups(data, groups)
    assert fit.converged and fit.outcome == "STATIONARY" and not fit.unidentified
    assert np.all(np.abs(np.log(fit.scale / true)) < 3 * fit.std / fit.scale)
    h = 1e-5
    J = np.stack([(predict(data, groups, fit.scale * np.exp(h * e))
                   - predict(data, groups, fit.scale * np.exp(-h * e))) / (2 * h)
                  for e in np.eye(2)], axis=1) / data.std[:, None]
    cov = np.linalg.inv(J.T @ J)
    np.testing.assert_allclose(fit.covariance, cov, rtol=1e-4)
    np.testing.assert_allclose(fit.std, fit.scale * np.sqrt(np.diag(cov)), rtol=1e-4)
    assert fit.correlation[0, 1] == pytest.approx(cov[0, 1] / np.sqrt(cov[0, 0] * cov[1, 1]),
                                                  abs=1e-4)


def test_two_perfectly_correlated_groups_are_reported_unidentifiable(tmp_path):
    """One tip deflection cannot separate the root and tip halves' flap stiffness: the
    information matrix is singular; the fit says so (labels and a message) instead of
    wandering off; a smoothness prior ties the halves, which then both take the factor
    of a single group."""
    scenes = [strip("m0.5", 0.5, BEHIND, elements=4)]
    path = tmp_path / "one.csv"
    path.write_text(HEADER + "m0.5,wing,-1,0,0,0,uz,0,0.0005,,0.5\n")
    obs = observation_set(path, scenes)
    one = parse_groups("EIy")
    obs = obs._replace(value=predict(obs, one, [1.3]))
    halves = parse_groups("EIy@0-1,EIy@2-3")
    fit = fit_groups(obs, halves)
    assert set(fit.unidentified) == {"EIy@0-1", "EIy@2-3"}
    assert "cannot identify" in fit.message and "EIy@0-1" in fit.message
    assert np.all(np.isinf(fit.std))
    tied = fit_groups(obs, halves, smoothness=1e-3)
    assert not tied.unidentified
    np.testing.assert_allclose(tied.scale, [1.3, 1.3], rtol=1e-3)


def test_unidentifiable_pair_ends_in_few_steps_with_its_status(tmp_path):
    """Two groups one deflection cannot tell apart: the fit moves only along the
    combination the data determine (the information matrix's range) and leaves the other
    where it stands (the start), so it settles in a few steps, fits the row exactly and says so
    (outcome UNIDENTIFIED, the combination kept in the message); the scales stay near the
    generating 1.3 instead of running off along the undetermined direction."""
    scenes = [strip("m0.5", 0.5, BEHIND, elements=4)]
    path = tmp_path / "one.csv"
    path.write_text(HEADER + "m0.5,wing,-1,0,0,0,uz,0,0.0005,,0.5\n")
    obs = observation_set(path, scenes)
    obs = obs._replace(value=predict(obs, parse_groups("EIy"), [1.3]))
    halves = parse_groups("EIy@0-1,EIy@2-3")
    fit = fit_groups(obs, halves, max_steps=100)
    assert fit.outcome == "UNIDENTIFIED" and fit.converged and fit.iterations <= 8
    assert "left (" in fit.message and "where it stood" in fit.message
    assert "settled in" in fit.message and "EIy@2-3" in fit.message
    assert abs(fit.residuals[0]) < 1e-6                 # normalized by the 0.5 mm std
    np.testing.assert_allclose(predict(obs, halves, fit.scale), obs.value, rtol=1e-8)
    assert np.all((fit.scale > 1.0) & (fit.scale < 1.6))
    assert fit.to_dict()["outcome"] == "UNIDENTIFIED"


def test_group_prior_pulls_the_scale_and_adds_its_information(tmp_path):
    """A prior row ``(x - log s0) / sigma``; with a prior far tighter than the data the
    fitted scale is the prior's, and the prior rows are what :func:`prior_rows` writes."""
    A, b = prior_rows((Group("a", "EIy", prior=(2.0, 0.5)), Group("b", "GJ", first=0, last=1),
                       Group("c", "GJ", first=2, last=3)), smoothness=0.1)
    np.testing.assert_allclose(A, [[2.0, 0, 0], [0, 10.0, -10.0]])
    np.testing.assert_allclose(b, [np.log(2.0) / 0.5, 0.0])
    obs, _ = observations(tmp_path, masses=(0.4,))
    obs = obs._replace(value=predict(obs, parse_groups("EIy,GJ"), [1.2, 1.0]))
    fit = fit_groups(obs, (Group("EIy", "EIy", prior=(0.9, 1e-6)), Group("GJ", "GJ")))
    assert fit.scale[0] == pytest.approx(0.9, rel=1e-5)
    assert fit.std[0] == pytest.approx(0.9 * 1e-6, rel=1e-2)


def test_splits_by_column_and_metrics_per_quantity(tmp_path):
    obs, _ = observations(tmp_path, masses=(0.2, 0.4, 0.6, 0.8, 1.0))
    mass = obs.column("tip_mass")
    lower, upper = splits.lower_upper(obs, "tip_mass")
    assert set(mass[lower]) == {0.2, 0.4, 0.6} and set(mass[upper]) == {0.8, 1.0}
    kept, held = splits.alternate(obs, "tip_mass")
    assert set(mass[held]) == {0.4, 0.8}
    folds = splits.k_fold(obs, "tip_mass", 2)
    assert len(folds) == 2 and np.all(folds[0][1] == folds[1][0])
    assert set(mass[folds[0][1]]) == {0.2, 0.6, 1.0}
    by_quantity = splits.lower_upper(obs, "tip_mass", within="quantity")[0]
    np.testing.assert_array_equal(by_quantity, lower)
    with pytest.raises(ValueError, match="no value in column 'load'"):
        obs.column("load")
    predicted = obs.value + np.where(obs.column("quantity") == "uz", 0.002, -0.01)
    m = metrics(obs, predicted)
    assert m["uz"]["n"] == 5 and m["uz"]["rms"] == pytest.approx(0.002)
    assert m["twist"]["mean"] == pytest.approx(-0.01)
    assert m["twist"]["rms_over_std"] == pytest.approx(0.01 / 0.0005)


@pytest.mark.slow
def test_cli_holds_out_the_upper_tip_masses(tmp_path, capsys):
    """``calibrate --hold-out-by tip_mass``: fitted on the two lighter masses, the two
    heavier ones are predicted (synthetic data from known scales: errors at round-off),
    with the errors per quantity."""
    from simsoft_jax.cli import main
    obs, scenes = observations(tmp_path)
    groups = parse_groups("EIy,GJ")
    values = predict(obs, groups, [1.1, 0.9])
    paths = []
    for scene in scenes:
        paths.append(str(tmp_path / f"{scene.name}.toml"))
        sj.save_scene(scene, paths[-1])
    lines = (tmp_path / "obs.csv").read_text().splitlines()
    body = [ln.replace(",0,0.0005,", f",{float(v)!r},0.0005,") for ln, v in zip(lines[1:], values)]
    (tmp_path / "m.csv").write_text("\n".join(lines[:1] + body) + "\n")
    assert main(["calibrate", "--scenes", *paths, "--measurements", str(tmp_path / "m.csv"),
                 "--params", "EIy,GJ", "--hold-out-by", "tip_mass"]) == 0
    printed = capsys.readouterr().out
    assert "held-out rows: 4 rows" in printed and "held-out uz: 2 rows" in printed
    rms = float(printed.split("held-out twist: 2 rows, rms ")[1].split(",")[0])
    assert rms < 1e-9


def test_levenberg_marquardt_stops_when_no_decrease_is_left():
    """A linear least-squares problem with an inconsistent right-hand side: the cost test
    (the Gauss-Newton model predicts no further decrease) ends it as STATIONARY at the
    normal-equations solution after one accepted step and one check, instead of
    shrinking rejected steps until the damping overflows."""
    from simsoft_jax.studies.least_squares import Outcome, least_squares
    A = np.array([[1.0, 0.0], [1.0, 1.0], [1.0, 2.0], [1.0, 3.0]])
    y = np.array([0.1, 0.9, 2.2, 2.8])

    def evaluate(U):
        return (U @ A.T - y), np.broadcast_to(A, (len(U),) + A.shape), np.ones(len(U), bool)

    sol = least_squares(evaluate, np.zeros((1, 2)), np.full((1, 2), -np.inf),
                        np.full((1, 2), np.inf), lambda r: np.full(len(r), np.inf), 0.0,
                        gradient_tolerance=0.0, cost_tolerance=1e-12)
    assert sol.outcome[0] == Outcome.STATIONARY and sol.steps[0] <= 3
    np.testing.assert_allclose(sol.u[0], np.linalg.lstsq(A, y, rcond=None)[0], rtol=1e-6)
