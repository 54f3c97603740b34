"""Displacement-controlled tendons and rod-rod contact composed with the other couplings
in dynamics (joints, sliding drives, each other), checked against equivalences, a
closed form (a constraint held to its law), symmetry and central finite differences.

References: a rod chain welded end to end is one rod (same nodes, same tendon route); a
displacement-controlled tendon is a tension-controlled one driven by the tension it
solved (replayed as a table time law, the rod moves the same way: "displacement control
gives the tension that tension control needs for the same shape"); a rod held by a
drive that lets it slide along y, moved along x across a crossing rod, feels no force
along y (the scene is symmetric about the plane y = 0 and the contact is frictionless),
so it moves as the same drive without the slide; derivatives of the differentiable
rollout equal central finite differences.
"""
import jax.numpy as jnp
import numpy as np
import pytest

import simsoft_jax as sj
from conftest import (assert_gradient_equals_central_differences, crossing_rod,
                      tendon_length_changes)

EA, GA, GJ, EI = 2e3, 1e3, 0.4, 0.5
STIFFNESS = {"EA": EA, "GAy": GA, "GAz": GA, "GJ": GJ, "EIy": EI, "EIz": EI}
INERTIA = {"rhoA": 0.1, "rhoJ": 1e-4, "rhoIy": 5e-5, "rhoIz": 5e-5}
L, R_OFF, DELTA, RAMP, DT = 0.5, 0.01, -0.002, 0.2, 0.01
PULL = {"kind": "smoothstep", "t0": 0.0, "t1": RAMP}


def rod(name, length, elements, x0=0.0):
    return {"name": name, "elements": elements, "stiffness": STIFFNESS, "inertia": INERTIA,
            "geometry": {"kind": "straight", "length": length},
            "base": {"position": [x0, 0.0, 0.0]}}


def slide_x(rod_name):
    """A drive at the rod's first node holding its rotation and the position normal to x,
    free to slide along x."""
    return {"kind": "drive", "rod": rod_name, "node": 0, "times": [0.0, 1.0],
            "displacement": [[0, 0, 0], [0, 0, 0]], "rotation": [[0, 0, 0], [0, 0, 0]],
            "slides_along": [1.0, 0.0, 0.0]}


def tendon_scene(welded=False, sliding=False, replay=None, t_end=0.3):
    """A straight rod (6 elements, or two rods of 3 welded end to end) with a straight
    tendon "t" from its base to its tip at offset R_OFF, shortened by |DELTA| over RAMP s;
    its base clamped or on a drive sliding along x. ``replay``: the scales (T,) at the
    saved times of a tension-controlled tendon "r" of 1 N (a table law) on the same
    route."""
    if welded:
        rods = [rod("a", L / 2, 3), rod("b", L / 2, 3, x0=L / 2)]
        joints = [{"kind": "weld", "a": {"rod": "a", "node": -1}, "b": {"rod": "b", "node": 0}}]
        route = {"rod": "a", "to_rod": "b"}
    else:
        rods, joints, route = [rod("a", L, 6)], [], {"rod": "a"}
    tendons = [dict(name="t", offset=[0.0, R_OFF], displacement=DELTA, profile=PULL, **route)]
    if replay is not None:
        times = np.linspace(0.0, t_end, len(replay))
        tendons.append(dict(name="r", offset=[0.0, R_OFF], tension=1.0, **route, profile={
            "kind": "table", "t": times.tolist(), "scale": list(map(float, replay))}))
    return {"solver": {"kind": "dynamic", "dt": DT, "t_end": t_end, "rho_inf": 0.9},
            "rods": rods, "joints": joints,
            "constraints": [slide_x("a") if sliding else
                            {"kind": "clamp", "rod": "a", "node": 0}],
            "tendons": tendons}


# the tendon pulled on a rod sliding along x and its tension-controlled replay share one
# structure (the replay's tendon "r" at zero in the pull): one compiled rollout for both
SLID_SAMPLES = 31                    # saved times of tendon_scene's 0.3 s at DT


def route_positions(result, welded):
    """Node positions (T, 7, 3) along the route, the weld's node once."""
    if not welded:
        return result.positions("a")
    return np.concatenate([result.positions("a"), result.positions("b")[:, 1:]], axis=1)


def length_changes(result):
    """The first tendon's length change (T,), m, along ``result``'s rollout."""
    return tendon_length_changes(result)[:, 0]


def law(t):
    x = np.clip(np.asarray(t) / RAMP, 0.0, 1.0)
    return DELTA * (3 * x**2 - 2 * x**3)


def test_displaced_tendon_across_a_weld_equals_the_tendon_on_one_rod():
    """Joints and a displacement-controlled tendon: the welded pair moves as the one rod
    and solves the same tension, and the length follows its law."""
    pair, one = sj.run(tendon_scene(welded=True)), sj.run(tendon_scene())
    assert pair.converged and one.converged
    a, b = route_positions(pair, True), route_positions(one, False)
    scale = np.abs(b - b[:1]).max()
    assert scale > 1e-3
    np.testing.assert_allclose(a, b, atol=1e-7 * scale)
    tension = one.tendon_tension("t")
    assert tension.max() > 1.0
    np.testing.assert_allclose(pair.tendon_tension("t"), tension, atol=1e-7 * tension.max())
    assert np.abs(length_changes(pair) - law(pair.time)).max() < 1e-10 * L


