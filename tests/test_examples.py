"""Every example script (one per seed result) runs in its fast mode and reproduces its
physics: each is started as a subprocess (``--fast --out DIR``, MPLBACKEND=Agg, from a
foreign working directory), must exit 0, write its PNG figures, and its
``summary.json`` numbers are checked against references computed here, independently of
the package:

* pure bending (seed Fig. 9): the exact circular arc (spec S74) at five torques;
* free planar rotation (Figs. 11-12): the stretched steady rotation (S79) of node B;
* helical scenes (Figs. 5-8): converged, finite, the arm length within the strain bound
  ``|F| / min(EA, k G A)``, and the work-energy theorem (work of the dead tip loads =
  kinetic + strain energy) up to the small dissipation of rho_inf = 0.9; the spring-steel
  rod, loaded slowly, ends near the quasi-static equilibrium computed here by shooting on
  the continuum Cosserat rod (scipy);
* Magellan catheter (Fig. 20): with end moments only, the quasi-static continuum solution
  is an initial-value problem (internal moment known in world coordinates), integrated
  here with scipy;
* bending actuator (Fig. 22): the section constant EI_y of a half disc, planar motion and
  the work-energy theorem;
* three-finger gripper on a palm (dynamic closing): at rest the squeeze of
  small-deflection beam theory, the three fingers pressing alike; six-leg parallel robot:
  its inverse kinematics checked on the plate body, its dynamic move settling at the
  static equilibrium (its forward kinematics against shooting:
  tests/test_parallel_robot_shooting.py);
* the measured tendon-driven robot (real data): the tendon's circular arc and tension
  (pure bending by a tendon at a constant offset) and the robot's three-fold symmetry;
* closed-loop control: model-predictive tracking beats the quasi-static open loop where
  the target is reachable, and learned PID gains end at the exact tendon arc's tension.

Run time: the scripts run in two parallel lanes, each with a persistent JAX compilation
cache (every compilation kept, one folder per lane and test session), so programs with
the same structure (the spring-steel and silicone rods, the many small eager kernels)
compile once per session.
"""
from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import pytest

from conftest import EXAMPLES_DIR, skew as hat

scipy_integrate = pytest.importorskip("scipy.integrate")
scipy_optimize = pytest.importorskip("scipy.optimize")

pytestmark = pytest.mark.slow   # subprocess lanes, minutes

EXAMPLES = EXAMPLES_DIR

FIGURES = {
    "pure_bending": ["pure_bending.png", "pure_bending_3d.png"],
    "free_planar_rotation": ["node_B_displacements.png", "errors.png", "snapshots.png"],
    "helical_motion": ["tip_displacements.png", "snapshots.png", "snapshot_t3.png"],
    "spring_steel_rod": ["tip_displacements.png", "snapshots.png"],
    "silicone_body": ["tip_displacements.png", "snapshots.png"],
    "magellan_catheter": ["snapshots.png", "tip_displacements.png"],
    "bending_actuator": ["snapshots.png", "snapshots_3d.png", "tip_displacements.png"],
    "princeton_replay": ["princeton_fig15_deflections.png", "vs_ansys_solid/fig16_errors.png",
                         "vs_ansys_solid/fig17_mean_errors.png", "vs_ansys_solid/fig18_error_spread.png"],
    "calibrate_princeton": ["calibration.png"],
    "dynamic_identification": ["tip_fit.png"],
    "princeton_sweep": ["tip_deflection_map.png"],
    "tendon_actuation": ["tendon_arcs.png"],
    "contact_catheter": ["snapshots.png", "contact_forces.png"],
    "parallel_robot": ["shapes.png", "sway.png"],
    "catheter_bend": ["snapshots.png", "contact_force.png", "catheter_bend.gif"],
    "gripper": ["grasp.png", "squeeze.png"],
    "three_finger_gripper": ["snapshots.png", "contact_force.png"],
    "six_leg_parallel_robot": ["shapes.png", "move.png"],
    "real_tdcr_tendon": ["tip_heights.png"],
    "magnetic_catheter": ["steering.png", "tip_angle.png", "swing.png"],
    "real_pazy_wing": [],
    "mpc_tendon_tracking": ["tracking.png", "tensions.png"],
    "learn_policy": ["learning_curve.png", "responses.png"],
}


