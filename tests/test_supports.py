"""Supports (issue 17): the hinge constraint and the detection of rigid motions that a
static scene's supports leave free.

Reference for the simply supported beam (length L, force F at mid-span along local z,
carried by EIy and GAz): linear Timoshenko theory, mid-span deflection
F L^3 / (48 EIy) + F L / (4 GAz), end slopes F L^2 / (16 EIy). The helical (constant
strain) element reproduces the end slopes exactly and the bending part of the deflection
with the factor (1 - 1/n^2) for n elements (a midpoint-rule error of the curvature, n
even; the shear part is exact): checked at n = 4 to 1e-9, and the brief's 1e-3 against
the continuum at n = 40 (0.98 / 40^2 = 6.1e-4). The load gives deflections of 1e-6 L,
so geometric nonlinearity (membrane tension of the held ends) is ~1e-8 relative.
"""
import numpy as np
import pytest

import simsoft_jax as sj
from simsoft_jax.model.model import build_model

L, EIY, GAZ, F = 1.0, 2.0, 1e3, 1e-4
BENDING, SHEAR = F * L**3 / (48 * EIY), F * L / (4 * GAZ)


def beam(constraints, n=4, kind="static"):
    solver = {"kind": "static"} if kind == "static" else {"kind": "dynamic", "t_end": 0.1,
                                                          "dt": 0.01}
    return {"solver": solver,
            "rods": [{"name": "b", "elements": n, "geometry": {"kind": "straight", "length": L},
                      "stiffness": {"EA": 1e5, "GAy": GAZ, "GAz": GAZ, "GJ": 1.0, "EIy": EIY,
                                    "EIz": 3.0},
                      "inertia": {"rhoA": 1.0, "rhoJ": 1e-3, "rhoIy": 1e-3, "rhoIz": 1e-3}}],
            "constraints": constraints,
            "loads": [{"kind": "force", "rod": "b", "node": n // 2, "vector": [0, 0, -F]}]}


def hinge(node, axis="y"):
    return {"kind": "hinge", "rod": "b", "node": node, "axis": axis}


def pin(node):
    return {"kind": "pin", "rod": "b", "node": node}


def slope(R):
    """Rotation angle about local y of a frame turned about y only (rad)."""
    return np.arctan2(R[0, 2], R[0, 0])


@pytest.mark.parametrize("constraints", [[hinge(0), hinge(-1)], [hinge(0), pin(-1)]],
                         ids=["hinge-hinge", "hinge-pin"])
def test_simply_supported_beam_four_elements(constraints):
    n = 4
    r = sj.run(beam(constraints, n))
    assert r.converged
    deflection = -r.positions("b")[n // 2, 2]
    assert deflection == pytest.approx(BENDING * (1 - 1 / n**2) + SHEAR, rel=1e-9)
    R = r.rotations("b")
    assert slope(R[0]) == pytest.approx(F * L**2 / (16 * EIY), rel=1e-9)
    assert slope(R[-1]) == pytest.approx(-F * L**2 / (16 * EIY), rel=1e-9)
    np.testing.assert_allclose(r.positions("b")[[0, -1]], [[0, 0, 0], [L, 0, 0]], atol=1e-15)


def test_simply_supported_beam_matches_timoshenko_within_1e_3():
    n = 40
    r = sj.run(beam([hinge(0), hinge(-1)], n))
    assert r.converged
    deflection = -r.positions("b")[n // 2, 2]
    assert abs(deflection / (BENDING + SHEAR) - 1) < 1e-3
    assert deflection == pytest.approx(BENDING * (1 - 1 / n**2) + SHEAR, rel=1e-9)


def test_hinge_masks_hold_all_but_the_axis():
    model = build_model(sj.Scene.from_dict(beam([hinge(0, "y"), hinge(-1, "z")])))
    free = np.asarray(model.structure.free_mask())
    np.testing.assert_array_equal(free[0], [0, 0, 0, 0, 1, 0])
    np.testing.assert_array_equal(free[-1], [0, 0, 0, 0, 0, 1])
    np.testing.assert_array_equal(free[1:-1], 1)


@pytest.mark.parametrize("constraints, words", [
    ([pin(0), pin(-1)],
     "one rigid motion, a rotation about the line through (0.5, 0, 0) m along (1, 0, 0)"),
    ([hinge(0, "x"), hinge(-1, "x")],
     "one rigid motion, a rotation about the line through (0.5, 0, 0) m along (1, 0, 0)"),
    ([hinge(0, "z")], "one rigid motion, a rotation about the line through (0, 0, 0) m "
                      "along (0, 0, 1)"),
    ([pin(2)], "3 rigid motions, e.g. a rotation about the line through (0.5, 0, 0) m"),
    ([], "no support"),
    ([hinge(0, "z"), pin(2)], None),    # the pin holds the rotation about the hinge axis
])
def test_free_rigid_motion_is_named(constraints, words):
    """A static scene may leave rigid motions free (validate accepts it, the solve holds
    the rod by settling springs); the model names them."""
    settling = build_model(sj.Scene.from_dict(beam(constraints))).structure.settling
    if words is None:
        assert settling == ()
    else:
        assert len(settling) == 1 and settling[0][0] == "b"
        assert settling[0][1].startswith(words)


def test_simply_supported_beam_on_two_pins_settles_to_the_hinged_answer():
    """Two pins leave the rotation about the line through them free; the load (dead,
    across the line, on the bent beam) holds it, so the solve converges to the beam's
    answer with hinges, the rotation about the line where it started."""
    n = 4
    r = sj.run(beam([pin(0), pin(-1)], n))
    assert r.converged, r.message
    assert -r.positions("b")[n // 2, 2] == pytest.approx(BENDING * (1 - 1 / n**2) + SHEAR,
                                                         rel=1e-6)
    np.testing.assert_allclose(r.positions("b")[:, 1], 0.0, atol=1e-12)


def test_free_rod_pushed_by_a_force_is_reported_unrestrained():
    """No support and nothing else holding the rod: a point force pushes it away at
    every repeated full-load level, and the solve says so, naming the motion."""
    r = sj.run(beam([]))
    assert not r.converged and r.status == "unrestrained"
    assert r.message.endswith("rod 'b': its supports leave no support (to hold it: a "
                              "clamp, or pins and hinges that hold every motion)")


def test_supports_of_a_rod_given_a_start_shape_are_checked_where_it_starts():
    """Hinges about local x at both ends of a straight rod leave the rotation about the
    rod's line free; started on a sagging arc (``initial.points``), the line through the
    ends is no longer along the end tangents and the same hinges hold every motion."""
    d = beam([hinge(0, "x"), hinge(-1, "x")])
    assert build_model(sj.Scene.from_dict(d)).structure.settling[0][1].startswith(
        "one rigid motion, a rotation about the line through (0.5, 0, 0) m along (1, 0, 0)")
    angle = np.linspace(-0.4, 0.4, 5)
    radius = 0.5 / np.sin(0.4)
    points = np.stack([0.5 + radius * np.sin(angle), 0 * angle,
                       radius * (np.cos(angle) - np.cos(0.4))], axis=1)
    d["rods"][0]["initial"] = {"points": points.tolist()}
    assert build_model(sj.Scene.from_dict(d)).structure.settling == ()


def test_hinged_pendulum_swings_about_its_axis():
    """A stiff rod hanging from a hinge (local y = world y) set swinging with a small
    angular velocity w0: a compound pendulum, theta(t) = (w0 / W) sin(W t) with
    W^2 = (rhoA g L^2 / 2) / (rhoA L^3 / 3 + rhoIy L). At t_end = T/4 (not a multiple of
    dt: the run closes with shorter steps) the tip is at x = -L sin(w0 / W). Bending
    (first frequency ~1400 rad/s against W = 5.4 rad/s: at most (5.4/1400)^2 = 1.5e-5)
    and the scheme's phase error (~1e-4 at 100 steps per quarter period, entering squared
    at the peak of the sine) bound the error well below 1e-4 (measured 1.7e-7)."""
    length, rho_a, rho_iy, g, w0 = 0.5, 0.1, 1e-4, 9.81, 0.01
    omega = np.sqrt(rho_a * g * length**2 / 2 / (rho_a * length**3 / 3 + rho_iy * length))
    t_end = np.pi / (2 * omega)
    d = {"solver": {"kind": "dynamic", "t_end": t_end, "dt": t_end / 100.5, "rho_inf": 1.0},
         "gravity": {"vector": [0.0, 0.0, -g]},
         "rods": [{"name": "p", "elements": 4, "geometry": {"kind": "straight", "length": length},
                   "base": {"rotation": {"axis": [0, 1, 0], "angle_deg": 90.0}},
                   "stiffness": {"EA": 1e6, "GAy": 1e6, "GAz": 1e6, "GJ": 1e3, "EIy": 1e3,
                                 "EIz": 1e3},
                   "inertia": {"rhoA": rho_a, "rhoJ": 2 * rho_iy, "rhoIy": rho_iy,
                               "rhoIz": rho_iy}}],
         "constraints": [{"kind": "hinge", "rod": "p", "node": 0, "axis": "y"}],
         "initial_velocity": [{"rod": "p", "angular": [0.0, w0, 0.0]}]}
    r = sj.run(d)
    assert r.converged and r.time[-1] == t_end
    p, R = r.positions("p"), r.rotations("p")
    tip_x = -length * np.sin(w0 / omega)
    assert abs(p[-1, -1, 0] / tip_x - 1) < 1e-4
    np.testing.assert_allclose(p[:, 0], 0.0, atol=1e-12)            # the hinge holds
    np.testing.assert_allclose(R[:, 0, :, 1], np.tile([0.0, 1.0, 0.0], (len(R), 1)),
                               atol=1e-12)                          # turns about y only
    np.testing.assert_allclose(p[:, -1, 1], 0.0, atol=1e-12)        # stays in the x-z plane
