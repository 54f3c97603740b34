"""Tendons and pressure chambers (``[[tendons]]``, ``[[chambers]]``).

References, all independent of the code's output:
- closed forms: a straight tendon at offset r with tension T bends a clamped straight rod
  into an arc of curvature ``T r / EI`` (per reference arc length) with axial strain
  ``-T / EA``; a chamber (pressure P, area A, offset r) gives curvature ``P A r / EI``
  and strain ``+P A / EA``;
- a shooting solution of the tendon-driven Cosserat rod (Rucker & Webster 2011, IEEE
  T-RO 27(6)) written here: free-body equilibrium of the rod and tendons beyond a cut
  ``s`` (total force N = the tip force, total moment M with ``M' = -p' x N``), the
  strains at each s from the constitutive law with the tendon's pull along its own
  tangent ``tau = (v + u x rho + rho') / |..|`` (a fixed-point solve), integrated with
  ``solve_ivp`` and shot on ``M(0)`` so that ``M(L) = 0``;
- a chamber on a curved rod against the same model with a tendon of tension ``-P A``.
Gradients through statics and rollouts, and the agreement of the two tangent paths, are
checked with the other terms in tests/test_one_model.py and tests/test_tangent_paths.py
(their scene has a helical tendon and a chamber).
"""
import json
import subprocess
import sys

import jax
import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import root

import simsoft_jax as sj
from conftest import REPO_ROOT, tendon_length_changes

EA, GA, GJ, EI = 2e3, 1e3, 0.4, 0.5
STIFFNESS = {"EA": EA, "GAy": GA, "GAz": GA, "GJ": GJ, "EIy": EI, "EIz": EI}
INERTIA = {"rhoA": 0.1, "rhoJ": 1e-4, "rhoIy": 5e-5, "rhoIz": 5e-5}


def rod_scene(elements, length=0.5, geometry=None, **extra):
    """A clamped rod (node 0) with the stiffness above; ``extra``: tendons, chambers,
    loads."""
    scene = {"solver": {"kind": "static", "tolerance": 1e-12},
             "rods": [{"name": "arm", "elements": elements,
                       "geometry": geometry or {"kind": "straight", "length": length},
                       "stiffness": STIFFNESS, "inertia": INERTIA}],
             "constraints": [{"kind": "clamp", "rod": "arm", "node": 0}]}
    scene.update(extra)
    return scene


def actuated(elements, tension=0.0, pressure=0.0, tip=(0.0, 0.0, 0.0), geometry=None,
             tendon_offset=(0.0, 0.01), chamber_offset=(0.0, -0.008)):
    """A rod with one tendon (to the tip), one chamber (area 1e-4) and a dead tip force:
    the same structure (one compilation per element count) for every value."""
    return rod_scene(elements, geometry=geometry, loads=[
        {"kind": "force", "rod": "arm", "node": -1, "vector": list(tip)}], tendons=[
        {"name": "t1", "rod": "arm", "from_node": 0, "to_node": -1,
         "offset": list(tendon_offset), "tension": tension}], chambers=[
        {"name": "c1", "rod": "arm", "from_node": 0, "to_node": -1, "area": 1e-4,
         "offset": list(chamber_offset), "pressure": pressure}])


def solve(scene_or_model):
    model = (scene_or_model if isinstance(scene_or_model, sj.Model)
             else sj.build_model(sj.Scene.from_dict(scene_or_model)))
    return np.asarray(sj.solve_static(model, throw=True).p)


def arc(length, elements, kappa, eps):
    """Node positions of a straight rod (along x) bent about -y into an arc towards +z:
    curvature ``kappa`` per reference length, axial strain ``eps``."""
    s = np.linspace(0.0, length, elements + 1)
    return (1.0 + eps) * np.stack([np.sin(kappa * s) / kappa, 0.0 * s,
                                   (1.0 - np.cos(kappa * s)) / kappa], axis=1)


@pytest.mark.parametrize("elements", [1, 6])
def test_straight_tendon_and_chamber_bend_arcs(elements):
    """Tendon at z = r, tension T: curvature T r / EI, strain -T / EA. Chamber at z = -r
    (it pushes that side longer), P A: curvature P A r / EI, strain +P A / EA."""
    L, r, T, P, A = 0.5, 0.01, 20.0, 2e4, 1e-4
    p = solve(actuated(elements, tension=T))
    np.testing.assert_allclose(p, arc(L, elements, T * r / EI, -T / EA), rtol=0,
                               atol=1e-10 * L)
    p = solve(actuated(elements, pressure=P, chamber_offset=(0.0, -r)))
    np.testing.assert_allclose(p, arc(L, elements, P * A * r / EI, P * A / EA), rtol=0,
                               atol=1e-10 * L)


