"""Start rotations of rods started from ``initial.points`` alone, relaxed into moment
balance with the positions held (simsoft_jax.model.start_balance, docs/scene-format.md
``initial``).

References, independent of the relaxation:
* an arc rod given its own stress-free node positions: the stress-free frames are in
  balance there (zero strain, no load), and the balance is unique near the chord frames,
  so the relaxed frames are the stress-free ones; the chord frames are not (at the ends
  the one-sided chord is off the arc's tangent by half an element's angle);
* a slack rope pinned at both ends under gravity: the moment rows of the static residual
  (spec S47/S70, algorithm.md) vanish at the relaxed frames, and the same rope given those
  frames as ``initial.rotations`` starts in the same state (the equivalence the docs state).
"""
import jax
import numpy as np
import pytest
from scipy.optimize import brentq

import simsoft_jax as sj
from simsoft_jax.physics.assembly import residual
from simsoft_jax.solvers.dynamics import DynamicSettings, simulate
from simsoft_jax.scene.start_frames import initial_frames, world_frames

LENGTH, CHORD = 1.0, 0.8


def arc_scene(initial=None, gravity=False):
    """A quarter arc (radius 0.3 m, 12 elements) pinned at its base (a clamp would hold
    the base node's start frame as given), without or with gravity."""
    rod = {"name": "arc", "elements": 12,
           "material": {"E": 1e6, "G": 1e6 / 3.0, "density": 1000.0},
           "section": {"shape": "circle", "diameter": 0.01},
           "geometry": {"kind": "arc", "radius": 0.3, "angle_deg": 90.0}}
    if initial is not None:
        rod["initial"] = initial
    return {"name": "arc", "rods": [rod],
            **({"gravity": {"vector": [0.0, 0.0, -9.81]}} if gravity else {}),
            "constraints": [{"kind": "pin", "rod": "arc", "node": 0}],
            "solver": {"kind": "dynamic", "dt": 1e-3, "t_end": 0.01}}


def test_arc_from_its_own_points_starts_in_its_stress_free_frames():
    ref = sj.build_model(sj.Scene.from_dict(arc_scene()))
    scene = sj.Scene.from_dict(arc_scene({"points": np.asarray(ref.p0).tolist()}))
    model = sj.build_model(scene)
    R_ref = np.asarray(ref.R0)
    chord, _ = initial_frames(scene.rods[0], *world_frames(scene.rods[0]))
    half_element = np.deg2rad(90.0 / 12) / 2
    tip = np.arccos(np.clip(chord[-1][:, 0] @ R_ref[-1][:, 0], -1.0, 1.0))
    np.testing.assert_allclose(tip, half_element, rtol=1e-6)    # the chord frame is off
    np.testing.assert_allclose(np.asarray(model.R0), R_ref, rtol=0, atol=1e-10)
    np.testing.assert_array_equal(np.asarray(model.p0), np.asarray(ref.p0))


@pytest.mark.slow
def test_arc_released_from_its_own_points_moves_as_from_its_stress_free_shape():
    """Released under gravity at dt = 10 ms: whole steps (from the chord frames every step
    was halved 2-5 times) and the motion of the same arc started in its stress-free shape
    (up to the start's balance under gravity: the stress-free frames are not quite in it)."""
    settings = DynamicSettings(dt=0.01, steps=10)
    ref_model = sj.build_model(sj.Scene.from_dict(arc_scene(gravity=True)))
    ref = simulate(ref_model, settings)
    model = sj.build_model(sj.Scene.from_dict(arc_scene(
        {"points": np.asarray(ref_model.p0).tolist()}, gravity=True)))
    run = simulate(model, settings)
    assert bool(run.converged) and np.all(np.asarray(run.substeps) == 1)
    motion = np.abs(np.asarray(ref.p) - np.asarray(ref.p)[0]).max()
    assert motion > 0.02                                   # m: the arc swings down
    np.testing.assert_allclose(np.asarray(run.p), np.asarray(ref.p), rtol=0,
                               atol=1e-3 * motion)


def slack_rope(rotations=None) -> sj.Model:
    """A soft rope (E = 1 MPa, radius 5 mm, 1 m, 50 elements) pinned at both ends 0.8 m
    apart under gravity, its points on a circular arc (frames not given: chord frames)."""
    theta = brentq(lambda t: 2.0 * np.sin(t / 2.0) / t - CHORD / LENGTH, 1e-6, 6.0)
    phi = np.linspace(-theta / 2.0, theta / 2.0, 51)
    radius = LENGTH / theta
    points = np.stack([radius * np.sin(phi), 0.0 * phi,
                       radius * (np.cos(theta / 2.0) - np.cos(phi))], axis=1)
    initial = {"points": (points - points[0]).tolist()}
    if rotations is not None:
        initial["rotations"] = np.asarray(rotations).tolist()
    scene = {"name": "slack", "gravity": {"vector": [0.0, 0.0, -9.81]},
             "rods": [{"name": "rope", "elements": 50,
                       "material": {"E": 1e6, "G": 1e6 / 3.0, "density": 1000.0},
                       "section": {"shape": "circle", "diameter": 0.01},
                       "geometry": {"kind": "straight", "length": LENGTH},
                       "initial": initial}],
             "constraints": [{"kind": "pin", "rod": "rope", "node": 0},
                             {"kind": "pin", "rod": "rope", "node": -1}],
             "solver": {"kind": "dynamic", "dt": 0.04, "t_end": 0.4}}
    return sj.Scene.from_dict(scene)


def test_slack_rope_starts_with_moment_rows_zero_and_given_rotations_are_the_same_start():
    scene = slack_rope()
    model = sj.build_model(scene)
    chord, points = initial_frames(scene.rods[0], *world_frames(scene.rods[0]))
    np.testing.assert_array_equal(np.asarray(model.p0), points)          # positions held
    static_residual = jax.jit(residual)
    before = np.linalg.norm(np.asarray(static_residual(model, chord, points))[:, 3:])
    after = np.linalg.norm(np.asarray(static_residual(model, model.R0, model.p0))[:, 3:])
    assert before > 1e-4                      # N m: the chord frames are out of balance
    assert after < 1e-10 * before
    turned = np.einsum("nji,njk->nik", chord, np.asarray(model.R0))
    angles = np.arccos(np.clip((np.trace(turned, axis1=1, axis2=2) - 1.0) / 2.0, -1, 1))
    assert 1e-3 < angles.max() < 0.1          # rad: a small turn from the chord frames
    given = sj.build_model(slack_rope(rotations=np.asarray(model.R0)))
    np.testing.assert_allclose(np.asarray(given.R0), np.asarray(model.R0), rtol=0,
                               atol=1e-14)
    np.testing.assert_array_equal(np.asarray(given.p0), np.asarray(model.p0))
