"""Tendons across rods welded together (``[[tendons]]`` with ``to_rod``; statics).

References, independent of the code's output: a straight tendon at offset r from a rod's
axis, with tension T and terminated beyond, bends that rod into an arc of curvature
``T r / EI`` (per reference arc length) with axial strain ``-T / EA``: the free body
beyond a cut (the rest of the rods, the welds and the tendon) has no external load but
the tendon's pull at the cut, along the rod's tangent. Across a weld the tendon keeps
its tension, so each rod it passes is such an arc with its own offset, a rod it does
not pass stays straight, and each rod starts in the frame its weld carries from the rod
before. The tendon's length change is the sum of the rods' ``L (eps + kappa r)``.
Cases: a Y-branched rod (the trunk and one branch as a straight rod split in two, then
welds that shift and roll the branch), a chain of three rods with the middle one turned
around (displacement control, slow), routes and their errors. Measured: positions agree
with the closed forms to about 1e-13 of the length (asserted 1e-10), the length change
to 1e-12 relative.
"""
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import simsoft_jax as sj
from simsoft_jax.couplings import tendon_lengths
from simsoft_jax.model.model import build_model

EA, GA, GJ, EI = 2e3, 1e3, 0.4, 0.5
STIFFNESS = {"EA": EA, "GAy": GA, "GAz": GA, "GJ": GJ, "EIy": EI, "EIz": EI}
INERTIA = {"rhoA": 0.1, "rhoJ": 1e-4, "rhoIy": 5e-5, "rhoIz": 5e-5}
T, R_OFF, LT, LB = 20.0, 0.01, 0.3, 0.2       # N, m, m (trunk), m (branches)
ALPHA_DOWN = 30.0                            # deg, the lower branch's tilt towards -z


def rod(name, elements, length, position=(0.0, 0.0, 0.0), rotation=(0.0, 0.0, 0.0)):
    """A straight rod from ``position`` along the x axis of the frame ``rotation`` (a
    rotation vector, rad)."""
    return {"name": name, "elements": elements,
            "geometry": {"kind": "straight", "length": length},
            "stiffness": STIFFNESS, "inertia": INERTIA,
            "base": {"position": list(position), "rotation": list(rotation)}}


def Ry(theta):
    c, s = np.cos(theta), np.sin(theta)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def Rx(theta):
    c, s = np.cos(theta), np.sin(theta)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def up_frame(alpha_deg, roll_deg):
    """Reference frame of the upper branch: tilted by alpha towards +z, rolled about its
    own axis."""
    return Ry(-np.radians(alpha_deg)) @ Rx(np.radians(roll_deg))


def up_base(alpha_deg, r_up):
    """Base of the upper branch (m, world): where its tendon point at ``r_up`` along its
    tilted z axis meets the trunk's tendon point ``(LT, 0, r)``."""
    return np.array([LT, 0.0, R_OFF]) - r_up * Ry(-np.radians(alpha_deg))[:, 2]


def y_scene(alpha_deg, r_up, roll_deg, tendon=None):
    """A clamped trunk (along x) with two branches welded to its tip: "up" tilted by
    ``alpha_deg`` towards +z, rolled by ``roll_deg`` about its axis, its base shifted (the
    weld's offset) so that the tendon, at (0, r) in the trunk's section and at ``r_up``
    along the tilted z direction in the branch (``r_up (sin, cos)(roll)`` in its own
    (y, z)), meets itself at the weld; "down" tilted by 30 degrees towards -z, unloaded.
    ``(0, r, 0)``: the trunk and the upper branch are one straight rod split in two,
    welded end to end at coincident nodes."""
    roll = np.radians(roll_deg)
    base = up_base(alpha_deg, r_up)
    tendon = tendon or {"tension": T}
    return {"solver": {"kind": "static", "tolerance": 1e-12},
            "rods": [rod("trunk", 3, LT),
                     rod("up", 2, LB, base,
                         rotation=Rotation.from_matrix(up_frame(alpha_deg, roll_deg)).as_rotvec()),
                     rod("down", 2, LB, (LT, 0.0, 0.0),
                         rotation=np.radians(ALPHA_DOWN) * np.array([0.0, 1.0, 0.0]))],
            "constraints": [{"kind": "clamp", "rod": "trunk", "node": 0}],
            "joints": [{"kind": "weld", "a": {"rod": "trunk", "node": -1,
                                              "offset": list(base - [LT, 0.0, 0.0])},
                        "b": {"rod": "up", "node": 0}},
                       {"kind": "weld", "a": {"rod": "trunk", "node": -1},
                        "b": {"rod": "down", "node": 0}}],
            "tendons": [{"name": "t", "rod": "trunk", "to_rod": "up", "offset": [0.0, R_OFF],
                         "rod_offsets": {"up": [r_up * np.sin(roll), r_up * np.cos(roll)]},
                         **tendon}]}