def test_chamber_on_a_curved_rod_is_a_tendon_of_tension_minus_pressure_times_area():
    """On an arc (reference curvature, an in-plane tip load) the chamber and a tendon of
    tension -P A at the same offset load the rod alike when the tendon's tangent stays
    along the section normal: no shear (a sheared or twisted section makes
    ``|t| - t_x ~ gamma^2 / 2``; here the shear stiffness is 1e7 N and the rod stays in
    its plane). A tendon cannot push, so the scene refuses T < 0; the model array takes
    it."""
    P, A, offset = 1.2e5, 1e-4, (0.01, 0.0)
    geometry = {"kind": "arc", "radius": 0.4, "angle_deg": 60.0}
    model = sj.build_model(sj.Scene.from_dict(actuated(
        6, pressure=P, tip=(0.0, 0.5, 0.0), geometry=geometry, tendon_offset=offset,
        chamber_offset=offset)))
    model = model.replace(stiffness=model.stiffness.at[:, 1:3].set(1e7))
    p_chamber = solve(model)
    p_tendon = solve(model.replace(chamber_pressure=0.0 * model.chamber_pressure,
                                   tendon_tension=model.tendon_tension - P * A))
    p_unpressed = solve(model.replace(chamber_pressure=0.0 * model.chamber_pressure))
    assert np.abs(p_chamber - p_unpressed).max() > 0.005     # the chamber's own part
    np.testing.assert_allclose(p_tendon, p_chamber, rtol=0, atol=1e-10)


# ----------------------------------------------------------- shooting reference (R & W)

def _hat(u):
    return np.array([[0.0, -u[2], u[1]], [u[2], 0.0, -u[0]], [-u[1], u[0], 0.0]])


def shooting(length, tendons, tip_force, s_out):
    """Node positions at ``s_out`` of a clamped straight rod (along x, section axes y, z)
    with tendons ``(T, rho(s) (3,), rho'(s) (3,), s_end)`` (tension, offset in the section
    frame and its derivative, termination) and a dead tip force (3,)."""
    Kse, Kbt = np.array([EA, GA, GA]), np.array([GJ, EI, EI])
    F = np.asarray(tip_force, float)

    def strains(s, R, M, x):
        """(v, u) with K_se (v - e_x) = R^T N - sum T tau, K_bt u = R^T M - sum T rho x tau."""
        active = [(T, rho(s), drho(s)) for T, rho, drho, end in tendons if s < end]
        for _ in range(100):
            n, m = R.T @ F, R.T @ M
            for T, r, dr in active:
                t = x[:3] + np.cross(x[3:], r) + dr
                tau = t / np.linalg.norm(t)
                n, m = n - T * tau, m - T * np.cross(r, tau)
            new = np.concatenate([np.array([1.0, 0.0, 0.0]) + n / Kse, m / Kbt])
            if np.max(np.abs(new - x)) < 1e-15:
                return new
            x = new
        raise RuntimeError("strains: no fixed point")

    def rhs(s, y):
        R, M = y[3:12].reshape(3, 3), y[12:]
        x = strains(s, R, M, np.array([1.0, 0, 0, 0, 0, 0]))
        v, u = x[:3], x[3:]
        return np.concatenate([R @ v, (R @ _hat(u)).ravel(), -np.cross(R @ v, F)])

    breaks = sorted({0.0, length} | {min(end, length) for *_, end in tendons})

    def integrate(M0, dense=False):
        y, pieces = np.concatenate([np.zeros(3), np.eye(3).ravel(), M0]), []
        for a, b in zip(breaks[:-1], breaks[1:]):
            sol = solve_ivp(rhs, (a, b), y, method="DOP853", rtol=1e-8, atol=1e-10,
                            dense_output=dense)
            y = sol.y[:, -1]
            pieces.append((a, b, sol))
        return y, pieces

    shot = root(lambda M0: integrate(M0)[0][12:], np.zeros(3), tol=1e-12)
    assert shot.success
    _, pieces = integrate(shot.x, dense=True)
    return np.array([next(sol.sol(s)[:3] for a, b, sol in pieces if a <= s <= b)
                     for s in s_out])