# Two lanes run side by side (2 cores); each runs its examples one after the other with
# its own persistent JAX compilation cache (a cache folder is never written by two
# processes at once). Lane 0 holds the scenes that share compiled programs (spring steel
# then silicone) and the examples whose programs the notebooks compile again (pure
# bending, helical, the catheters, the control examples that notebook 09 runs whole):
# its cache is reused by tests/test_notebooks.py (same folder name). The lanes take
# about the same CPU time (about 180 s each with the test compile flags).
LANES = (("helical_motion", "spring_steel_rod", "silicone_body", "pure_bending",
          "princeton_replay", "catheter_bend", "contact_catheter", "real_pazy_wing",
          "learn_policy", "mpc_tendon_tracking"),
         ("free_planar_rotation", "magellan_catheter", "bending_actuator",
          "dynamic_identification", "princeton_sweep", "calibrate_princeton",
          "tendon_actuation", "gripper", "parallel_robot", "real_tdcr_tendon",
          "magnetic_catheter", "six_leg_parallel_robot", "three_finger_gripper"))
CACHE_NAMES = ("jax_compilation_cache", "jax_compilation_cache_lane1")


def run_example(name: str, tmp_path: Path, cache: Path) -> tuple[dict, Path]:
    """Run ``examples/<name>.py --fast`` in ``tmp_path``; check the exit code and the
    figures; return its summary.json and its output folder."""
    out = tmp_path / "out"
    env = dict(os.environ, MPLBACKEND="Agg", JAX_COMPILATION_CACHE_DIR=str(cache),
               JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS="0")
    proc = subprocess.run([sys.executable, str(EXAMPLES / f"{name}.py"), "--fast",
                           "--out", str(out)], cwd=tmp_path, env=env, capture_output=True,
                          text=True, timeout=900)
    assert proc.returncode == 0, f"{name} failed:\n{proc.stdout}\n{proc.stderr}"
    assert "summary.json" in proc.stdout
    for figure in FIGURES[name]:
        path = out / figure
        assert path.is_file() and path.stat().st_size > 1000, f"{name}: {figure} missing"
    return json.loads((out / "summary.json").read_text()), out


@pytest.fixture(scope="module")
def examples(request, tmp_path_factory):
    """Futures of the example runs (name -> (summary, out folder)), started at once in
    the two lanes for the examples whose tests are selected."""
    selected = [item.name for item in request.session.items
                if getattr(item, "module", None) is request.module]
    base = tmp_path_factory.getbasetemp()
    futures, pools = {}, []
    for lane, cache_name in zip(LANES, CACHE_NAMES):
        cache = base / cache_name
        cache.mkdir(exist_ok=True)
        pool = ThreadPoolExecutor(max_workers=1)
        pools.append(pool)
        for name in lane:
            if any(test.startswith(f"test_{name}") for test in selected):
                futures[name] = pool.submit(run_example, name, tmp_path_factory.mktemp(name),
                                            cache)
    yield futures
    for pool in pools:
        pool.shutdown(wait=True, cancel_futures=True)


def circle_constants(E, nu, density, d):
    """EA, kGA (Cowper k = 6(1+nu)/(7+6nu)), GJ, EI, EI of a solid circle; rho A."""
    G, A, I = E / (2 * (1 + nu)), math.pi * d**2 / 4, math.pi * d**4 / 64
    k = 6 * (1 + nu) / (7 + 6 * nu)
    return np.array([E * A, k * G * A, k * G * A, 2 * G * I, E * I, E * I]), density * A


# ------------------------------------------------------------------------------- statics

def test_pure_bending(examples):
    s, _ = examples["pure_bending"].result()
    assert s["converged"] and s["torques_Nm"] == [1.0, 2.0, 3.0, 4.0, 5.0]
    for tau, tip in zip(s["torques_Nm"], s["tips_m"]):
        k = tau / 1.0                                   # EI_y = 1 N m^2, L = 1 m
        exact = [math.sin(k) / k, 0.0, -(1 - math.cos(k)) / k]
        assert np.linalg.norm(np.subtract(tip, exact)) < 1e-8
    assert s["max_position_error_rel"] < 1e-8
    assert s["max_rotation_error"] < 1e-8
    assert s["max_interpolation_error_rel"] < 1e-8


