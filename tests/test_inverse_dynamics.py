"""Trajectory optimization (:func:`simsoft_jax.track_path`): the values of
a table time law that make the tip follow a target path.

Robot: a clamped 1 m rod, 3 elements, EI = 1 N m^2, rhoA = 0.1 kg/m, a follower tip moment
about z whose time law is a table with knots at t = 0, 0.1, ..., 0.4 s (the value at t = 0
stays 0, the 4 others are the actuation). Rollout: 40 steps of 0.01 s, every second state
saved (21 states). The target path is the tip's path under known knot values (so it can be
followed exactly, and those values are the ones to recover); the optimizer starts from no
moment at all. The Jacobian of the tracking residual (forward mode through every step's
implicit derivative) is checked against central differences of rollouts.
"""
import jax.numpy as jnp
import numpy as np
import pytest

import simsoft_jax as sj
from simsoft_jax.studies.inverse_dynamics import tracking_residual
from simsoft_jax.solvers.statics import as_traced

KNOTS = [0.0, 0.1, 0.2, 0.3, 0.4]
SETTINGS = sj.DynamicSettings(dt=0.01, steps=40, save_every=2, tolerance=1e-12)
U_TRUE = np.array([0.3, 0.8, 0.6, 0.9])    # N m at t = 0.1, 0.2, 0.3, 0.4 s


@pytest.fixture(scope="module")
def robot():
    d = {"name": "tracking", "solver": {"kind": "dynamic", "t_end": 0.4, "dt": 0.01},
         "rods": [{"name": "arm", "elements": 3, "geometry": {"kind": "straight", "length": 1.0},
                   "stiffness": {"EA": 1e3, "GAy": 1e3, "GAz": 1e3, "GJ": 1.0, "EIy": 1.0,
                                 "EIz": 1.0},
                   "inertia": {"rhoA": 0.1, "rhoJ": 1e-3, "rhoIy": 1e-3, "rhoIz": 1e-3}}],
         "constraints": [{"kind": "clamp", "rod": "arm", "node": 0}],
         "loads": [{"kind": "moment", "rod": "arm", "node": -1, "vector": [0, 0, 1.0],
                    "frame": "local",
                    "profile": {"kind": "table", "t": KNOTS, "scale": [0.0] * 5}}]}
    model = sj.build_model(sj.Scene.from_dict(d))
    actuate = sj.leaf_actuation(model, [("channels.table_scale", (0, k)) for k in range(1, 5)])
    return model, actuate


def test_tracking_reaches_a_followable_path_and_recovers_the_time_law(robot):
    model, actuate = robot
    evaluate = tracking_residual(actuate, 3)
    _, _, ok, path = evaluate(model, as_traced(SETTINGS), jnp.asarray(U_TRUE), jnp.zeros((21, 3)))
    assert bool(ok)
    path = np.asarray(path)
    assert np.ptp(path[:, 1]) > 0.2, "the moments must move the tip"
    for method in ("lbfgs", "levenberg_marquardt"):
        res = sj.track_path(model, actuate, SETTINGS, ("arm", -1), path, np.zeros(4),
                         method=method)
        assert res.outcome == 0, res.message
        assert res.improvement > 1e6, res.message          # 0.36 m -> below 4e-7 m
        np.testing.assert_allclose(res.u, U_TRUE, atol=1e-6)
        np.testing.assert_allclose(res.path, path, atol=1e-7)

    # Jacobian of the tracking residual vs central differences of rollouts (away from
    # the optimum, so that the residual is not small)
    u = U_TRUE + np.array([0.05, -0.1, 0.07, 0.02])
    r, J, ok, _ = evaluate(model, as_traced(SETTINGS), jnp.asarray(u), jnp.asarray(path))
    assert bool(ok)
    h = 1e-5
    for k in range(4):
        e = np.zeros(4)
        e[k] = h
        plus = np.asarray(evaluate(model, as_traced(SETTINGS), jnp.asarray(u + e),
                                   jnp.asarray(path))[0])
        minus = np.asarray(evaluate(model, as_traced(SETTINGS), jnp.asarray(u - e),
                                    jnp.asarray(path))[0])
        fd = (plus - minus) / (2 * h)
        assert np.linalg.norm(fd) > 1e-2
        assert np.linalg.norm(np.asarray(J)[:, k] - fd) <= 1e-5 * np.linalg.norm(fd), k
    # the gradient of the cost, J^T r, the same way
    cost = lambda v: 0.5 * float(np.sum(np.asarray(  # noqa: E731
        evaluate(model, as_traced(SETTINGS), jnp.asarray(v), jnp.asarray(path))[0]) ** 2))
    grad = np.asarray(J).T @ np.asarray(r)
    fd_grad = np.array([(cost(u + h * np.eye(4)[k]) - cost(u - h * np.eye(4)[k])) / (2 * h)
                        for k in range(4)])
    np.testing.assert_allclose(grad, fd_grad, rtol=1e-5)


def test_bad_input(robot):
    model, actuate = robot
    for kwargs, message in ((dict(path=np.zeros((20, 3))), "path: expected shape (21, 3)"),
                            (dict(node=("arm", 7)), "nodes[0]: unknown node 7"),
                            (dict(lower=[1.0] * 4, upper=[0.0] * 4), "lower: lower[0] = 1.0"),
                            (dict(u0=np.zeros(3)), "u0: expected shape (4,)")):
        args = dict(node=("arm", -1), path=np.zeros((21, 3)), u0=np.zeros(4))
        args.update(kwargs)
        with pytest.raises(ValueError, match=None) as info:
            sj.track_path(model, actuate, SETTINGS, **args)
        assert message in str(info.value), str(info.value)
