"""Newton globalized for slack, nearly inextensible rods (DynamicSettings.globalized): the
step started from the guess with the smallest residual and kept from overshooting by a
backtracking line search. A slack rope pinned at both ends, released from a horizontal
arc, swings down under gravity; with 40 ms steps the extrapolated guess turns nodes by
radians and Newton from it wanders off, so steps are halved. Globalized, every step is
taken whole, and the motion is the generalized-alpha solution: it follows a run with
steps eight times shorter to the time-discretization error, and the energy does not grow.
"""
import jax
import numpy as np
import pytest
from scipy.optimize import brentq

import simsoft_jax as sj
from simsoft_jax.physics.inertia import line_density
from simsoft_jax.solvers.dynamics import DynamicSettings, energy, simulate

LENGTH, CHORD, ELEMENTS = 1.0, 0.8, 50


def swinging_rope():
    """A 1 m rope (E = 1 MPa, 10 mm, 1000 kg/m^3: EA = 79 N against a weight of 0.77 N)
    pinned at both ends 0.8 m apart, released at rest from a circular arc in the
    horizontal plane."""
    turn = brentq(lambda t: 2 * np.sin(t / 2) / t - CHORD / LENGTH, 1e-6, 6.0)
    radius = LENGTH / turn
    phi = np.linspace(-turn / 2, turn / 2, 401)
    points = np.stack([radius * np.sin(phi), -radius * (np.cos(turn / 2) - np.cos(phi)),
                       0 * phi], 1)
    scene = {"name": "swing", "gravity": {"vector": [0, 0, -9.81]},
             "rods": [{"name": "rope", "elements": ELEMENTS,
                       "material": {"E": 1e6, "G": 1e6 / 3, "density": 1000.0},
                       "section": {"shape": "circle", "diameter": 0.01},
                       "geometry": {"kind": "straight", "length": LENGTH},
                       "initial": {"points": (points - points[0]).tolist()}}],
             "constraints": [{"kind": "pin", "rod": "rope", "node": 0},
                             {"kind": "pin", "rod": "rope", "node": -1}],
             "solver": {"kind": "dynamic", "dt": 0.04, "t_end": 0.48}}
    return sj.build_model(sj.Scene.from_dict(scene))


def total_energy(model, run):
    """Kinetic + strain + gravitational energy (J) of each saved state."""
    rho_a = np.asarray(jax.vmap(line_density)(model.inertia)) * np.asarray(model.length)
    a = np.asarray(model.structure.element_nodes)
    out = []
    for k in range(len(run.time)):
        p = np.asarray(run.p[k])
        height = 0.5 * (p[a] + p[a + 1]) @ np.asarray(model.gravity)
        out.append(float(energy(model, run.R[k], run.p[k], run.v[k])) - float(rho_a @ height))
    return np.array(out)


@pytest.mark.slow
def test_slack_rope_swings_in_whole_steps_and_follows_short_steps():
    model = swinging_rope()
    coarse = simulate(model, DynamicSettings(dt=0.04, steps=12, globalized=True))
    fine = simulate(model, DynamicSettings(dt=0.005, steps=96, globalized=True))
    assert bool(coarse.converged) and bool(fine.converged)
    np.testing.assert_array_equal(np.asarray(coarse.substeps), 1)     # no step halved
    p_coarse, p_fine = np.asarray(coarse.p), np.asarray(fine.p)[::8]
    motion = np.abs(p_fine - p_fine[0]).max()
    assert motion > 0.4                                  # it swings down by half a metre
    # generalized-alpha's time-discretization error at 40 ms (second order: a few % here)
    assert np.abs(p_coarse - p_fine).max() < 0.06 * motion
    # the energy does not grow: against the work of gravity over the swing (~0.4 J)
    weight = 9.81 * float(np.sum(jax.vmap(line_density)(model.inertia) * model.length))
    e = total_energy(model, coarse)
    assert e.max() - e[0] < 0.01 * weight * motion


def test_globalized_is_a_switch():
    with pytest.raises(ValueError, match="DynamicSettings.globalized"):
        DynamicSettings(dt=0.01, steps=1, globalized="yes")
