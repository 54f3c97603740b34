"""Validation limits (issue 17): element rotation and length in the stress-free shape,
element counts, static drives, loads placed by arc length on held nodes.

Hand-derived references: an arc of angle phi in n elements turns each element by phi/n; a
helix of radius a and pitch c (b = c / 2 pi) turns each element by
(arc length / n) / sqrt(a^2 + b^2) = 2 pi turns / n; the limit is 90 degrees per element,
so the smallest accepted count is ceil(phi / 90 deg).
"""
import numpy as np
import pytest

from simsoft_jax.scene.scene import MAX_ELEMENTS, Scene


def scene(geometry, elements=4, kind="static", constraints=None, loads=()):
    d = {"solver": {"kind": kind} if kind == "static" else
         {"kind": kind, "t_end": 0.1, "dt": 0.01},
         "rods": [{"name": "r", "material": "spring_steel",
                   "section": {"shape": "circle", "diameter": 1e-3},
                   "elements": elements, "geometry": geometry}],
         "constraints": constraints if constraints is not None else
         [{"kind": "clamp", "rod": "r", "node": 0}],
         "loads": list(loads)}
    return d


ARC270 = {"kind": "arc", "radius": 0.1, "angle_deg": 270.0}
ARC360 = {"kind": "arc", "radius": 0.1, "angle_deg": 360.0}
FLAT_COIL = {"kind": "helix", "radius": 0.05, "pitch": 0.0, "turns": 1.0}
STEEP = {"kind": "helix", "radius": 0.05, "pitch": 0.4, "turns": 1.5}


@pytest.mark.parametrize("geometry, elements, message, enough", [
    (ARC270, 1, "element 0 of 1 turns by 270 degrees", 3),
    (ARC270, 2, "element 0 of 2 turns by 135 degrees", 3),
    (ARC360, 3, "element 0 of 3 turns by 120 degrees", 4),
    (FLAT_COIL, 2, "element 0 of 2 turns by 180 degrees", 4),
    (STEEP, 5, "element 0 of 5 turns by 108 degrees", 6),   # 540 degrees in all
])
def test_element_turn_limit_suggests_the_element_count(geometry, elements, message, enough):
    with pytest.raises(ValueError) as err:
        Scene.from_dict(scene(geometry, elements))
    text = str(err.value)
    assert text.startswith("rods[0].geometry: " + message)
    assert text.endswith(f"more than the limit 90 degrees per element; use elements >= {enough}")
    Scene.from_dict(scene(geometry, enough))            # the suggestion is accepted


def test_zero_length_elements_are_rejected():
    """A polyline folding back on itself in 9 elements of 2/9 m puts nodes 4 and 5 both
    at x = 8/9; in 2 elements node 1 sits on the fold and has no tangent (a turn of 180
    degrees). A full circle in one element is caught by the turn limit first."""
    fold = {"kind": "polyline", "points": [[0, 0, 0], [1, 0, 0], [0, 0, 0]]}
    with pytest.raises(ValueError, match=r"^rods\[0\]\.geometry: element 4 of 9 has zero length"):
        Scene.from_dict(scene(fold, 9))
    with pytest.raises(ValueError, match=r"^rods\[0\]\.geometry: element 0 of 2 turns by 180"):
        Scene.from_dict(scene(fold, 2))
    with pytest.raises(ValueError, match=r"^rods\[0\]\.geometry: element 0 of 1 turns by 360 "
                                         r"degrees.*use elements >= 4$"):
        Scene.from_dict(scene(ARC360, 1))


def test_polyline_corner_turn():
    """A right-angle corner at node 1 of 2: the central-difference tangent there is at
    45 degrees, so both elements turn by 45 degrees (accepted). A corner of
    180 - atan(0.1) = 174.3 degrees in 3 elements of 2.005/3 m: node 1 at (0.668, 0),
    node 2 on the way back; element 1 turns by 168.6 degrees, and the advice is to round
    the corner, since more elements keep a kink."""
    corner = {"kind": "polyline", "points": [[0, 0, 0], [1, 0, 0], [1, 1, 0]]}
    Scene.from_dict(scene(corner, 2))
    back = {"kind": "polyline", "points": [[0, 0, 0], [1, 0, 0], [0, 0.1, 0]]}
    with pytest.raises(ValueError, match=r"^rods\[0\]\.geometry: element 1 of 3 turns by "
                                         r"168.6 degrees.*round its corners with more points"):
        Scene.from_dict(scene(back, 3))