@pytest.fixture(scope="module")
def slid():
    """The tendon pulled on a rod whose base slides along x (the replay's tendon at zero)."""
    result = sj.run(tendon_scene(sliding=True, replay=np.zeros(SLID_SAMPLES)))
    assert result.converged
    return result


@pytest.mark.slow   # in the lane of the gradient below, which reuses this rollout's program
def test_displaced_tendon_on_a_sliding_drive_holds_its_length_and_slides(slid):
    """The length change follows its law, the base slides (the tendon shortens the rod,
    no force holds it along x) and stays on its line (y = z = 0)."""
    t = np.asarray(slid.time)
    assert np.abs(length_changes(slid) - law(t)).max() < 1e-10 * L
    base = slid.positions("a")[:, 0]
    assert np.abs(base[:, 0]).max() > 1e-5
    assert np.abs(base[:, 1:]).max() < 1e-12


@pytest.mark.slow   # with the test above
# t's tension in the replay is zero up to round-off; a negative round-off is reported as slack
@pytest.mark.filterwarnings("ignore:tendon 't' would have to push")
def test_tension_control_with_the_solved_tensions_slides_the_rod_the_same_way(slid):
    """The tension-controlled tendon "r" driven by the tensions "t" solved, on the same
    route, with "t" still holding its law: "r" pulls the rod as "t" did, so "t" carries no
    tension (within the solver's tolerance) and the rod slides the same way."""
    t = np.asarray(slid.time)
    np.testing.assert_allclose(t, np.linspace(0.0, 0.3, SLID_SAMPLES), rtol=0, atol=1e-12)
    assert np.all(slid.tendon_tension("r") == 0.0)
    tension = slid.tendon_tension("t")
    assert tension.max() > 1.0
    replay = sj.run(tendon_scene(sliding=True, replay=tension))
    assert replay.converged
    np.testing.assert_allclose(replay.tendon_tension("r"), tension, rtol=0,
                               atol=1e-12 * tension.max())
    np.testing.assert_allclose(replay.tendon_tension("t"), 0.0, atol=1e-7 * tension.max())
    np.testing.assert_allclose(replay.positions("a"), slid.positions("a"), atol=2e-8 * L)


@pytest.mark.slow   # the differentiable rollout's compile
def test_gradient_through_a_displaced_tendon_on_a_sliding_drive_equals_finite_differences():
    model = sj.build_model(sj.Scene.from_dict(tendon_scene(sliding=True,
                                                         replay=np.zeros(SLID_SAMPLES))))
    settings = sj.DynamicSettings(dt=DT, steps=8, rho_inf=0.9)

    def tip(theta):
        m = model.replace(tendon_displacement=model.tendon_displacement * theta[0],
                          stiffness=model.stiffness * theta[1])
        p = sj.simulate(m, settings, differentiable=True).p
        return (p[-1, -1] + p[-1, 0]) @ jnp.array([1.0, 2.0, -1.0])

    assert_gradient_equals_central_differences(tip, [1.0, 1.0])


# ------------------------------------------------ rod-rod contact with the other couplings

N_TOP, L_TOP, R_C = 4, 0.2, 0.005


def on_a_crossing_rod(base, t_end=0.03, tip_force=(0.0, 0.0, -2.0), tendons=None):
    """A rod along x (node 0 held by ``base``) pressed by a tip force onto a rod along y
    clamped at both ends, crossing its middle; ``tendons``: name -> control of tendons
    on the upper rod, all on one straight route below its axis."""
    from simsoft_jax.physics.terms.contact import SMOOTHING
    z = 2 * R_C - SMOOTHING * 2 * R_C      # a smoothing width into the contact
    return {"solver": {"kind": "dynamic", "dt": 0.005, "t_end": t_end, "rho_inf": 0.8},
            "rods": [crossing_rod("a", -L_TOP / 2, L_TOP, N_TOP, z=z),
                     crossing_rod("bottom", -L_TOP / 2, L_TOP, N_TOP, along_y=True)],
            "constraints": [dict(base, rod="a", node=0)]
                           + [{"kind": "clamp", "rod": "bottom", "node": n} for n in (0, -1)],
            "loads": [{"kind": "force", "rod": "a", "node": -1, "vector": list(tip_force)}],
            "tendons": [dict(name=name, rod="a", offset=[0.0, -R_C], **control)
                        for name, control in (tendons or {}).items()],
            "contact": {"radius": R_C, "self": True, "max_pairs": 6,
                        "quadrature_points": 4}}


def carried(slides):
    """A drive that carries the rod 0.03 m along x in 0.05 s (holding its rotation),
    sliding along y or not."""
    drive = {"kind": "drive", "times": [0.0, 0.05],
             "displacement": [[0, 0, 0], [0.03, 0, 0]], "rotation": [[0, 0, 0], [0, 0, 0]]}
    return dict(drive, slides_along=[0.0, 1.0, 0.0]) if slides else drive


