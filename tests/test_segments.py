"""Rods whose section changes along the length (``rods[].segments``)."""
import warnings

import numpy as np
import pytest

import simsoft_jax as sj

GUIDE = {"shape": "tube", "outer_diameter": 3.48e-3, "inner_diameter": 2.54e-3}
LEADER = {"shape": "tube", "outer_diameter": 2.13e-3, "inner_diameter": 1.0e-3}


def catheter(moment=0.05, **rod_changes):
    rod = {"name": "cath", "material": "spring_steel",
           "geometry": {"kind": "straight", "length": 0.1},
           "segments": [{"elements": 3, "section": GUIDE}, {"elements": 2, "section": LEADER}]}
    rod.update(rod_changes)
    return {"solver": {"kind": "static"}, "rods": [rod],
            "constraints": [{"kind": "clamp", "rod": "cath", "node": 0}],
            "loads": [{"kind": "moment", "rod": "cath", "node": -1, "vector": [0, 0, moment]}]}


def _bending_stiffness(outer, inner):
    steel = sj.get_material("spring_steel")
    return steel.E * np.pi * (outer**4 - inner**4) / 64.0


def two_arcs(M, lengths, ei):
    """Exact planar tip of a cantilever in pure bending, piece by piece (moment about +z
    bends toward +y): curvature M/EI_k on piece k, arcs joined with a common tangent.
    Returns the tip position (2,) and angle."""
    angle, position = 0.0, np.zeros(2)
    for L, EI in zip(lengths, ei):
        k = M / EI
        new_angle = angle + k * L
        position = position + np.array([np.sin(new_angle) - np.sin(angle),
                                        np.cos(angle) - np.cos(new_angle)]) / k
        angle = new_angle
    return position, angle


EI_GUIDE_LEADER = [_bending_stiffness(3.48e-3, 2.54e-3), _bending_stiffness(2.13e-3, 1.0e-3)]


def assert_tip(result, M, lengths):
    assert result.converged
    position, angle = two_arcs(M, lengths, EI_GUIDE_LEADER)
    assert np.allclose(result.positions("cath")[-1][:2], position, atol=1e-11)
    R_tip = result.rotations("cath")[-1]
    assert np.isclose(np.arctan2(R_tip[1, 0], R_tip[0, 0]), angle, atol=1e-10)


def test_pure_moment_on_two_sections_gives_two_exact_arcs():
    """A tip moment M gives curvature M/EI_k on each segment (seed eqs. 88-91 per piece):
    the tip rotation is M (L1/EI1 + L2/EI2) and the tip position follows two circular arcs."""
    M = 0.05
    assert_tip(sj.run(catheter(M)), M, [0.06, 0.04])


def lengths_catheter(moment=0.05, lengths=(0.07, 0.03)):
    scene = catheter(moment)
    for seg, length in zip(scene["rods"][0]["segments"], lengths):
        seg["length"] = length
    return scene


def test_segment_lengths_put_the_section_change_where_they_say():
    """With ``length`` the guide is 0.07 m (3 elements of 0.0233 m) and the leader 0.03 m
    (2 of 0.015 m): the same five elements now give the exact arcs of those lengths; the
    section change is at s = 0.07, between the nodes of equal elements (0.06 and 0.08)."""
    M = 0.05
    scene = lengths_catheter(M)
    assert_tip(sj.run(scene), M, [0.07, 0.03])
    model = sj.build_model(sj.Scene.from_dict(scene))
    assert np.allclose(np.asarray(model.length), [0.07 / 3] * 3 + [0.015] * 2, rtol=1e-12)
    p0 = np.asarray(model.p0)
    assert np.allclose(p0[:, 0], [0, 0.07 / 3, 0.14 / 3, 0.07, 0.085, 0.1], atol=1e-15)


