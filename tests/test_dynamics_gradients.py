"""Gradients through whole rollouts with respect to load scales and initial velocities
(issue: "gradient of any scalar of the trajectory with respect to array inputs"), checked
against central finite differences of plain (non-differentiable) rollouts."""
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import simsoft_jax as sj
from simsoft_jax.solvers import dynamics as dy

SCENE = {
    "solver": {"kind": "dynamic", "t_end": 0.5, "dt": 0.01, "rho_inf": 0.9},
    "rods": [{"name": "arm", "elements": 3, "geometry": {"kind": "straight", "length": 1.0},
              "stiffness": {"EA": 1e3, "GAy": 1e3, "GAz": 1e3, "GJ": 1.0, "EIy": 1.0,
                            "EIz": 2.0},
              "inertia": {"rhoA": 0.1, "rhoJ": 2e-3, "rhoIy": 1e-3, "rhoIz": 1e-3}}],
    "constraints": [{"kind": "clamp", "rod": "arm", "node": 0}],
    "loads": [{"kind": "force", "rod": "arm", "node": -1, "vector": [0.0, 0.1, -0.3],
               "profile": {"kind": "ramp", "t0": 0.0, "t1": 0.2}}],
    "initial_velocity": [{"rod": "arm", "linear": [0, 0, 0], "angular": [0.0, 0.5, 0.3]}],
}
SETTINGS = dy.DynamicSettings(dt=0.01, steps=50, rho_inf=0.9, tolerance=1e-12)


@pytest.mark.slow
def test_rollout_gradient_wrt_load_scale_and_initial_velocity():
    scene = sj.Scene.from_dict(SCENE)
    model = sj.build_model(scene)

    def scaled(x):
        channels = model.channels.replace(nodal_dead=model.channels.nodal_dead * x[0])
        return model.replace(channels=channels, v0=model.v0 * x[1])

    def tip(x, differentiable):
        traj = dy.simulate(scaled(x), SETTINGS, differentiable=differentiable)
        return traj.p[-1, -1], traj.converged

    x0 = jnp.array([1.0, 1.0])
    jac = np.asarray(jax.jacrev(lambda x: tip(x, True)[0])(x0))
    delta = 1e-5
    for k in range(2):
        e = np.zeros(2)
        e[k] = delta
        (plus, ok_p), (minus, ok_m) = tip(x0 + e, False), tip(x0 - e, False)
        assert bool(ok_p) and bool(ok_m)
        fd = (np.asarray(plus) - np.asarray(minus)) / (2 * delta)
        assert np.linalg.norm(fd) > 1e-3, "the scale must move the tip"
        assert np.linalg.norm(jac[:, k] - fd) <= 1e-5 * np.linalg.norm(fd), (k, jac[:, k], fd)