def arc(length, elements, kappa, eps):
    """Nodes of an arc from the origin along x, turning towards +z (``Ry(-kappa s)``)."""
    s = np.linspace(0.0, length, elements + 1)
    return (1.0 + eps) * np.stack([np.sin(kappa * s) / kappa, 0.0 * s,
                                   (1.0 - np.cos(kappa * s)) / kappa], axis=1)


def length_change(*parts):
    """Closed-form tendon length change (m) over rods ``(length, offset)`` under T."""
    return -T * sum(L * (1.0 / EA + r**2 / EI) for L, r in parts)


@pytest.fixture(scope="module")
def y_structure():
    """The structure every case below shares (weld offsets and frames, routings and
    tensions are model arrays): one compilation."""
    return sj.build_model(sj.Scene.from_dict(y_scene(0.0, R_OFF, 0.0))).structure


CASES = [(0.0, R_OFF, 0.0), (30.0, R_OFF - 0.004, 90.0), (-20.0, 1.6 * R_OFF, 30.0)]


@pytest.mark.parametrize("alpha_deg, r_up, roll_deg", CASES)
def test_tendon_across_a_weld_bends_each_rod_into_its_arc(y_structure, alpha_deg, r_up,
                                                          roll_deg):
    """The trunk bends with curvature T r / EI, the upper branch with ``T r_up / EI``
    from the trunk's tip frame times its own tilt, its base carried by the weld's offset;
    the lower branch stays straight in the trunk's tip frame. For (0, r, 0) trunk and
    upper branch are one arc."""
    model = sj.build_model(sj.Scene.from_dict(y_scene(alpha_deg, r_up, roll_deg)))
    assert model.structure == y_structure                      # no recompilation
    eq = sj.solve_static(model, throw=True)
    p, info = np.asarray(eq.p), {r.name: r for r in model.structure.rods}
    eps, k = -T / EA, T * R_OFF / EI
    trunk = arc(LT, 3, k, eps)
    turn = Ry(-k * LT)                                         # the trunk's tip frame
    up = (trunk[-1] + turn @ (up_base(alpha_deg, r_up) - [LT, 0.0, 0.0])
          + arc(LB, 2, T * r_up / EI, eps) @ (turn @ Ry(-np.radians(alpha_deg))).T)
    down = trunk[-1] + np.outer(np.linspace(0.0, LB, 3),
                                (turn @ Ry(np.radians(ALPHA_DOWN)))[:, 0])
    for name, ref in (("trunk", trunk), ("up", up), ("down", down)):
        first = info[name].first_node
        np.testing.assert_allclose(p[first:first + 3 + (name == "trunk")], ref, rtol=0,
                                   atol=1e-10 * LT)
    if alpha_deg == 0.0:     # the split rod is one arc
        first = info["up"].first_node
        np.testing.assert_allclose(p[[0, 1, 2, 3, first + 1, first + 2]],
                                   arc(LT + LB, 5, k, eps), rtol=0, atol=1e-10 * LT)
    # one tension along the tendon: its length is the sum of its parts in both rods
    change = tendon_lengths.length_changes(model, eq.R, eq.p)
    assert float(change[0]) == pytest.approx(length_change((LT, R_OFF), (LB, r_up)),
                                             rel=1e-10)


# -------------------------------------------------------------------------- routes

def chain(**tendon):
    """Rods a, b, c in a line along x, welded end to end, b turned around (rotated by pi
    about z: its last node at a's tip, its z axis a's): a tendon at (0, r) in every
    section meets itself at both welds."""
    return {"solver": {"kind": "static", "tolerance": 1e-12},
            "rods": [rod("a", 3, 0.3), rod("b", 2, 0.2, (0.5, 0.0, 0.0), (0.0, 0.0, np.pi)),
                     rod("c", 2, 0.2, (0.5, 0.0, 0.0))],
            "constraints": [{"kind": "clamp", "rod": "a", "node": 0}],
            "joints": [{"kind": "weld", "a": {"rod": "a", "node": -1},
                        "b": {"rod": "b", "node": -1}},
                       {"kind": "weld", "a": {"rod": "c", "node": 0},
                        "b": {"rod": "b", "node": 0}}],
            "tendons": [dict({"name": "t", "offset": [0.0, R_OFF]}, **tendon)]}