def test_tendon_actuation(examples):
    """Straight tendon (tension T at z = r) and chamber (P A at z = -r): exact arcs of
    curvature ``T r / EI`` (strain ``-T/EA``) and ``P A r / EI`` (strain ``+P A / EA``)."""
    s, _ = examples["tendon_actuation"].result()
    assert s["converged"]
    L, EA, EI, r, A = s["length_m"], s["EA_N"], s["EI_Nm2"], s["offset_m"], s["area_m2"]
    loads = [(T * r / EI, -T / EA) for T in s["tensions_N"]] + [
        (P * A * r / EI, P * A / EA) for P in s["pressures_Pa"]]
    for (k, eps), tip in zip(loads, s["tips_m"], strict=True):
        exact = (1 + eps) * np.array([math.sin(k * L) / k, 0.0, (1 - math.cos(k * L)) / k])
        assert np.linalg.norm(np.subtract(tip, exact)) < 1e-10 * L
    assert s["max_error_rel"] < 1e-10


def test_parallel_robot(examples):
    """Two fixed-guided columns under a rigid welded plate: side stiffness ``24 EI / L^3``
    (the elements' constant strains make the sway converge at second order, about
    ``(L_e/L)^2`` short); the free sway period against Rayleigh's estimate with the
    columns' effective mass 13/35; the welds hold."""
    s, _ = examples["parallel_robot"].result()
    assert s["converged"]
    n, L, EI = s["elements"], s["length_m"], s["EI_Nm2"]
    k = 24 * EI / L**3
    for F, u in zip(s["forces_N"], s["sway_m"], strict=True):
        assert abs(u / (F / k) - 1) < 1.2 / n**2 + 1e-3 * F / 0.2
    mass = s["plate_kg"] + 2 * 13 / 35 * s["rho_A_kg_m"] * L
    rayleigh = 2 * math.pi * math.sqrt(mass / k)
    assert abs(s["period_s"] / rayleigh - 1) < 0.6 / n**2 + 3e-3
    assert s["max_weld_gap_m"] < 1e-10 * L


# ------------------------------------------------------------------------------ dynamics

def test_free_planar_rotation(examples):
    s, _ = examples["free_planar_rotation"].result()
    assert s["converged"]
    c0 = math.sqrt(2.7e3 / 6.9e10)                      # = sqrt(2.7e-3 / 6.9e7), seed
    assert [c["omega_rad_s"] for c in s["cases"]] == pytest.approx([math.pi, 2 * math.pi,
                                                                     3 * math.pi])
    for case in s["cases"]:
        w, t = case["omega_rad_s"], s["t_end_s"]
        xi_L = math.tan(c0 * w / 2) / (c0 * w)          # S79 at s = L = 1 m
        exact_B = np.array([0.5, 0, 0]) + xi_L * np.array([math.cos(w * t), 0, -math.sin(w * t)])
        assert case["exact_tip_stretch_m"] == pytest.approx(xi_L - 0.5, rel=1e-6)
        assert np.linalg.norm(np.subtract(case["node_B_final_m"], exact_B)) < 1e-4   # 0.01 % of L
        assert case["max_error_percent"] < 0.01        # seed: < 0.1 %


def _helical_checks(s, max_force, stiffness, energy_tolerance):
    assert s["converged"] and s["tip_finite"]
    assert s["t_end_s"] == pytest.approx(3.0)
    # |d_U| / L - 1 is bounded by the axial/shear strain |n| / min(EA, kGA)
    assert s["max_length_change_rel"] < 1.05 * max_force / min(stiffness[:3])
    # work of the tip loads = kinetic + strain energy (rho_inf = 0.9 dissipates a little)
    assert s["energy_balance_rel"] < energy_tolerance
    assert s["work_final_J"] > 0