L_SHOOT, N_SHOOT, R_T, PITCH = 0.5, 32, 0.01, 0.5
TIP = [0.0, 0.3, -0.5]


def _helix(s):
    a = 2.0 * np.pi * s / PITCH
    return np.array([0.0, R_T * np.cos(a), R_T * np.sin(a)])


def _helix_slope(s):
    a, k = 2.0 * np.pi * s / PITCH, 2.0 * np.pi / PITCH
    return np.array([0.0, -R_T * k * np.sin(a), R_T * k * np.cos(a)])


def _table(s):
    return np.array([0.0, 0.02 * s / L_SHOOT, 0.015 - 0.01 * s / L_SHOOT])


ROUTINGS = {
    "helix": ({"kind": "helix", "radius": R_T, "pitch": PITCH, "phase_deg": 0.0},
              _helix, _helix_slope),
    "table": ({"kind": "table", "s": [0.0, L_SHOOT], "y": [0.0, 0.02], "z": [0.015, 0.005]},
              _table, lambda s: np.array([0.0, 0.02 / L_SHOOT, -0.01 / L_SHOOT])),
}


def shooting_scene(t1_offset, T1, T2):
    """32 elements, a tip force, tendon t1 (routed, to the tip) and t2 (offset -r in z,
    to the middle node): one structure for every case of the shooting tests."""
    return rod_scene(N_SHOOT, L_SHOOT, loads=[
        {"kind": "force", "rod": "arm", "node": -1, "vector": TIP}], tendons=[
        {"name": "t1", "rod": "arm", "offset": t1_offset, "tension": T1},
        {"name": "t2", "rod": "arm", "to_node": N_SHOOT // 2, "offset": [0.0, -R_T],
         "tension": T2}])


NODES = np.arange(0, N_SHOOT + 1, 4)


@pytest.mark.slow
@pytest.mark.parametrize("routing", sorted(ROUTINGS))
def test_routed_tendon_matches_shooting(routing):
    """Helical and variable-offset routing with a tip force, 32 elements: within 1e-4 of
    the length of the shooting solution (the elements converge at second order: 8
    elements are ~5e-4 off)."""
    offset, rho, drho = ROUTINGS[routing]
    T = 15.0
    p = solve(shooting_scene(offset, T, 0.0))
    ref = shooting(L_SHOOT, [(T, rho, drho, L_SHOOT)], TIP, NODES * L_SHOOT / N_SHOOT)
    assert np.abs(ref[-1, 1:]).max() > 0.02            # the tendon bends the rod a lot
    np.testing.assert_allclose(p[NODES], ref, rtol=0, atol=1e-4 * L_SHOOT)


