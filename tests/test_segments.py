"""Rods whose section changes along the length (``rods[].segments``)."""
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


def test_pure_moment_on_two_sections_gives_two_exact_arcs():
    """A tip moment M gives curvature M/EI_k on each segment (seed eqs. 88-91 per piece):
    the tip rotation is M (L1/EI1 + L2/EI2) and the tip position follows two circular arcs."""
    M = 0.05
    result = sj.run(catheter(M))
    assert result.converged
    ei = [_bending_stiffness(3.48e-3, 2.54e-3), _bending_stiffness(2.13e-3, 1.0e-3)]
    lengths = [0.06, 0.04]
    # exact: planar arcs in x-y (moment about +z bends toward +y)
    angle, position = 0.0, np.zeros(2)
    for L, EI in zip(lengths, ei):
        k = M / EI
        new_angle = angle + k * L
        position = position + np.array([np.sin(new_angle) - np.sin(angle),
                                        np.cos(angle) - np.cos(new_angle)]) / k
        angle = new_angle
    tip = result.positions("cath")[-1]
    assert np.allclose(tip[:2], position, atol=1e-11)
    R_tip = result.rotations("cath")[-1]
    assert np.isclose(np.arctan2(R_tip[1, 0], R_tip[0, 0]), angle, atol=1e-10)


def test_segment_constants_land_on_their_elements():
    model = sj.build_model(sj.Scene.from_dict(catheter()))
    ei = np.asarray(model.stiffness)[:, 4]
    assert np.allclose(ei[:3], _bending_stiffness(3.48e-3, 2.54e-3), rtol=1e-12)
    assert np.allclose(ei[3:], _bending_stiffness(2.13e-3, 1.0e-3), rtol=1e-12)


@pytest.mark.parametrize("changes, path", [
    ({"elements": 4}, "rods[0].elements"),
    ({"segments": []}, "rods[0].segments"),
    ({"segments": [{"section": GUIDE}]}, "rods[0].segments[0].elements"),
    ({"segments": [{"elements": 2}]}, "rods[0].segments[0].section"),
    ({"segments": [{"elements": 2, "section": GUIDE, "colour": 1}]}, "rods[0].segments[0].colour"),
])
def test_bad_segments_name_the_key(changes, path):
    with pytest.raises(ValueError, match=path.replace("[", r"\[").replace("]", r"\]")):
        sj.Scene.from_dict(catheter(**changes))
