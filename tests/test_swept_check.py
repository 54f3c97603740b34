"""The swept check of an update (:mod:`simsoft_jax.solvers.swept_check`): a Newton update or
a load-continuation prediction that would carry a rod through another rod or through an
obstacle is cut back. References are the geometry itself: two straight rods crossing at
right angles (top along x at height z, bottom along y at 0, contact radius r each) pass
through each other exactly when the top one goes from z > r to z < r (its centreline
closer than one radius to the other's, or beyond it), wherever the crossing lies on the
chords (at a node or inside an element); a node crosses a plane's surface when its
signed height goes from > 0 to < 0.
"""
import jax.numpy as jnp
import numpy as np
import pytest

from simsoft_jax.model.model import build_model
from simsoft_jax.scene.scene import Scene
from simsoft_jax.solvers import swept_check

N, L, R_C = 4, 0.2, 0.005


def _rod(name, along_y, z, shift=0.0):
    return {"name": name, "elements": N, "geometry": {"kind": "straight", "length": L},
            "base": {"position": [shift, -L / 2, z] if along_y else [-L / 2, shift, z],
                     "rotation": [0.0, 0.0, np.pi / 2 if along_y else 0.0]},
            "stiffness": {"EA": 1e7, "GAy": 1e7, "GAz": 1e7, "GJ": 1.0, "EIy": 1.0,
                          "EIz": 1.0},
            "inertia": {"rhoA": 1.0, "rhoJ": 1e-6, "rhoIy": 1e-6, "rhoIz": 1e-6}}


def _model(shift=0.0, obstacle=False):
    scene = {"solver": {"kind": "dynamic", "t_end": 0.1, "dt": 0.01},
             "rods": [_rod("top", False, 0.0, shift), _rod("bottom", True, 0.0, shift)],
             "contact": {"radius": R_C, "self": not obstacle}}
    if obstacle:
        scene["rods"] = scene["rods"][:1]
        scene["obstacles"] = [{"name": "floor", "kind": "plane", "point": [0, 0, -0.01],
                               "normal": [0, 0, 1]}]
    return build_model(Scene.from_dict(scene))


def _lifted(model, z):
    """Node positions with the top rod (the first N + 1 nodes) at height z (m)."""
    return jnp.asarray(model.p0).at[:N + 1, 2].add(z)


@pytest.mark.parametrize("shift", [0.0, 0.3 * L / N], ids=["at-a-node", "inside-an-element"])
def test_rod_passing_through_another_is_detected_and_cut_back(shift):
    model = _model(shift)
    above = _lifted(model, 3 * R_C)
    for z, passing in ((-3 * R_C, True), (0.5 * R_C, True), (1.5 * R_C, False),
                       (10 * R_C, False)):
        assert bool(swept_check.passes(model, above, _lifted(model, z))) is passing, z
    # moving up is never a pass; nor is a move that starts already closer than r
    assert not bool(swept_check.passes(model, _lifted(model, 0.5 * R_C),
                                       _lifted(model, -3 * R_C)))
    # from z = 3r towards z = -4r: the largest fraction 2^-k that keeps z > r is 1/4
    move = lambda t: _lifted(model, 3 * R_C - t * 7 * R_C)   # noqa: E731
    assert float(swept_check.cut_back(model, above, move, 1.0)) == 0.25


def test_rods_sliding_past_each_other_are_not_a_pass():
    """The top rod moved sideways along the bottom one (and along itself), keeping its
    height above r: no pass, though the crossing moves from one chord pair to another."""
    model = _model()
    above = _lifted(model, 2 * R_C)
    moved = above.at[:N + 1, 1].add(0.7 * L / N).at[:N + 1, 0].add(0.4 * L / N)
    assert not bool(swept_check.passes(model, above, moved))


def test_node_sinking_through_an_obstacle_surface_is_detected():
    model = _model(obstacle=True)
    p = jnp.asarray(model.p0)      # the rod 0.01 m above the floor
    assert bool(swept_check.passes(model, p, p.at[2, 2].add(-0.011)))
    assert not bool(swept_check.passes(model, p, p.at[:, 2].add(-0.009)))
    assert float(swept_check.cut_back(model, p, lambda t: p.at[:, 2].add(-0.05 * t),
                                      1.0)) == 0.125


def test_models_without_contact_are_not_checked():
    scene = {"solver": {"kind": "dynamic", "t_end": 0.1, "dt": 0.01},
             "rods": [_rod("top", False, 0.0), _rod("bottom", True, 0.0)]}
    model = build_model(Scene.from_dict(scene))
    assert not swept_check.checked(model)
    assert swept_check.cut_back(model, model.p0, None, 1.0) == 1.0


@pytest.mark.slow     # compiling the rod-contact dynamics: ~30 s on a loaded 2-core machine
def test_heavy_rope_dropped_dynamically_with_a_large_step_rests_on_top():
    """Two ropes pinned at both ends, crossing at right angles, the upper one (8 times
    denser, so it sags twice as far) starting 4 r above the lower one, under gravity with
    mass damping, stepped at dt = 0.1 s (ten steps per second, against a sag period of
    ~0.4 s): the upper one lands on the lower and stays on top, the centrelines one
    diameter apart at the crossing (less the penetration of the penalty), from the first
    step after the landing on."""
    import simsoft_jax as sj
    r, length, n = 0.005, 0.4, 20

    def rope(name, along_y, z, density):
        return {"name": name, "elements": n,
                "material": {"E": 1e6, "G": 1e6 / 3, "density": density,
                             "mass_damping": 10.0},
                "section": {"shape": "circle", "diameter": 2 * r},
                "geometry": {"kind": "straight", "length": length},
                "base": {"position": [0.0, -length / 2, z] if along_y else
                         [-length / 2, 0.0, z],
                         "rotation": [0.0, 0.0, np.pi / 2 if along_y else 0.0]}}

    scene = {"solver": {"kind": "dynamic", "t_end": 1.0, "dt": 0.1, "rho_inf": 0.0},
             "gravity": {"vector": [0, 0, -9.81]},
             "rods": [rope("lower", False, 0.0, 1000.0), rope("upper", True, 4 * r, 8000.0)],
             "constraints": [{"kind": "pin", "rod": k, "node": i}
                             for k in ("lower", "upper") for i in (0, -1)],
             "contact": {"self": True}}
    result = sj.run(scene)
    assert result.converged, result.message
    apart = (result.positions("upper")[:, n // 2, 2]
             - result.positions("lower")[:, n // 2, 2]) / (2 * r)
    assert np.all(apart > 0.98)                 # never closer, never through
    np.testing.assert_allclose(apart[2:], 1.0, atol=0.01)   # resting on top