def test_helical_motion(examples):
    s, out = examples["helical_motion"].result()
    _helical_checks(s, 2.0, [1e3, 1e3, 1e3], 2e-3)        # measured 2e-4
    # the motion is three-dimensional (seed Fig. 6): the tip moves in x, y and z
    assert min(s["tip_max_abs_m"]) > 0.3 * s["length_m"]
    gif = out / "helical_motion.gif"
    assert gif.read_bytes()[:6] in (b"GIF87a", b"GIF89a")


def test_spring_steel_rod_follows_quasi_static_path(examples):
    s, _ = examples["spring_steel_rod"].result()
    K, _ = circle_constants(210e9, 0.3, 7850.0, 2e-3)
    F, M = np.array([0.0, 0.0, 0.14 * 3]), np.array([0.0, 0.0, 0.49 * 3])
    _helical_checks(s, 0.42, K, 1e-2)                     # measured 4e-4
    # loaded over ~17 first-mode periods: near the quasi-static equilibrium at 3 s
    L = 0.5

    def tip_of(ptip, lam):
        def rhs(_, y):
            R, p = y[:9].reshape(3, 3), y[9:]
            m = lam * (M + np.cross(ptip - p, F))      # world moment, n = lam F
            gamma = np.array([1.0, 0, 0]) + R.T @ (lam * F) / K[:3]
            return np.concatenate([(R @ hat(R.T @ m / K[3:])).ravel(), R @ gamma])
        y0 = np.concatenate([np.eye(3).ravel(), np.zeros(3)])
        return scipy_integrate.solve_ivp(rhs, (0.0, L), y0, rtol=1e-10, atol=1e-12).y[9:, -1]

    ptip = np.array([L, 0.0, 0.0])
    for lam in (0.25, 0.5, 0.75, 1.0):
        ptip = scipy_optimize.fsolve(lambda q: tip_of(q, lam) - q, ptip, xtol=1e-12)
    assert np.linalg.norm(np.subtract(s["tip_final_m"], ptip)) < 4e-2 * L   # measured 1.6e-2


def test_silicone_body(examples):
    s, _ = examples["silicone_body"].result()
    K, _ = circle_constants(110e3, 0.5, 1080.0, 0.05)
    _helical_checks(s, 0.1035 * 3, K, 1e-3)   # measured 1.4e-5


def test_magellan_catheter_is_quasi_static(examples):
    s, _ = examples["magellan_catheter"].result()
    assert s["converged"] and s["units"] == "N m"
    E, G = 210e9, 210e9 / 2.6

    def tube(do, di):
        I = math.pi * (do**4 - di**4) / 64
        return np.array([2 * G * I, E * I, E * I])      # GJ, EI, EI

    tau2, tau3 = np.array(s["tau2_final_Nm"]), np.array(s["tau3_final_Nm"])
    np.testing.assert_allclose(tau2, [0.4, 4.0, 40.0])
    np.testing.assert_allclose(tau3, [-0.15, -1.5, -15.0])
    pieces = [(s["guide_length_m"], tube(3.48e-3, 2.54e-3), tau2 + tau3),
              (s["leader_length_m"], tube(2.13e-3, 1.0e-3), tau3)]
    # end moments only: n = 0, the internal moment is m (world) on each piece, so
    # R' = R (C^-1 R^T m)^, p' = R e1 from the clamp
    y = np.concatenate([np.eye(3).ravel(), np.zeros(3)])
    for length, C, m in pieces:
        def rhs(_, y, C=C, m=m):
            R = y[:9].reshape(3, 3)
            return np.concatenate([(R @ hat(R.T @ m / C)).ravel(), R[:, 0]])
        y = scipy_integrate.solve_ivp(rhs, (0.0, length), y, rtol=1e-11, atol=1e-13).y[:, -1]
    L = s["guide_length_m"] + s["leader_length_m"]
    np.testing.assert_allclose(s["quasi_static_tip_m"], y[9:], atol=1e-7 * L)
    assert np.linalg.norm(np.subtract(s["tip_final_m"], y[9:])) < 2e-3 * L   # measured 4e-4
    # both segments bend by about 2 rad (visible curling, as in Fig. 20)
    assert 1.5 < s["guide_turn_rad"] < 2.6 and 1.5 < s["leader_turn_rad"] < 2.6


