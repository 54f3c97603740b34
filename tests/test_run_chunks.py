"""The host driver of ``sj.run`` (simsoft_jax.solvers.dynamics.driver): a run spanning several
chunks of one compiled program, its packed outputs unpacked on the host, and the
throw-away execution that follows compiling or loading the program.

Reference: free fall of a rod under gravity, which the Lie-group generalized-alpha scheme
reproduces to round-off at any step size (every node at ``p0 - g t^2 / 2`` along world z,
frames unchanged; tests/test_time_limits.py), and ``sj.simulate`` on the same steps (one
``lax.scan``, another code path).
"""
import numpy as np

import simsoft_jax as sj
from simsoft_jax.solvers.dynamics import driver

G, DT = 9.81, 1e-3


def falling(steps, save_every=1):
    return {"solver": {"kind": "dynamic", "t_end": steps * DT, "dt": DT,
                       "save_every": save_every},
            "gravity": {"vector": [0.0, 0.0, -G]},
            "rods": [{"name": "rod", "elements": 2,
                      "geometry": {"kind": "straight", "length": 0.3},
                      "stiffness": {"EA": 1e4, "GAy": 1e4, "GAz": 1e4, "GJ": 1.0,
                                    "EIy": 1.0, "EIz": 1.0},
                      "inertia": {"rhoA": 0.1, "rhoJ": 2e-4, "rhoIy": 1e-4, "rhoIz": 1e-4}}]}


def test_a_run_over_several_chunks_is_the_exact_fall_and_equals_simulate():
    steps = 2 * driver.CHUNK_STEPS + driver.CHUNK_STEPS // 2   # two and a half chunks
    scene = falling(steps)
    r = sj.run(scene)
    assert r.converged and r.status == "converged" and r.failed_at is None
    t = DT * np.arange(steps + 1)
    np.testing.assert_allclose(r.time, t, rtol=0, atol=1e-12)
    p0 = np.array([[0.0, 0.0, 0.0], [0.15, 0.0, 0.0], [0.3, 0.0, 0.0]])
    expected = p0[None] + np.stack([0 * t, 0 * t, -0.5 * G * t * t], axis=1)[:, None]
    # round-off accumulates over the 1000 steps (a fall of 4.9 m): 1e-10
    np.testing.assert_allclose(r.positions("rod"), expected, rtol=0, atol=1e-10)
    np.testing.assert_allclose(r.rotations("rod"),
                               np.broadcast_to(np.eye(3), (steps + 1, 3, 3, 3)), rtol=0,
                               atol=1e-10)
    # linear velocity along z; within the Newton tolerance over the step (1e-10 / dt)
    np.testing.assert_allclose(r.velocities("rod")[:, :, 2],
                               np.broadcast_to(-G * t[:, None], (steps + 1, 3)), rtol=0,
                               atol=1e-8)
    model = sj.build_model(sj.Scene.from_dict(scene))
    ref = sj.simulate(model, sj.DynamicSettings(dt=DT, steps=steps))
    np.testing.assert_allclose(r.raw.p, ref.p, rtol=0, atol=1e-14)
    np.testing.assert_array_equal(r.raw.iterations, ref.iterations)
    np.testing.assert_allclose(r.raw.final.vd, ref.final.vd, rtol=0, atol=1e-12)
    assert float(r.raw.final.t) == float(ref.final.t)


def test_saving_every_few_steps_over_chunks_keeps_the_saved_states():
    """save_every 3 over 2.5 chunks' worth of steps, and a closing block (the step count
    is not a multiple of 3): the saved times and states are those of the exact fall."""
    steps = 2 * driver.CHUNK_STEPS + driver.CHUNK_STEPS // 2 + 1
    r = sj.run(falling(steps, save_every=3))
    assert r.converged
    t = r.time
    assert t[-1] == steps * DT and np.all(np.diff(t) > 0)
    np.testing.assert_allclose(t[:-1], 3 * DT * np.arange(len(t) - 1), rtol=0, atol=1e-12)
    np.testing.assert_allclose(r.positions("rod")[:, :, 2], np.broadcast_to(
        -0.5 * G * t[:, None] ** 2, (len(t), 3)), rtol=0, atol=1e-10)
