"""Static solves of rods that contact, friction or the loads hold where their supports do
not (:func:`simsoft_jax.solvers.statics.newton.settling_force`), against closed forms:

* a rope pinned at both ends (its rotation about the line through the pins left free by
  the supports, held by its weight once it sags) against the elastic catenary: a
  perfectly flexible cable of weight ``w`` per unstretched length, axial stiffness EA,
  length L, supports at one height a span S apart, with horizontal tension H and
  vertical reaction ``V = w L / 2``, has at unstretched arc length s
  ``x = H s / EA + (H / w) (asinh((w s - V) / H) + asinh(V / H))`` and
  ``z = (w s^2 / 2 - V s) / EA + (hypot(H, w s - V) - hypot(H, V)) / w``, H from
  ``x(L) = S``. The rope's bending stiffness (EI = 4.9e-4 N m^2 against H ~ 0.4 N) rounds
  the shape over ``sqrt(EI/H) ~ 3 cm`` where the curvature changes; pinned ends carry
  no moment, so the shape differs from the cable by well under a millimetre;
* a rope with no support hanging over a frictionless cylinder (axis y), with equal
  weights W at its ends: symmetric, and the tension of a frictionless string under its
  own weight ``w`` grows with height, ``T = W + w (height above the end)``: on the
  hanging pieces ``T = W + w s`` (s from the end), at the top ``W + w (LH + Rw)``
  less the rope's bending share: where its curvature grows from 0 to ``1/Rw`` its shear
  force ``Q = EI dkappa/ds`` turns into tension, ``dT/ds = -kappa Q`` (the tangential
  balance of an elastica without friction), which lowers the tension on the turn by
  ``EI / (2 Rw^2)`` (0.022 N here);
* the same rope over a rough cylinder (Coulomb mu) with weights W1 > W2, within the
  capstan limit ``T1 / T2 <= exp(mu pi)`` at the points where it leaves the cylinder:
  it holds (its ends move by its stretch only), and the hanging pieces carry
  ``W + w s`` (tested away from where the rope leaves the drum: its bending stiffness
  rounds the turn over ``sqrt(EI/T)``);
* the crossing of two ropes pinned at both ends (the upper one dropped onto the lower
  one, frictionless rod contact, cosseratbench's "crossing" scene and its elastica
  reference): it rests on top, centrelines one diameter apart, its shape within the
  benchmark's best published error.

Tensions are measured from the deformation: ``T = EA (arc / h - 1)`` per element, the
chord turned into its arc ``c (a/2) / sin(a/2)`` with ``a`` the angle between its end
tangents.
"""
import numpy as np
import pytest
from scipy.optimize import brentq

import simsoft_jax as sj

E, RADIUS, DENSITY, G = 1.0e6, 0.005, 1000.0, 9.81
AREA = np.pi * RADIUS**2
EA, W_LINE = E * AREA, DENSITY * AREA * G          # N, N/m


def tensions(R, p, h):
    """Axial force (N) per element from its stretch (module docstring); h (E,) the
    unstretched element lengths."""
    chord = np.linalg.norm(np.diff(p, axis=0), axis=1)
    cos = np.einsum("ni,ni->n", R[:-1, :, 0], R[1:, :, 0])
    half = 0.5 * np.arccos(np.clip(cos, -1.0, 1.0))
    arc = chord * np.where(half > 1e-12, half / np.sin(np.maximum(half, 1e-12)), 1.0)
    return EA * (arc / h - 1.0)


def rope(name, points, elements, length, **extra):
    """A rope (circle section, E, density) started at ``points`` (world, from node 0)."""
    points = np.asarray(points, float)
    return {"name": name, "elements": elements,
            "material": {"E": E, "G": E / 3.0, "density": DENSITY},
            "section": {"shape": "circle", "diameter": 2 * RADIUS},
            "geometry": {"kind": "straight", "length": length},
            "base": {"position": points[0].tolist()},
            "initial": {"points": (points - points[0]).tolist(), **extra}}


def elastic_catenary(s, length, span):
    """(x, z) (m) of the elastic catenary at unstretched arc lengths s (module
    docstring)."""
    w, V = W_LINE, W_LINE * length / 2

    def x(H, s):
        return H * s / EA + H / w * (np.arcsinh((w * s - V) / H) + np.arcsinh(V / H))

    H = brentq(lambda H: x(H, length) - span, 1e-6, 1e6, xtol=1e-14)
    z = (w * s**2 / 2 - V * s) / EA + (np.hypot(H, w * s - V) - np.hypot(H, V)) / w
    return x(H, s), z


def test_rope_pinned_at_both_ends_hangs_as_the_elastic_catenary():
    length, span, n = 1.0, 0.8, 40
    half = brentq(lambda a: np.sin(a) / a - span / length, 1e-6, np.pi - 1e-6)
    radius = length / (2 * half)
    a = np.linspace(-half, half, n + 1)        # a circular arc: equal chords, not the answer
    start = np.stack([span / 2 + radius * np.sin(a), 0 * a,
                      radius * (np.cos(half) - np.cos(a))], axis=1)
    scene = {"solver": {"kind": "static"}, "gravity": {"vector": [0, 0, -G]},
             "rods": [rope("rope", start, n, length)],
             "constraints": [{"kind": "pin", "rod": "rope", "node": k} for k in (0, -1)]}
    model = sj.build_model(sj.Scene.from_dict(scene))
    assert model.structure.settling[0][1].startswith("one rigid motion, a rotation about "
                                                     "the line through (0.4, 0, 0) m")
    r = sj.run(scene)
    assert r.converged, r.message
    p = r.positions("rope")
    x, z = elastic_catenary(np.linspace(0.0, length, n + 1), length, span)
    np.testing.assert_allclose(p[:, 0], x, atol=1e-3)
    np.testing.assert_allclose(p[:, 2], z, atol=1e-3)
    np.testing.assert_allclose(p[:, 1], 0.0, atol=1e-9)     # it stays in its plane
    assert np.abs(p[:, 2] - z).max() < 0.02 * np.abs(z).max()