def test_bending_actuator(examples):
    s, _ = examples["bending_actuator"].result()
    r, E, L = 0.01, 110e3, 0.15
    EI_y = E * (math.pi / 8 - 8 / (9 * math.pi)) * r**4    # half disc, axis parallel to flat side
    assert s["converged"]
    assert s["EI_y_Nm2"] == pytest.approx(EI_y, rel=1e-12)
    assert s["quasi_static_angle_final_rad"] == pytest.approx(0.002 * L / EI_y, rel=1e-12)
    assert s["max_out_of_plane_rel"] < 1e-12 and s["max_twist"] < 1e-12
    assert s["energy_balance_rel"] < 1e-3                 # measured 7e-5
    assert s["tip_final_m"][2] < -0.5 * L                 # curls towards the flat side (-z)
    assert 0.8 < s["tip_angle_final_rad"] / s["quasi_static_angle_final_rad"] < 1.4


def test_princeton_replay(examples):
    """Seed Figs. 15-18: 25 converged cases; symmetry (no flapwise motion at theta = 0,
    no edgewise motion at 90 deg); against the ANSYS solid-element predictions (3-D
    elasticity, shipped data) every tip error of eq. (112) is below the paper's 1 %."""
    s, _ = examples["princeton_replay"].result()
    theta, tip = np.array(s["theta_deg"]), np.array(s["tip_deflection_m"])
    assert s["converged"] and len(theta) == 25
    assert np.all(tip[theta == 0, 0] == 0) and np.all(np.abs(tip[theta == 90, 1]) < 1e-15)
    assert np.all(tip[theta == 90, 0] < -0.04)          # flapwise: tens of mm at f0/2 and more
    errors = np.array(s["ansys_tip_error_percent"])
    assert len(errors) == 14 and errors.max() < 1.0


def test_calibrate_princeton(examples):
    """3a: known factors recovered within 2 sigma; 3b: held-out error lower after the fit."""
    s, _ = examples["calibrate_princeton"].result()
    a = s["identifiability"]
    assert np.all(np.abs(np.array(a["fitted"]) - a["true"]) < 2 * np.array(a["std"]))
    b = s["ansys_held_out"]
    assert np.mean(b["error_after_percent"]) < np.mean(b["error_before_percent"])


def test_dynamic_identification(examples):
    s, _ = examples["dynamic_identification"].result()
    fitted, true, std = (np.array(s[k]) for k in ("fitted", "true", "std"))
    assert np.all(np.abs(fitted - true) < 2.5 * std) and np.all(np.abs(fitted / true - 1) < 0.03)


def test_princeton_sweep(examples):
    """The batched map: every point converged; the tip moves further with more load at
    every angle (both components grow in magnitude, or stay zero by symmetry)."""
    s, _ = examples["princeton_sweep"].result()
    tip = np.abs(np.array(s["tip_m"]))
    assert s["converged"] and s["cases"] == tip.shape[0] * tip.shape[1]
    assert np.all(np.diff(tip[1:, :, 0], axis=1) > 0)       # flapwise, theta > 0
    assert np.all(np.diff(tip[:-1, :, 1], axis=1) > 0)      # edgewise, theta < 90


# ------------------------------------------------------------------------------- contact

def test_contact_catheter(examples):
    """The light, damped catheter follows its quasi-static path: at t = 1 s its base has
    moved 40 mm and it passes under the sphere, which pushes it down by
    delta = r + R_wall - y_c at the sphere's lowest point, a = x_c - 0.04 m from the
    clamped base. Small-deflection cantilever: F = 3 EI delta / a^3 (EI of the 2/1 mm
    steel tube), to 5 % (the contact spreads over a few mm; friction 0.1 adds a small
    axial force); the force points along -y; penetration below 5 % of the radius."""
    s, _ = examples["contact_catheter"].result()
    assert s["converged"]
    EI = 210e9 * math.pi * (2e-3**4 - 1e-3**4) / 64
    xc, yc, _ = s["wall_center_m"]
    delta = s["contact_radius_m"] + s["wall_radius_m"] - yc
    a = xc - 0.04
    wall = s["contacts"]["wall"]
    assert wall["normal_force_N"][-1] == pytest.approx(3 * EI * delta / a**3, rel=0.05)
    force = np.asarray(wall["force_N"][-1])
    assert force[1] < -0.99 * np.linalg.norm(force)
    assert max(max(c["max_penetration_m"]) for c in s["contacts"].values()) < (
        0.05 * s["contact_radius_m"])