def test_a_route_through_a_middle_rod_and_its_reverse():
    """From a's node 1 to c's node 1 the tendon passes a's elements 1, 2, both of b's
    (against b's direction) and c's element 0; the reversed route is the same tendon (a
    length has no direction); a routing on c that misses b's at their weld is refused."""
    forward = build_model(sj.Scene.from_dict(chain(rod="a", from_node=1, to_rod="c",
                                                   to_node=1, tension=T)))
    assert forward.structure.tendon_elements == ((False, True, True, True, True, True,
                                                  False),)
    backward = build_model(sj.Scene.from_dict(chain(rod="c", from_node=1, to_rod="a",
                                                    to_node=1, tension=T)))
    assert backward.structure == forward.structure
    np.testing.assert_array_equal(backward.tendon_offset, forward.tendon_offset)
    with pytest.raises(ValueError, match=r"^tendons\[0\]: tendon 't' crosses the weld "
                                         r"joints\[1\] from rod 'b' \(node 0\) to rod 'c' "
                                         r"\(node 0\)"):
        build_model(sj.Scene.from_dict(chain(rod="a", to_rod="c", tension=T,
                                             rod_offsets={"c": [0.0, 2 * R_OFF]})))


@pytest.mark.slow
def test_displacement_control_through_two_welds_solves_one_tension():
    """The chain a - b - c is one straight rod of 0.7 m split in three, b turned around.
    Prescribing the length change of a tendon at (0, r) along all of it, the closed form
    ``-T L (1/EA + r^2/EI)`` of tension T, gives that single T (the three parts share it)
    and one arc of curvature T r / EI through all three rods (b's nodes in reverse)."""
    result = sj.run(chain(rod="a", to_rod="c", displacement=length_change((0.7, R_OFF))),
                    stability=False)
    assert result.converged
    assert result.tendon_tension("t") == pytest.approx(T, rel=1e-10)
    ref = arc(0.7, 7, T * R_OFF / EI, -T / EA)
    for name, nodes in (("a", [0, 1, 2, 3]), ("b", [5, 4, 3]), ("c", [5, 6, 7])):
        np.testing.assert_allclose(result.positions(name), ref[nodes], rtol=0,
                                   atol=1e-10 * 0.7)


# ------------------------------------------------------------------------- errors

def test_routing_points_apart_at_the_weld_are_refused():
    alpha_deg, r_up, roll_deg = CASES[1]
    scene = y_scene(alpha_deg, r_up, roll_deg)
    scene["tendons"][0]["rod_offsets"]["up"] = [0.0, r_up]   # the roll left out
    with pytest.raises(ValueError, match=r"^tendons\[0\]: tendon 't' crosses the weld "
                                         r"joints\[0\] from rod 'trunk' \(node 3\) to rod "
                                         r"'up' \(node 0\), but its routing points there are "
                                         r"0\.0\d+ m apart"):
        build_model(sj.Scene.from_dict(scene))


@pytest.mark.parametrize("change, message", [
    (lambda d: d["joints"][0].update(kind="ball"),
     r"^tendons\[0\]\.to_rod: no path of welds from rod 'trunk' to rod 'up'"),
    (lambda d: d["joints"].append({"kind": "weld", "a": {"rod": "down", "node": -1},
                                   "b": {"rod": "up", "node": -1}}),
     r"^tendons\[0\]\.to_rod: more than one path of welds from rod 'trunk' to rod 'up' "
     r"\(joints\[0\]; joints\[1\] -> joints\[2\]\)"),
    (lambda d: d["tendons"][0].update(to_rod="c"), r"^tendons\[0\]\.to_rod: no rod named 'c'"),
    (lambda d: d["tendons"][0]["rod_offsets"].update(down=[0.0, 0.0]),
     r"^tendons\[0\]\.rod_offsets\.down: rod 'down' is not on the tendon's route "
     r"\(trunk, up\)"),
    (lambda d: d["tendons"][0].pop("offset"),
     r"^tendons\[0\]\.offset: required \(the routing on rod 'trunk'"),
    (lambda d: d["tendons"][0].update(from_node=-1, to_node=0),
     r"^tendons\[0\]\.to_node: the tendon passes no element"),
    (lambda d: d["tendons"][0].update(to_node=3), r"^tendons\[0\]\.to_node: out of range "
                                                  r"for rod 'up' with 3 nodes"),
])
def test_bad_tendon_routes_name_the_key(change, message):
    scene = y_scene(*CASES[1])
    change(scene)
    with pytest.raises(ValueError, match=message):
        sj.Scene.from_dict(scene)