RC, DEPTH, NH, NA = 0.1, 0.01 * RADIUS, 12, 24     # drum radius, start penetration, elements
RW = RC + RADIUS - DEPTH                            # centreline radius on the drum
H_EL = RW * np.pi / NA                              # element length, m
LH = NH * H_EL                                      # each hanging piece, m


def drum_scene(mu, w1, w2):
    """A rope with no support over the drum (axis y through the origin): a piece hanging
    at x = -RW, the half turn over the top, a piece hanging at x = +RW; weights w1, w2
    (N) at its ends."""
    s = H_EL * np.arange(2 * NH + NA + 1)
    phi = np.clip((s - LH) / RW, 0.0, np.pi)
    below = np.minimum(s - LH, 0.0) + np.maximum(s - LH - RW * np.pi, 0.0)
    points = np.stack([-RW * np.cos(phi), 0 * s, RW * np.sin(phi) - np.abs(below)], axis=1)
    return {"solver": {"kind": "static"}, "gravity": {"vector": [0, 0, -G]},
            "rods": [rope("rope", points, 2 * NH + NA, s[-1])],
            "loads": [{"kind": "force", "rod": "rope", "node": 0, "frame": "world",
                       "vector": [0, 0, -w1]},
                      {"kind": "force", "rod": "rope", "node": -1, "frame": "world",
                       "vector": [0, 0, -w2]}],
            "obstacles": [{"name": "drum", "kind": "cylinder", "axis_point": [0, 0, 0],
                           "axis": [0, 1, 0], "radius": RC, "friction": mu}],
            "contact": {"radius": RADIUS, "stiffness": 1e6, "slip_displacement": 1e-7}}


STRAIGHT = NH - 4    # hanging elements tested: those farther than sqrt(EI/T) ~ 3 cm
#                      from the drum (the rope bends where it leaves it)


def hanging_tension(weight):
    """``W + w s`` at the middle of the hanging elements tested, from the end (N)."""
    return weight + W_LINE * H_EL * (np.arange(STRAIGHT) + 0.5)


def test_rope_over_a_frictionless_drum_with_equal_weights_is_symmetric():
    weight = 0.5
    scene = drum_scene(0.0, weight, weight)
    r = sj.run(scene)
    assert r.converged, r.message
    p, R = r.positions("rope"), r.rotations("rope")
    np.testing.assert_allclose(p[:, 0], -p[::-1, 0], atol=1e-9)
    np.testing.assert_allclose(p[:, 2], p[::-1, 2], atol=1e-9)
    T = tensions(R, p, H_EL)
    np.testing.assert_allclose(T[:STRAIGHT], hanging_tension(weight), rtol=1e-3)
    np.testing.assert_allclose(T[::-1][:STRAIGHT], hanging_tension(weight), rtol=1e-3)
    top = T[NH + NA // 2 - 1:NH + NA // 2 + 1]
    EI = E * np.pi * RADIUS**4 / 4
    np.testing.assert_allclose(top, weight + W_LINE * (LH + RW) - EI / (2 * RW**2), rtol=1e-3)


@pytest.mark.slow     # compiling the contact-with-friction solver: ~40 s on a loaded machine
def test_rope_over_a_rough_drum_within_the_capstan_limit_holds():
    mu, w1, w2 = 0.3, 1.0, 0.5
    T1, T2 = w1 + W_LINE * LH, w2 + W_LINE * LH      # where the rope leaves the drum
    assert T1 / T2 < np.exp(mu * np.pi)              # within the capstan limit
    scene = drum_scene(mu, w1, w2)
    start = np.asarray(sj.build_model(sj.Scene.from_dict(scene)).p0)
    r = sj.run(scene)
    assert r.converged, r.message
    p, R = r.positions("rope"), r.rotations("rope")
    T = tensions(R, p, H_EL)
    np.testing.assert_allclose(T[:STRAIGHT], hanging_tension(w1), rtol=1e-3)
    np.testing.assert_allclose(T[::-1][:STRAIGHT], hanging_tension(w2), rtol=1e-3)
    # held: the ends move by the rope's stretch (< (T1 / EA) of its length), no slide
    assert np.linalg.norm(p - start, axis=1).max() < 2 * T1 / EA * (2 * LH + np.pi * RW)


@pytest.mark.slow     # compiling the rod-contact solver: ~60 s on a loaded 2-core machine
def test_crossing_rope_dropped_statically_rests_on_top():
    crossing = pytest.importorskip("cosseratbench.experiments.crossing")
    from cosseratbench.metrics import max_distance_to_curve
    from simsoft_jax.apps.cosseratbench_solver import scene_dict
    n = 50
    scenario = crossing.build(1e6, 0.1)
    scene = scene_dict(scenario, n)       # static, ropes pinned at both ends
    r = sj.run(scene)
    assert r.converged, r.message
    lower, upper = r.positions("rod0"), r.positions("rod1")
    apart = upper[n // 2, 2] - lower[n // 2, 2]     # the crossing (both middle nodes)
    assert 0.98 * 2 * crossing.RADIUS < apart <= 2 * crossing.RADIUS
    curves = crossing.reference_curves(scenario)
    error = max(max_distance_to_curve(x, c) for x, c in zip((lower, upper), curves))
    assert error / crossing.LENGTH < 7.8e-4     # PyElastica's, the better published one