def test_catheter_bend(examples):
    """The catheter pushed through the 90 degree bend stays in the vessel and follows it.
    The vessel's centreline distance is written here from the geometry (inlet: |y| for
    x < 0; bend: | |p - C| - R | in the quadrant; outlet: |x - R| for y > R): every node,
    the free tip included (its end cap meets the wall), at every saved time, lies within
    a - r of it (to 2 % of r). The catheter is pushed, not stretched:
    its tip, ending in the outlet, is along the centreline (arc length from the bend's
    start, where it started) within (a - r) times the bend angle of the push (the inner
    and outer ways round the bend); its penetration at the contact stations (Gauss points
    and nodes) stays below
    5 % of r; the animation is a GIF."""
    s, out = examples["catheter_bend"].result()
    assert s["converged"]
    p = np.asarray(s["positions_m"])[..., :2]
    a, r, R = s["vessel_radius_m"], s["contact_radius_m"], s["bend_radius_m"]
    x, y = p[..., 0], p[..., 1]
    bend = np.abs(np.hypot(x, y - R) - R)
    dist = np.where(x < 0.0, np.abs(y), np.where(y > R, np.abs(x - R), bend))
    assert dist.max() <= a - r + 0.02 * r
    assert dist.max() > 0.5 * (a - r)                 # it does lean on the walls
    tip = p[-1, -1]
    assert tip[1] > R                                 # in the outlet at the end
    s_tip = R * s["bend_angle_rad"] + (tip[1] - R)    # centreline arc length from the start
    push, theta = s["push_m"], s["bend_angle_rad"]
    assert abs(s_tip - push) <= (a - r) * theta
    assert max(s["max_penetration_m"]) < 0.05 * r
    assert (out / "catheter_bend.gif").read_bytes()[:6] in (b"GIF87a", b"GIF89a")


def test_gripper(examples):
    """Two tendon-driven fingers squeeze a fixed frictionless sphere. A tendon at the
    constant offset d bends its finger by the uniform moment T d; held back by the
    sphere's force F at x_c, the cantilever's deflection there is
    T d x_c^2/(2 EI) - F x_c^3/(3 EI) = g (the gap), so F = 3 T d/(2 x_c) - 3 EI g/x_c^3
    (small deflections: slopes below 0.05 here). Checked: the squeeze per finger at every
    tension to 2 % of that (the contact point slides a little round the sphere and the
    contact spreads over a few mm), the two fingers pressed symmetrically (the sphere's
    net force on them has no y part, to 1e-9 of the squeeze), penetration below 1 % of
    the finger's contact radius."""
    s, _ = examples["gripper"].result()
    T = np.asarray(s["tension_N"])
    d, EI, xc, g = s["tendon_offset_m"], s["EI_Nm2"], s["sphere_x_m"], s["gap_m"]
    expected = 1.5 * T * d / xc - 3.0 * EI * g / xc**3
    assert (expected > 0).all()
    np.testing.assert_allclose(s["squeeze_N"], expected, rtol=2e-2)
    force = np.asarray(s["force_N"])
    assert np.abs(force[:, 1]).max() <= 1e-9 * max(s["squeeze_N"])
    assert max(s["max_penetration_m"]) < 1e-2 * s["finger_radius_m"]


