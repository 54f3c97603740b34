"""Observation files (points at offsets, displacements, rotations and twist, reference
cases, std): exact predictions for a twisted strip, and errors naming file, line, column."""
import numpy as np
import pytest

import simsoft_jax as sj
from simsoft_jax.studies.calibration_groups import parse_groups, predict
from simsoft_jax.studies.measurements import observation_set

L, GJ, C = 0.5, 2.0, 0.04


def twisted(name, torque, elements=4):
    return sj.Scene.from_dict({
        "name": name, "solver": {"kind": "static", "tolerance": 1e-13},
        "rods": [{"name": "strip", "elements": elements,
                  "geometry": {"kind": "straight", "length": L},
                  "stiffness": {"EA": 1e5, "GAy": 1e5, "GAz": 1e5, "GJ": GJ, "EIy": 3.0,
                                "EIz": 50.0},
                  "inertia": {"rhoA": 1.0, "rhoJ": 0.0, "rhoIy": 0.0, "rhoIz": 0.0}}],
        "constraints": [{"kind": "clamp", "rod": "strip", "node": 0}],
        "loads": [{"kind": "moment", "rod": "strip", "node": -1,
                   "vector": [torque, 0.0, 0.0]}]})


HEADER = "scene,rod,node,offset_x,offset_y,offset_z,quantity,value,std,reference\n"


def test_observations_of_a_twisted_strip_are_exact(tmp_path):
    """A torque T on a straight strip twists it uniformly, exactly: ``phi = T L / GJ``. A
    point at the offset (0, c, 0) of the tip section sits at (L, c cos phi, c sin phi);
    relative to a reference case with torque T0 its twist is (T - T0) L / GJ."""
    T, T0 = 3.0, 1.0
    phi, phi0 = T * L / GJ, T0 * L / GJ
    rows = [f"t3,strip,-1,0,{C},0,z,0,1,",
            f"t3,strip,-1,0,{C},0,uz,0,0.001,",
            f"t3,strip,-1,0,{C},0,uy,0,1,",
            "t3,strip,-1,,,,twist,0,1,",
            "t3,strip,2,,,,rx,0,1,",
            "t3,strip,-1,,,,ry,0,1,",
            f"t3,strip,-1,0,{C},0,uz,0,1,t1",
            "t3,strip,-1,,,,twist,0,1,t1",
            f"t3,strip,-1,0,{C},0,y,0,1,t1"]
    (tmp_path / "obs.csv").write_text(HEADER + "\n".join(rows) + "\n")
    obs = observation_set(tmp_path / "obs.csv", [twisted("t3", T), twisted("t1", T0)])
    got = predict(obs, parse_groups("GJ"))
    expected = [C * np.sin(phi), C * np.sin(phi), C * (np.cos(phi) - 1), phi, phi / 2, 0.0,
                C * (np.sin(phi) - np.sin(phi0)), phi - phi0,
                C * (np.cos(phi) - np.cos(phi0))]
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-11)
    # the fitted scale of a group enters as the scaled GJ: twist = T L / (s GJ)
    np.testing.assert_allclose(predict(obs, parse_groups("GJ"), [2.0])[3], phi / 2,
                               rtol=1e-10)


def test_tilt_reads_twist_as_leading_and_trailing_edge_heights_do(tmp_path):
    """A strip pitched down by theta at its clamp (base rotated about y) and twisted by
    phi = T L / GJ: its tip section is ``R_y(theta) R_x(phi)``, so its chord (local y)
    rises by ``asin(sin phi cos theta)`` above the horizontal, which ``tilt_y`` gives,
    while ``twist`` (about the section's own axis) gives phi."""
    T, theta = 3.0, 0.6
    phi = T * L / GJ
    scene = twisted("pitched", T).to_dict()
    scene["rods"][0]["base"] = {"rotation": [0.0, theta, 0.0]}
    scene["loads"][0]["frame"] = "local"          # the torque about the pitched axis
    rows = ["pitched,strip,-1,,,,tilt_y,0,1,", "pitched,strip,-1,,,,twist,0,1,",
            "pitched,strip,-1,,,,tilt_x,0,1,"]
    (tmp_path / "obs.csv").write_text(HEADER + "\n".join(rows) + "\n")
    obs = observation_set(tmp_path / "obs.csv", [sj.Scene.from_dict(scene)])
    got = predict(obs, parse_groups("GJ"))
    np.testing.assert_allclose(got, [np.arcsin(np.sin(phi) * np.cos(theta)), phi, 0.0],
                               rtol=0, atol=1e-11)


@pytest.mark.parametrize("row, match", [
    ("t3,strip,-1,,,,twirl,0,1,", "line 2, column quantity: unknown quantity 'twirl'"),
    ("t3,strip,-1,,,,uz,abc,1,", "line 2, column value: not a number"),
    ("t3,strip,-1,,,,uz,0,-1,", "line 2, column std: must be > 0"),
    ("t3,strip,-1,x,,,uz,0,1,", "line 2, column offset_x: not a number"),
    ("t3,strip,9,,,,uz,0,1,", "line 2, column node: rod 'strip' of scene 't3' has nodes"),
    ("t3,strip,-1,,,,uz,0,1,t9", "line 2, column reference: unknown scene 't9'"),
    ("t3,wing,-1,,,,uz,0,1,", "line 2, column rod: scene 't3' has no rod 'wing'"),
    ("t3,strip,-1,,,,,0,1,", "line 2, column quantity: empty"),
])
def test_bad_observation_rows_name_file_line_and_column(tmp_path, row, match):
    (tmp_path / "obs.csv").write_text(HEADER + row + "\n")
    with pytest.raises(ValueError, match="obs.csv " + match):
        observation_set(tmp_path / "obs.csv", [twisted("t3", 1.0)])


def test_group_specs():
    g = parse_groups("EIy@seg0-5=0.5:2, GJ@wing:-2--1,E")
    assert [(x.param, x.rod, x.first, x.last, x.bounds) for x in g] == [
        ("EIy", None, 0, 5, (0.5, 2.0)), ("GJ", "wing", -2, -1, None),
        ("E", None, None, None, None)]
    for bad, match in (("EIq", "unknown parameter 'EIq'"), ("EIy@0-5=2:1", "0 < lo < hi"),
                       ("EIy@a-b", "cannot read group")):
        with pytest.raises(ValueError, match=match):
            parse_groups(bad)