def test_segment_lengths_place_loads_and_tendons_by_arc_length():
    """Places given by ``s`` follow the unequal nodes: a force at s = 0.08 acts in element
    3 (from 0.07 to 0.085) at xi = 0.01 / 0.015; a helical tendon routing is sampled at the
    arc length of each Gauss point of each element (computed here from the lengths)."""
    scene = lengths_catheter()
    scene["loads"].append({"kind": "force", "rod": "cath", "s": 0.08, "vector": [0, 1e-3, 0]})
    radius, pitch = 1e-3, 0.04
    scene["tendons"] = [{"name": "t", "rod": "cath", "tension": 1.0, "offset": {
        "kind": "helix", "radius": radius, "pitch": pitch, "phase_deg": 0.0}}]
    model = sj.build_model(sj.Scene.from_dict(scene))
    assert np.asarray(model.element_point_xi)[3] == pytest.approx(0.01 / 0.015, rel=1e-12)
    assert np.asarray(model.element_point_dead)[3, 1] == pytest.approx(1e-3)
    nodes = np.array([0, 0.07 / 3, 0.14 / 3, 0.07, 0.085, 0.1])
    offset = np.asarray(model.tendon_offset)[0]                    # (E, Q, 2)
    q = offset.shape[1]
    gauss = 0.5 * (1.0 + np.polynomial.legendre.leggauss(q)[0])
    s = nodes[:-1, None] + gauss[None, :] * np.diff(nodes)[:, None]
    angle = 2 * np.pi * s / pitch
    assert np.allclose(offset, radius * np.stack([np.cos(angle), np.sin(angle)], -1),
                       atol=1e-15)


def test_segment_constants_land_on_their_elements():
    model = sj.build_model(sj.Scene.from_dict(catheter()))
    ei = np.asarray(model.stiffness)[:, 4]
    assert np.allclose(ei[:3], _bending_stiffness(3.48e-3, 2.54e-3), rtol=1e-12)
    assert np.allclose(ei[3:], _bending_stiffness(2.13e-3, 1.0e-3), rtol=1e-12)


def test_a_mass_by_s_between_nodes_warns_and_lengths_put_a_node_there():
    """A mass at s = 0.07 m falls between the nodes of equal elements (0.06, 0.08): it is
    placed on the nearest node with a warning that says how far; with segment lengths
    ending at 0.07 m the mass sits on node 3 exactly, without a warning."""
    mass = {"rod": "cath", "s": 0.07, "mass": 0.01}
    with pytest.warns(UserWarning, match=r"masses\[0\]\.s = 0\.07 m lies between nodes; "
                      r"it is placed at the nearest node 4 \(s = 0\.08 m, 0\.01 m away\)"):
        scene = sj.Scene.from_dict({**catheter(), "masses": [mass]})
    assert scene.masses[0].node == 4
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        scene = sj.Scene.from_dict({**lengths_catheter(), "masses": [mass]})
    assert scene.masses[0].node == 3


@pytest.mark.parametrize("changes, path", [
    ({"elements": 4}, "rods[0].elements"),
    ({"segments": []}, "rods[0].segments"),
    ({"segments": [{"section": GUIDE}]}, "rods[0].segments[0].elements"),
    ({"segments": [{"elements": 2}]}, "rods[0].segments[0].section"),
    ({"segments": [{"elements": 2, "section": GUIDE, "colour": 1}]}, "rods[0].segments[0].colour"),
    ({"segments": [{"elements": 3, "section": GUIDE, "length": 0.07},
                   {"elements": 2, "section": LEADER}]}, "rods[0].segments[1]: give every"),
    ({"segments": [{"elements": 3, "section": GUIDE, "length": 0.07},
                   {"elements": 2, "section": LEADER, "length": 0.04}]},
     "rods[0].segments: the segments' lengths add up to 0.11 m"),
    ({"segments": [{"elements": 3, "section": GUIDE, "length": -0.07},
                   {"elements": 2, "section": LEADER, "length": 0.17}]},
     "rods[0].segments[0].length"),
])
def test_bad_segments_name_the_key(changes, path):
    with pytest.raises(ValueError, match=path.replace("[", r"\[").replace("]", r"\]")):
        sj.Scene.from_dict(catheter(**changes))