def test_three_finger_gripper(examples):
    """Three tendon-driven fingers on a palm close dynamically on a fixed sphere (with
    friction) and settle. At rest the regularized friction is gone, so each finger's
    squeeze is the frictionless cantilever's: F = 3 T d/(2 z_c) - 3 EI g/z_c^3 (as for the
    two-finger gripper), to 3 %. The three fingers press alike: the sphere's net force on
    them has no horizontal part (to 1e-9 of the squeeze). The fingers' tips stay more
    than two contact radii apart (distance r sqrt(3) at radius r from the axis), so the
    finger-finger contact force is zero; penetration below 1 % of the finger's radius; the
    palm, held by the stiff wrist, moves by less than a micrometre."""
    s, _ = examples["three_finger_gripper"].result()
    assert s["converged"]
    T, d, EI = s["tension_final_N"], s["tendon_offset_m"], s["EI_Nm2"]
    zc, g, r = s["sphere_z_m"], s["gap_m"], s["finger_radius_m"]
    assert s["tension_N"][-1] == pytest.approx(T, rel=1e-12)
    expected = 1.5 * T * d / zc - 3.0 * EI * g / zc**3
    assert s["final_squeeze_N"] == pytest.approx(expected, rel=3e-2)
    assert s["final_horizontal_over_squeeze"] < 1e-9
    assert min(s["final_tip_radial_m"]) * math.sqrt(3) > 2 * r
    assert max(s["rod_rod_normal_force_N"]) == 0.0
    assert s["max_penetration_over_radius"] < 1e-2
    assert s["palm_max_displacement_m"] < 1e-6


def test_six_leg_parallel_robot(examples):
    """Six legs welded to a plate: the welds hold; inverse kinematics by the legs'
    lengths reaches its target, checked on the plate body of a forward solve (its six
    attachment points fix its pose); the dynamic move by the base drives settles at the
    static equilibrium of the clamps moved by the same strokes, which is within 1 % of
    the largest stroke of the target (pushing a clamp by delta instead of inserting delta
    more leg differs at second order). The forward kinematics against an independent
    shooting solution: tests/test_parallel_robot_shooting.py."""
    s, _ = examples["six_leg_parallel_robot"].result()
    assert s["converged"]
    length = min(s["nominal_lengths_m"])
    assert s["max_weld_gap_m"] < 1e-10 * length
    ik = s["inverse"]
    assert ik["reached"]
    assert ik["plate_position_error_m"] < 1e-8 * length
    assert ik["plate_angle_error_rad"] < 1e-7
    dyn = s["dynamic"]
    stroke = np.abs(dyn["strokes_m"]).max()
    assert stroke > 1e-3
    assert dyn["settle_position_error_m"] < 1e-4 * stroke
    assert dyn["settle_angle_error_rad"] < 1e-5
    assert dyn["static_to_target_m"] < 1e-2 * stroke


def test_real_pazy_wing_from_the_shipped_data(examples):
    """The Pazy wing built from the shipped beam data reproduces the published UM/NAST beam
    model (same data, 0.1 %); flap and torsion stiffness calibrated on the lighter tip mass
    predict the heavier one better than the data's nominal stiffness does."""
    s, _ = examples["real_pazy_wing"].result()
    assert s["cli_status"] == 0
    assert s["max_relative_difference_to_UMNAST"]["uz"] < 1e-3
    held = s["lighter_to_heavier"]["skin0"]["held_out"]["uz"]
    assert held["n"] == 2 and held["rms"] < 0.5 * s["rms_error_vs_measured"]["uz"]


