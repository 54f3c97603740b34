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
from simsoft_jax.model import build_model

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


@pytest.mark.parametrize("constraints, count, motion", [
    ([pin(0), pin(-1)], "one rigid motion,",
     "a rotation about the line through (0.5, 0, 0) m along (1, 0, 0)"),
    ([hinge(0, "x"), hinge(-1, "x")], "one rigid motion,",
     "a rotation about the line through (0.5, 0, 0) m along (1, 0, 0)"),
    ([hinge(0, "z")], "one rigid motion,",
     "a rotation about the line through (0, 0, 0) m along (0, 0, 1)"),
    ([pin(2)], "3 rigid motions, e.g.", "a rotation about the line through (0.5, 0, 0) m"),
])
def test_free_rigid_motion_is_named(constraints, count, motion):
    with pytest.raises(ValueError) as err:
        sj.Scene.from_dict(beam(constraints))
    text = str(err.value)
    assert text.startswith("constraints: rod 'b' (rods[0]) is free to move as a rigid body: "
                           f"its supports leave {count} {motion}")
    if count.startswith("one"):
        assert text.endswith("replace a pin by a hinge whose axis is not along that line "
                             "(kind = \"hinge\", e.g. axis = \"y\" or \"z\" where the rod runs "
                             "along local x), or by a clamp")


def test_unsupported_rod_and_accepted_supports():
    with pytest.raises(ValueError, match=r"^constraints: rod 'b' \(rods\[0\]\) has no support"):
        sj.Scene.from_dict(beam([]))
    # a hinge about z holds the twist, a pin elsewhere the rotation about the hinge axis
    sj.Scene.from_dict(beam([hinge(0, "z"), pin(2)]))
    sj.Scene.from_dict(beam([pin(0), pin(-1)], kind="dynamic"))   # dynamics may leave it free


def test_build_model_checks_the_start_configuration():
    """Scene.replace skips validation; build_model checks the supports again."""
    good = sj.Scene.from_dict(beam([hinge(0), hinge(-1)]))
    two_pins = good.replace(constraints=sj.Scene.from_dict(
        beam([pin(0), pin(-1)], kind="dynamic")).constraints)
    with pytest.raises(ValueError, match=r"^constraints: rod 'b' \(rods\[0\]\) is free to move"):
        build_model(two_pins)