def test_element_count_limit():
    assert MAX_ELEMENTS == 20000
    with pytest.raises(ValueError, match=r"^rods\[0\]\.elements: must be <= 20000"):
        Scene.from_dict(scene({"kind": "straight", "length": 1.0}, 20001))
    d = scene({"kind": "straight", "length": 1.0}, 15000)
    d["rods"].append({**d["rods"][0], "name": "q"})
    d["constraints"].append({"kind": "clamp", "rod": "q", "node": 0})
    with pytest.raises(ValueError, match=r"^rods\[1\]\.elements: the scene's rods have 30000 "
                                         r"elements in all, more than the limit 20000"):
        Scene.from_dict(d)


def test_static_scene_rejects_a_moving_drive():
    drive = {"kind": "drive", "rod": "r", "node": 0, "times": [0.0, 1.0],
             "displacement": [[0, 0, 0], [0, 0, 0.01]]}
    straight = {"kind": "straight", "length": 1.0}
    with pytest.raises(ValueError, match=r"^constraints\[0\]: a static solve cannot follow "
                                         r"a drive's displacement or rotation"):
        Scene.from_dict(scene(straight, constraints=[drive]))
    turning = {**drive, "displacement": [[0, 0, 0]] * 2, "rotation": [[0, 0, 0], [0, 0.1, 0]]}
    with pytest.raises(ValueError, match=r"^constraints\[0\]: a static solve"):
        Scene.from_dict(scene(straight, constraints=[turning]))
    still = {**drive, "displacement": [[0, 0, 0]] * 2}
    assert Scene.from_dict(scene(straight, constraints=[still])).constraints[0].kind == "drive"
    Scene.from_dict(scene(straight, kind="dynamic", constraints=[drive]))


def test_load_by_arc_length_on_a_held_node_is_reported():
    """4 elements of 0.25 m: s = 0 is node 0 (clamped) and the force would vanish;
    s = 0.1 lies inside element 0 and acts there (not rounded); a moment on a pinned
    node acts; a force by s on the pinned tip is rejected."""
    straight = {"kind": "straight", "length": 1.0}
    force = {"kind": "force", "rod": "r", "s": 0.0, "vector": [0, 0, 1.0]}
    with pytest.raises(ValueError, match=r"^loads\[0\]\.s: s = 0.0 is node 0 of rod "
                                         r"'r', which a clamp holds: the force would have no"):
        Scene.from_dict(scene(straight, loads=[force]))
    inside = Scene.from_dict(scene(straight, loads=[{**force, "s": 0.1}])).loads[0]
    assert inside.node is None and inside.element == 0 and inside.xi == pytest.approx(0.4)
    pins = [{"kind": "pin", "rod": "r", "node": 0}, {"kind": "pin", "rod": "r", "node": -1}]
    moment = {"kind": "moment", "rod": "r", "s": 1.0, "vector": [0, 1.0, 0]}
    assert Scene.from_dict(scene(straight, kind="dynamic", constraints=pins,
                                 loads=[moment])).loads[0].node == 4
    with pytest.raises(ValueError, match=r"^loads\[0\]\.s: .* which a pin holds: the force"):
        Scene.from_dict(scene(straight, kind="dynamic", constraints=pins,
                              loads=[{**force, "s": 1.0}]))


@pytest.mark.parametrize("rotation, key, message", [
    ([0.0, 1e300, 0.0], "rods[0].base.rotation", "rotation angle (its length) must be at most 1e+06 rad"),
    ([8e5, 8e5, 0.0], "rods[0].base.rotation", "rotation angle (its length) must be at most 1e+06 rad"),
    ({"axis": [0, 0, 1], "angle_deg": 3e301}, "rods[0].base.rotation.angle_deg",
     "must be at most 5.73e+07 in size"),
])
def test_huge_rotation_angles_are_rejected_by_key(rotation, key, message):
    """Rotation vectors whose length overflows (or has no digits left below one turn)
    used to raise a bare 'math domain error'."""
    d = scene({"kind": "straight", "length": 1.0})
    d["rods"][0]["base"] = {"rotation": rotation}
    with pytest.raises(ValueError) as err:
        Scene.from_dict(d)
    assert str(err.value).startswith(f"{key}: {message}")


def test_rotation_axis_with_huge_components_is_normalised():
    """An axis (1e300, 1e300, 0) is the direction (1, 1, 0)/sqrt(2): a quarter turn about
    it maps x to (1/2, 1/2, -1/sqrt(2))."""
    d = scene({"kind": "straight", "length": 1.0})
    d["rods"][0]["base"] = {"rotation": {"axis": [1e300, 1e300, 0.0], "angle_deg": 90.0}}
    R = Scene.from_dict(d).rods[0].base_rotation
    np.testing.assert_allclose(R[:, 0], [0.5, 0.5, -np.sqrt(0.5)], atol=1e-15)
