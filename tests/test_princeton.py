"""Princeton replay (simsoft_jax.apps.princeton): load cases, the batched replay against
unbatched solves of the physical set-up, the linear (Timoshenko) limit, eq. (112) and the
measurement file; the ``simsoft-jax princeton`` command end to end."""
import csv

import numpy as np
import pytest

import simsoft_jax as sj
from simsoft_jax.apps import princeton as pr
from simsoft_jax.math import lie
from simsoft_jax.cli import main
from conftest import SCENES_DIR

ELEMENTS = 8


def test_seed_cases_are_the_25_of_the_seed():
    theta, load = pr.seed_cases()
    assert len(theta) == 25
    expected = {0: [1, 2, 3, 4], 15: [1, 2, 3, 4], 30: [1, 2, 3, 4], 45: [1, 2, 3],
                60: [0.5, 1, 1.5, 2], 75: [0.5, 1, 1.5], 90: [0.5, 1, 1.5]}
    for th, multiples in expected.items():
        np.testing.assert_allclose(np.sort(load[theta == th]) / 4.448, multiples)


@pytest.fixture(scope="module")
def seed_replay():
    """The 25 seed cases and the 7 self-weight states (load 0): one batch of 32, the
    padded size of the 25 cases alone, so the other replays here reuse its compilation."""
    theta, load = pr.seed_cases()
    angles = np.unique(theta)
    return pr.replay(np.concatenate([theta, angles]), np.concatenate([load, 0 * angles]),
                     elements=ELEMENTS)


def test_replay_equals_unbatched_solve_of_the_pitched_root(seed_replay):
    """The scene file pitches the root by 30 deg and hangs a vertical 2 lbf weight with
    vertical gravity (the physical set-up); the replay rotates loads instead. Rotating the
    file's tip displacement into the root axes must give the replay's deflections."""
    data = sj.load_scene(SCENES_DIR / "princeton_theta30.toml").to_dict()
    data["rods"][0]["elements"] = ELEMENTS
    result = sj.run(sj.Scene.from_dict(data))
    R_root = np.asarray(lie.exp_so3(np.radians(30.0) * np.array([1.0, 0.0, 0.0])))
    local = R_root.T @ result.positions("beam")[-1]
    case = np.flatnonzero((seed_replay.theta_deg == 30.0) & np.isclose(seed_replay.load_N, 8.896))
    assert seed_replay.converged.all()
    assert seed_replay.iterations.max() < 60
    np.testing.assert_allclose(seed_replay.deflection[case[0], -1], local[1:], rtol=1e-9, atol=1e-12)
    assert abs(local[0] - pr.LENGTH) < 0.05 * pr.LENGTH


@pytest.mark.slow
def test_small_loads_converge_to_the_timoshenko_cantilever():
    """Without gravity and with a small tip load the beam deflects by
    ``F r^2 (3L - r)/(6 EI) + F r/GA`` at station r: along z at theta = 0 (EI_y, GA_z) and
    along y at theta = 90 (EI_z, GA_y). The constant-strain elements converge to it with
    order 2 in the mesh size."""
    F, L = 1e-4, pr.LENGTH
    K = np.asarray(sj.build_model(pr.scene(ELEMENTS)).stiffness[0])
    r = np.array([0.5, 1.0]) * L
    exact = np.zeros((2, 2, 2))
    exact[0, :, 1] = -(F * r**2 * (3 * L - r) / (6 * K[4]) + F * r / K[2])
    exact[1, :, 0] = -(F * r**2 * (3 * L - r) / (6 * K[5]) + F * r / K[1])
    errors = []
    for n in (ELEMENTS, 2 * ELEMENTS):
        sim = pr.replay([0.0, 90.0], [F, F], elements=n, gravity=False, stations=(0.5, 1.0))
        assert np.all(np.abs(sim.deflection[0, :, 0]) < 1e-15)      # no coupling
        assert np.all(np.abs(sim.deflection[1, :, 1]) < 1e-15)
        errors.append(np.abs(sim.deflection - exact).max() / np.abs(exact).max())
    assert errors[1] < 2e-3
    assert np.log2(errors[0] / errors[1]) > 1.9


def test_relative_deflections_remove_the_self_weight_state(seed_replay):
    theta, load = pr.seed_cases()
    relative = pr.replay(elements=ELEMENTS, relative=True)
    weight = seed_replay.deflection[25 + np.searchsorted(np.unique(theta), theta)]
    np.testing.assert_allclose(relative.deflection, seed_replay.deflection[:25] - weight,
                               atol=1e-12)
    assert relative.relative and relative.converged.all()
    with pytest.raises(ValueError, match="relative"):
        pr.replay([0.0], [1.0], gravity=False, relative=True)


def _measurement_file(path, sim, offset, mirrored=False):
    """Measurements = simulation + a known offset (y, z) in the CSV layout."""
    with open(path, "w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["theta_deg", "load_N", "station_m", "y_m", "z_m"]
                        + (["y_neg_theta_m", "z_neg_theta_m"] if mirrored else []))
        for c in range(len(sim.theta_deg)):
            for s, r in enumerate(sim.stations_m):
                y, z = sim.deflection[c, s] + offset
                row = [sim.theta_deg[c], sim.load_N[c], r]
                if mirrored:   # +theta and -theta runs scattered symmetrically about (y, z)
                    row += [y + 1e-4, z - 2e-4, -(y - 1e-4), z + 2e-4]
                else:
                    row += [y, z]
                writer.writerow([repr(float(v)) for v in row])
    return path