def test_real_tdcr_tendon_bends_the_backbone_into_the_tendon_arc(examples):
    """The measured tendon-driven robot (examples/real_tdcr_tendon.py): a tendon at the
    constant offset r pulled in by delta bends the backbone (EI of the Nitinol tube) into
    a circular arc of angle theta = delta / r with tension T = EI theta / (L r)
    (inextensible, weightless). The tube's weight (7 mN against tensions of 3-6 N) and
    its axial compression T L / EA (0.4 % of delta) move the tip by well under 0.3 % of L
    and the tension by under 2 %. Checked for all six pulled rows: the tip against the arc
    in the pulled tendon's direction (world (-sin a, cos a) for a tendon at angle a in the
    section's y-z plane, whose x is world +z), the tension against T, the loose tendons
    at zero tension, and the three tendons giving the same height and tension (the
    robot's symmetry) to 1e-9."""
    s, _ = examples["real_tdcr_tendon"].result()
    assert s["converged"]
    E, L, r = 83e9, 0.25, 6e-3                      # the example's tube and tendons
    EI = E * math.pi * (1.22e-3**4 - 0.954e-3**4) / 64
    pulled = [row for row in s["rows"] if max(row["pull_m"]) > 0]
    assert len(pulled) == 6
    by_pull = {}
    for row in pulled:
        k = int(np.argmax(row["pull_m"]))
        delta, a = row["pull_m"][k], math.radians((0.0, 120.0, 240.0)[k])
        theta = delta / r
        lateral, height = L * (1 - math.cos(theta)) / theta, L * math.sin(theta) / theta
        arc = np.array([-math.sin(a) * lateral, math.cos(a) * lateral, height])
        assert np.linalg.norm(np.subtract(row["tip_m"], arc)) < 3e-3 * L
        tensions = np.asarray(row["tensions_N"])
        assert abs(tensions[k] - EI * theta / (L * r)) < 2e-2 * EI * theta / (L * r)
        assert np.all(np.delete(tensions, k) == 0.0)
        by_pull.setdefault(delta, []).append((row["z_model_m"], tensions[k]))
    for same in by_pull.values():
        assert len(same) == 3
        np.testing.assert_allclose(same, [same[0]] * 3, rtol=1e-9)


def test_magnetic_catheter(examples):
    """Every field direction converges; the tips lie on the shooting solution of the
    elastica with the magnet's couple (to 0.2 % of the length at 20 elements); the tip turns
    towards the field but not past it, more for a larger field angle; the dynamic run settles
    near the static shape."""
    s, _ = examples["magnetic_catheter"].result()
    assert all(s["converged"])
    assert s["max_tip_error_m"] < 2e-4
    tips, fields = np.array(s["tip_angles_deg"]), np.array(s["field_angles_deg"])
    assert np.all(np.diff(tips) > 0) and np.all((tips > 0) & (tips < fields))
    assert s["dynamic_status"] == "converged"
    assert s["dynamic_final_distance_to_static_m"] < 3e-3


# ------------------------------------------------------------------------- closed-loop control
def tendon_arc_tension(z, L=0.2, EA=50.0, EI=2e-4, r=0.005):
    """Tension (N) of the exact arc of an arm pulled by a straight tendon at offset r
    (curvature T r / EI, axial strain -T / EA) whose tip height is z (bisection)."""
    def height(T):
        k = T * r / EI
        return (1.0 - T / EA) * (1.0 - math.cos(k * L)) / k
    lo, hi = 1e-6, math.pi * EI / (r * L)
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if height(mid) < z else (lo, mid)
    return 0.5 * (lo + hi)


def test_mpc_tendon_tracking(examples):
    """Receding-horizon control (examples/mpc_tendon_tracking.py): every rollout
    converged; where the floor leaves the target reachable, MPC tracks it better than
    the quasi-static open loop; the floor holds the tip's centreline above its reach
    (contact radius) up to the penalty's small penetration; each plan lowered its
    horizon cost below that of a target missed by the full amplitude."""
    s, _ = examples["mpc_tendon_tracking"].result()
    assert s["converged"]
    assert s["rms_error_mpc_reachable_m"] < 0.8 * s["rms_error_open_loop_reachable_m"]
    assert s["lowest_tip_mpc_m"] > s["floor_reach_m"] - 1e-3
    assert max(s["mpc_final_horizon_costs"]) < 1.0


def test_learn_policy(examples):
    """Learned PID gains (examples/learn_policy.py): the loss decreases; each long
    closed-loop run with the learned gains ends closer to its target than with the
    initial gains, within 10 um, with the integral term at the tension of the exact
    tendon arc through that target (pure bending by a tendon at constant offset)."""
    s, _ = examples["learn_policy"].result()
    assert s["converged"]
    assert s["losses"][-1] < 0.8 * s["losses"][0]
    for z, error, before, tension in zip(s["targets_m"], s["final_errors_m"],
                                         s["initial_gains_final_errors_m"],
                                         s["integral_tension_N"]):
        exact = tendon_arc_tension(z)
        assert abs(error) < min(1e-5, abs(before))
        assert abs(tension - exact) < 1e-3 * exact