@pytest.mark.slow
def test_antagonistic_tendons_match_shooting():
    """Two tendons on opposite sides, one ending half-way (t1's offset is a constant
    table, so the structure is the routed tests' one)."""
    T1, T2 = 12.0, 20.0
    p = solve(shooting_scene({"kind": "table", "s": [0.0, L_SHOOT], "y": [0.0, 0.0],
                              "z": [R_T, R_T]}, T1, T2))
    zero = lambda s: np.zeros(3)  # noqa: E731
    ref = shooting(L_SHOOT, [(T1, lambda s: np.array([0.0, 0.0, R_T]), zero, L_SHOOT),
                             (T2, lambda s: np.array([0.0, 0.0, -R_T]), zero, L_SHOOT / 2)],
                   TIP, NODES * L_SHOOT / N_SHOOT)
    assert ref[len(ref) // 2, 2] < -0.01    # the stronger bottom tendon wins up to its end
    np.testing.assert_allclose(p[NODES], ref, rtol=0, atol=1e-4 * L_SHOOT)


# ------------------------------------------------------------------ displacement control

def displaced(elements, delta):
    scene = actuated(elements)
    tendon = scene["tendons"][0]
    del tendon["tension"]
    tendon["displacement"] = delta
    return scene


def test_displacement_control_gives_the_tension_tension_control_needs():
    """Straight tendon at offset r shortened by delta: ``Delta l = L (eps + kappa r)``
    with ``eps = -T/EA``, ``kappa r = -T r^2 / EI``, so ``T = -delta / (L (1/EA +
    r^2/EI))``; tension control with that T gives the same shape. A lengthened tendon
    would have to push: its negative tension is reported as slack."""
    L, r, delta = 0.5, 0.01, -0.005
    result = sj.run(displaced(6, delta), stability=False)
    T = -delta / (L * (1.0 / EA + r**2 / EI))
    assert result.converged and not result.slack_tendons
    assert result.tendon_tension("t1") == pytest.approx(T, rel=1e-10)
    assert result.to_dict()["tendons"]["t1"]["tension"] == pytest.approx(T, rel=1e-10)
    np.testing.assert_allclose(result.positions("arm"), solve(actuated(6, tension=T)),
                               rtol=0, atol=1e-10)
    np.testing.assert_allclose(result.positions("arm"), arc(L, 6, T * r / EI, -T / EA),
                               rtol=0, atol=1e-10)
    with pytest.warns(UserWarning, match="'t1' would have to push"):
        slack = sj.run(displaced(6, 0.002), stability=False)
    assert slack.slack_tendons == ("t1",) and slack.tendon_tension("t1") < 0.0
    assert "slack" in slack.message


@pytest.mark.slow
def test_displacement_controlled_tension_gradient():
    """d T / d delta and d T / d EI of the solved tension (implicit function theorem)
    against the closed form's derivatives."""
    import jax

    L, r, delta = 0.5, 0.01, -0.005
    model = sj.build_model(sj.Scene.from_dict(displaced(6, delta)))
    grad = jax.grad(lambda m: sj.solve_static(m).tendon_tension[0])(model)
    c = L * (1.0 / EA + r**2 / EI)
    assert float(grad.tendon_displacement[0]) == pytest.approx(-1.0 / c, rel=1e-8)
    # T = -delta / c: dT/dEI = -delta L r^2 / (c^2 EI^2), over the 6 elements' EI_y
    dT_dEI = -delta * L * r**2 / (c**2 * EI**2)
    assert float(grad.stiffness[:, 4].sum()) == pytest.approx(dT_dEI, rel=1e-8)


# ---------------------------------------------------------------- results and the CLI

CLI_SCENE = """
[solver]
kind = "static"
tolerance = 1e-12

[[rods]]
name = "arm"
elements = 6
geometry = { kind = "straight", length = 0.5 }
stiffness = { EA = 2e3, GAy = 1e3, GAz = 1e3, GJ = 0.4, EIy = 0.5, EIz = 0.5 }
inertia = { rhoA = 0.1, rhoJ = 1e-4, rhoIy = 5e-5, rhoIz = 5e-5 }

[[constraints]]
kind = "clamp"
rod = "arm"
node = 0

[[tendons]]
name = "t1"
rod = "arm"
from_node = 0
to_node = -1
offset = [0.0, 0.01]
tension = 20.0
profile = { kind = "ramp", t0 = 0.0, t1 = 1.0 }
"""


def test_cli_run_writes_tendon_tensions(tmp_path):
    path = tmp_path / "tendon.toml"
    path.write_text(CLI_SCENE)
    out = tmp_path / "out.json"
    proc = subprocess.run([sys.executable, "-m", "simsoft_jax.cli", "run", str(path), "-o",
                           str(out)], capture_output=True, text=True, timeout=300,
                          cwd=REPO_ROOT)
    assert proc.returncode == 0, proc.stderr
    d = json.loads(out.read_text())
    assert d["tendons"] == {"t1": {"tension": 20.0}}
    np.testing.assert_allclose(d["rods"]["arm"]["positions"],
                               arc(0.5, 6, 20.0 * 0.01 / EI, -20.0 / EA), rtol=0, atol=1e-10)


@pytest.mark.slow
def test_dynamic_result_reports_the_tension_time_law():
    scene = rod_scene(2, tendons=[{"name": "t1", "rod": "arm", "offset": [0.0, 0.01],
                                   "tension": 4.0,
                                   "profile": {"kind": "ramp", "t0": 0.0, "t1": 0.05}}])
    scene["solver"] = {"kind": "dynamic", "dt": 0.01, "t_end": 0.08}
    result = sj.run(scene)
    assert result.converged
    np.testing.assert_allclose(result.tendon_tension("t1"),
                               4.0 * np.clip(result.time / 0.05, 0.0, 1.0), rtol=0, atol=1e-14)
    assert result.to_dict()["tendons"]["t1"]["tension"] == pytest.approx(
        list(4.0 * np.clip(result.time / 0.05, 0.0, 1.0)), abs=1e-14)
    with pytest.raises(ValueError, match="no tendon named 'x'"):
        result.tendon_tension("x")


# ---------------------------------------------------------------------- bad inputs

TENDON = {"name": "t1", "rod": "arm", "from_node": 0, "to_node": -1, "offset": [0.0, 0.01],
          "tension": 1.0}
CHAMBER = {"name": "c1", "rod": "arm", "area": 1e-4, "offset": [0.0, 0.01], "pressure": 1e3}


@pytest.mark.parametrize("key, change, path", [
    ("tendons", {"rod": "leg"}, r"tendons\[0\]\.rod: no rod named 'leg'"),
    ("tendons", {"from_node": 3, "to_node": 2}, r"tendons\[0\]\.to_node: must come after"),
    ("tendons", {"to_node": 9}, r"tendons\[0\]\.to_node: out of range"),
    ("tendons", {"displacement": -0.01}, r"tendons\[0\]: give exactly one of tension, "
                                         r"displacement"),
    ("tendons", {"tension": -1.0}, r"tendons\[0\]\.tension: must be >= 0"),
    ("tendons", {"offset": [0.0]}, r"tendons\[0\]\.offset: must have 2 entries"),
    ("tendons", {"offset": {"kind": "table", "s": [0.0, 0.2, 0.1], "y": [0, 0, 0],
                            "z": [0, 0, 0]}}, r"tendons\[0\]\.offset\.s: must be strictly"),
    ("tendons", {"offset": {"kind": "table", "s": [0.0, 0.2], "y": [0], "z": [0, 0]}},
     r"tendons\[0\]\.offset\.y: must have as many entries as s"),
    ("tendons", {"offset": {"kind": "helix", "radius": 0.01, "pitch": 0.0}},
     r"tendons\[0\]\.offset\.pitch: must be nonzero"),
    ("tendons", {"offset": {"kind": "helix", "radius": -0.01, "pitch": 0.1}},
     r"tendons\[0\]\.offset\.radius: must be > 0"),
    ("tendons", {"offset": {"kind": "spiral"}}, r"tendons\[0\]\.offset\.kind"),
    ("tendons", {"profile": {"kind": "table", "t": [0.0, 1.0], "scale": [1.0, -1.0]}},
     r"tendons\[0\]\.profile: makes the tension negative"),
    ("tendons", {"friction": 0.1}, r"tendons\[0\]\.friction: unknown key"),
    ("tendons", {"offset": {"radius": 0.01}}, r"tendons\[0\]\.offset\.kind: required"),
    ("chambers", {"area": 0.0}, r"chambers\[0\]\.area: must be > 0"),
    ("chambers", {"rod": "leg"}, r"chambers\[0\]\.rod: no rod named"),
    ("chambers", {"from_node": -1, "to_node": 0}, r"chambers\[0\]\.to_node: must come after"),
    ("chambers", {"pressure": "high"}, r"chambers\[0\]\.pressure"),
])
def test_bad_actuator_input_names_the_key(key, change, path):
    item = dict(TENDON if key == "tendons" else CHAMBER, **change)
    with pytest.raises(ValueError, match=path):
        sj.Scene.from_dict(rod_scene(4, **{key: [item]}))


def test_duplicate_tendon_names_are_refused():
    with pytest.raises(ValueError, match=r"tendons\[1\]\.name: duplicate name 't1'"):
        sj.Scene.from_dict(rod_scene(4, tendons=[TENDON, TENDON]))


def test_dynamic_displacement_control_with_a_welded_body_follows_its_law():
    """A displacement-controlled tendon in a dynamic scene with joints (a body welded at
    the tip): the length change follows its law at every step, to 1e-10 of the rod's
    length, and the tension is reported (the multiplier after the weld's)."""
    item = {k: v for k, v in TENDON.items() if k != "tension"}
    pull = {"kind": "smoothstep", "t0": 0.0, "t1": 0.1}
    scene = rod_scene(4, tendons=[dict(item, displacement=-0.005, profile=pull)],
                      bodies=[{"name": "tip", "mass": 0.1, "position": [0.5, 0.0, 0.0]}],
                      joints=[{"kind": "weld", "a": {"rod": "arm", "node": -1},
                               "b": {"body": "tip"}}])
    scene["solver"] = {"kind": "dynamic", "dt": 0.01, "t_end": 0.1}
    result = sj.run(scene)
    assert result.converged
    change = tendon_length_changes(result)[:, 0]
    x = np.clip(np.asarray(result.time) / 0.1, 0.0, 1.0)
    assert np.abs(change - (-0.005) * (3 * x**2 - 2 * x**3)).max() < 1e-10 * 0.5
    assert result.tendon_tension("t1")[-1] > 0.0