def _seed_only(replay):
    """The 25 seed cases of the fixture (without the self-weight states)."""
    return replay._replace(theta_deg=replay.theta_deg[:25], load_N=replay.load_N[:25],
                           deflection=replay.deflection[:25])


def test_eq112_errors_of_a_known_offset(tmp_path, seed_replay):
    """e_i = (|dy| + |dz|) / r_i * 100 for measurements offset by (dy, dz) from the model;
    -theta columns are mirrored and averaged."""
    sim = _seed_only(seed_replay)
    offset = np.array([3e-4, -1e-4])
    expected = 100.0 * np.abs(offset).sum() / sim.stations_m
    for mirrored in (False, True):
        path = _measurement_file(tmp_path / f"m{mirrored}.csv", sim, offset, mirrored)
        err = pr.errors(pr.read_measurements(path), elements=ELEMENTS)
        np.testing.assert_allclose(err.e, np.tile(expected, (25, 1)), rtol=1e-8)
        np.testing.assert_allclose(err.e_mu, expected.mean(), rtol=1e-8)
        np.testing.assert_allclose(err.e_sigma, expected.std(), rtol=1e-8)
        np.testing.assert_allclose(err.tip, expected[-1], rtol=1e-8)
        assert err.by_angle[15.0][0] == pytest.approx(expected.mean())
        assert err.by_angle[15.0][1] == pytest.approx(0.0, abs=1e-9)


@pytest.mark.parametrize("content, match", [
    ("theta_deg,load_N,station_m,y_m\n0,1,0.5,0\n", r"lacks column\(s\) \['z_m'\]"),
    ("theta_deg,load_N,station_m,y_m,z_m\n0,1,0.5,abc,0\n", "line 2, column y_m: not a number"),
    ("theta_deg,load_N,station_m,y_m,z_m\n0,1,0.9,0,0\n", "column station_m"),
    ("theta_deg,load_N,station_m,y_m,z_m,y_neg_theta_m\n0,1,0.5,0,0,0\n", "without its partner"),
    ("theta_deg,load_N,station_m,y_m,z_m\n", "no data rows"),
])
def test_bad_measurement_files_name_the_problem(tmp_path, content, match):
    path = tmp_path / "m.csv"
    path.write_text(content)
    with pytest.raises(ValueError, match=match):
        pr.read_measurements(path)


def test_every_case_needs_every_station(tmp_path):
    path = tmp_path / "m.csv"
    path.write_text("theta_deg,load_N,station_m,y_m,z_m\n0,1,0.5,0,0\n0,1,0.25,0,0\n"
                    "15,1,0.5,0,0\n")
    with pytest.raises(ValueError, match="has no row for station 0.25"):
        pr.errors(pr.read_measurements(path), elements=ELEMENTS)


def test_princeton_command_writes_table_and_figures(tmp_path, capsys, seed_replay):
    """``simsoft-jax princeton``: the 25 cases and, by default, the tip errors against the
    shipped ANSYS solid-element predictions (below the paper's 1 %); with measurements,
    Figs. 15-18 and errors."""
    out = tmp_path / "out"
    assert main(["princeton", "--elements", str(ELEMENTS), "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "vs ANSYS solid elements" in printed and "14 tip cases" in printed
    with open(out / "vs_ansys_solid" / "tip_errors.csv") as handle:
        tip_errors = [float(r["error_percent"]) for r in csv.DictReader(handle)
                      if float(r["station_m"]) == pr.LENGTH]
    assert len(tip_errors) == 14 and 0.0 < max(tip_errors) < 1.0
    assert (out / "vs_ansys_solid" / "fig17_mean_errors.png").stat().st_size > 10_000
    with open(out / "princeton_replay.csv") as handle:
        rows = list(csv.DictReader(handle))
    assert len(rows) == 25 * 4
    tip = np.array([[float(r["y_m"]), float(r["z_m"])] for r in rows
                    if float(r["station_m"]) == pr.LENGTH])
    np.testing.assert_allclose(tip, seed_replay.deflection[:25, -1], atol=1e-12)
    assert (out / "princeton_fig15_deflections.png").stat().st_size > 10_000
    measured = _measurement_file(tmp_path / "m.csv", _seed_only(seed_replay), np.array([0.0, 5e-4]))
    capsys.readouterr()
    assert main(["princeton", "--elements", str(ELEMENTS), "--measurements", str(measured),
                 "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    e_mu = 100 * 5e-4 * np.mean(1 / seed_replay.stations_m)
    assert f"average mean error {e_mu:.4f} %" in printed
    for fig in ("fig16_errors", "fig17_mean_errors", "fig18_error_spread"):
        assert (out / f"princeton_{fig}.png").stat().st_size > 10_000
    assert main(["princeton", "--measurements", str(tmp_path / "none.csv")]) == 2


def test_load_angle_sweep_matches_replay(seed_replay):
    """A 4 x 8 grid solved by warm-started continuation along the grid, and all at once
    (vmapped), both contain the 30 deg and 60 deg seed cases of the unbatched replay."""
    loads = pr.F0 * np.arange(1, 9) / 2
    angles = [0.0, 30.0, 60.0, 90.0]
    for warm in (True, False):
        tip, ok = pr.load_angle_sweep(angles, loads, elements=ELEMENTS, warm_start=warm)
        assert tip.shape == (4, 8, 2) and ok.all()
        for i, th, k in ((1, 30.0, 3), (2, 60.0, 1)):
            case = np.flatnonzero((seed_replay.theta_deg == th)
                                  & np.isclose(seed_replay.load_N, loads[k]))
            np.testing.assert_allclose(tip[i, k], seed_replay.deflection[case[0], -1],
                                       rtol=1e-9, atol=1e-12)