def middle_height(result):
    """The upper rod's height above the lower one where they cross (T,), m: the upper
    rod's z interpolated at x = 0, minus the lower rod's middle node's z."""
    pa = result.positions("a")
    z = np.array([np.interp(0.0, p[:, 0], p[:, 2]) for p in pa])
    return z - result.positions("bottom")[:, N_TOP // 2, 2]


@pytest.mark.slow   # in the lane of the gradient below, which reuses this rollout's program
def test_rod_carried_across_a_crossing_rod_on_a_sliding_drive_equals_the_plain_drive():
    """Rod-rod contact and a sliding drive: slid along y, moved along x across the lower
    rod, the rod feels no force along y (symmetry, no friction): it moves as on the same
    drive without the slide, and the contact holds it above the lower rod."""
    slid = sj.run(on_a_crossing_rod(carried(True), t_end=0.05))
    held = sj.run(on_a_crossing_rod(carried(False), t_end=0.05))
    assert slid.converged and held.converged
    for name in ("a", "bottom"):
        np.testing.assert_allclose(slid.positions(name), held.positions(name), atol=1e-9)
    assert np.abs(slid.positions("a")[-1, 0, 0] - (-L_TOP / 2 + 0.03)) < 1e-12
    assert np.all(middle_height(slid) > 1.5 * R_C)


@pytest.mark.slow   # the differentiable rollout's compile
def test_gradient_through_rod_contact_on_a_sliding_drive_equals_finite_differences():
    """Rod-rod contact with a drive sliding along the rod's axis: the contact's normal
    leans as the rod bends, so the rod slides; the rollout's derivative in the tip force
    and the stiffness equals central finite differences."""
    model = sj.build_model(sj.Scene.from_dict(on_a_crossing_rod(slide_x("a"))))
    settings = sj.DynamicSettings(dt=0.005, steps=6, rho_inf=0.8)

    def tip(theta):
        m = model.replace(nodal_dead=model.nodal_dead * theta[0],
                          stiffness=model.stiffness * theta[1])
        p = sj.simulate(m, settings, differentiable=True).p
        return (p[-1, N_TOP] + 10.0 * p[-1, 0]) @ jnp.array([1.0, 2.0, -1.0])

    assert_gradient_equals_central_differences(tip, [1.0, 1.0])


# d's tension in the replay is zero up to round-off; a negative round-off is reported as slack
@pytest.mark.filterwarnings("ignore:tendon 'd' would have to push")
def test_displaced_tendon_pulls_a_rod_onto_a_crossing_rod_as_its_tension_does():
    """Rod-rod contact and a displacement-controlled tendon: the tendon "d" (below the axis)
    curls the rod down onto the lower rod; its length follows the law, the contact holds
    the rod above the lower one, and tension control with the solved tensions moves both
    rods the same way. The tension-controlled tendon "t" runs on the same route in the same
    scene (one structure: one compiled rollout for both runs), its table law at zero in the
    pull and at d's solved tensions in the replay, where d still holds its law: t then
    pulls the rod as d did, so d carries no tension (within the solver's tolerance) and
    the rods move as in the pull."""
    T = np.linspace(0.0, 0.04, 9)                         # the saved times (dt = 5 ms)

    def scene(scale):
        return on_a_crossing_rod({"kind": "clamp"}, t_end=0.04, tip_force=(0, 0, 0), tendons={
            "d": {"displacement": -2e-4,
                  "profile": {"kind": "smoothstep", "t0": 0.0, "t1": 0.03}},
            "t": {"tension": 1.0, "profile": {"kind": "table", "t": T.tolist(),
                                              "scale": list(scale)}}})

    pulled = sj.run(scene(np.zeros_like(T)))
    assert pulled.converged
    t = np.asarray(pulled.time)
    np.testing.assert_allclose(t, T, rtol=0, atol=1e-12)
    x = np.clip(t / 0.03, 0.0, 1.0)
    assert np.abs(length_changes(pulled) - (-2e-4) * (3 * x**2 - 2 * x**3)).max() < 1e-10 * L_TOP
    assert np.all(pulled.tendon_tension("t") == 0.0)
    tension = pulled.tendon_tension("d")
    assert tension.max() > 0.0
    force = pulled.contacts["rods"]["normal_force"]
    assert np.max(force) > 0.0                         # the rods do touch
    assert np.all(middle_height(pulled) > 1.5 * R_C)
    replay = sj.run(scene(tension))
    assert replay.converged
    np.testing.assert_allclose(replay.tendon_tension("t"), tension, rtol=0,
                               atol=1e-12 * tension.max())
    np.testing.assert_allclose(replay.tendon_tension("d"), 0.0, atol=1e-7 * tension.max())
    for name in ("a", "bottom"):
        np.testing.assert_allclose(replay.positions(name), pulled.positions(name),
                                   atol=2e-8 * L_TOP)
