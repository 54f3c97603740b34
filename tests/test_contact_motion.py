"""Moving obstacles (issue 14): a plane that moves by a time law (``motion``), dynamic,
dt = 0.01 s. A plane moving at constant speed hits a free rod, which leaves at twice
that speed (an elastic collision with an infinitely heavy wall), and a plate sliding
under a resting rod drags it by Coulomb friction until it moves with the plate. Both runs
share one structure (one compiled rollout); the references are closed forms derived in
the tests.
"""
import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import simsoft_jax as sj
from simsoft_jax.physics import assembly
from simsoft_jax.model.loads import loads_at
from simsoft_jax.physics.terms import contact

R_CONTACT, L_ROD, RHO_A, N = 0.02, 0.5, 0.5, 10
MU, G = 0.3, 9.81
T_CONTACT = 0.2                                   # s: pi sqrt(rhoA/k), 20 steps
K_SOFT = RHO_A * (np.pi / T_CONTACT) ** 2         # N/m^2


def _scene(direction, speed, gravity, stiffness, plane_z, rho_inf):
    """A free straight rod along x at rest at z = 0 and a plane z = plane_z (normal +z,
    friction MU) moving along ``direction`` at ``speed`` (m/s) from t = 0."""
    return {
        "solver": {"kind": "dynamic", "t_end": 0.5, "dt": 0.01, "rho_inf": rho_inf},
        "gravity": {"vector": [0.0, 0.0, -gravity]},
        "rods": [{"name": "rod", "elements": N, "geometry": {"kind": "straight", "length": L_ROD},
                  "stiffness": {"EA": 1e5, "GAy": 1e5, "GAz": 1e5, "GJ": 1.0, "EIy": 1.0,
                                "EIz": 1.0},
                  "inertia": {"rhoA": RHO_A, "rhoJ": 1e-4, "rhoIy": 5e-5, "rhoIz": 5e-5}}],
        "obstacles": [{"name": "plate", "kind": "plane", "point": [0.0, 0.0, plane_z],
                       "normal": [0.0, 0.0, 1.0], "friction": MU,
                       "motion": {"displacement": direction,
                                  "profile": {"kind": "linear", "rate": speed}}}],
        "contact": {"radius": R_CONTACT, "stiffness": stiffness}}


def _world_velocity(res):
    """Mean world velocity of the rod's nodes (T,3)."""
    v = np.einsum("tnij,tnj->tni", res.rotations("rod"), res.velocities("rod")[..., :3])
    return v.mean(axis=1)


def test_a_moving_plane_bounces_a_free_rod_off_at_twice_its_speed():
    """No gravity, no damping (rho_inf = 1), frictionless in effect (the motion is normal
    to the plane). The plane, 5 mm below the rod, rises at V = 0.05 m/s and reaches it at
    t = 0.1 s. In the plane's frame the rod comes at V and the conservative penalty
    (contact time T = 0.2 s, 20 steps) sends it back at V: in the world it leaves at 2V.
    Checked: every step converges, the rod's speed after it has left to 1 % of 2V with no
    sideways drift, the largest penetration (reported where the plane is at each time)
    V T/pi + eps/2 to 10 %, and the contact starting at t = 0.1 s (within a step)."""
    V, gap = 0.05, 0.005
    res = sj.run(_scene([0.0, 0.0, 1.0], V, 0.0, K_SOFT, -R_CONTACT - gap, 1.0))
    assert res.converged and int(np.max(res.raw.substeps)) == 1
    pen = res.contacts["plate"]["max_penetration"]
    touching = np.flatnonzero(pen > 0)
    assert touching.size and abs(res.time[touching[0]] - gap / V) <= 0.0101
    after = touching[-1] + 2
    assert after < len(res.time) - 3                      # it has left the plane
    v = _world_velocity(res)
    np.testing.assert_allclose(v[after:, 2], 2 * V, rtol=1e-2)
    assert np.abs(v[after:, :2]).max() < 1e-6
    expected = V * T_CONTACT / np.pi + 0.5 * contact.SMOOTHING * R_CONTACT
    assert abs(pen.max() - expected) < 0.1 * expected


def test_a_sliding_plate_drags_a_resting_rod_by_friction():
    """Gravity g, a rod resting on a plate that starts sliding along x at V = 0.5 m/s at
    t = 0. Coulomb friction mu m g accelerates the rod at mu g while it slips, so its
    speed is mu g t until it reaches V at t* = V/(mu g) = 0.17 s; then it moves with the
    plate. The friction is regularized on the velocity relative to the plate (slip scale
    1e-3 m/s): checked the rod's speed for 0.05 <= t <= 0.15 s to 2 % of mu g t (in the
    first steps the rod, started just touching, settles into the penalty and its normal
    force, hence its friction, oscillates about m g), its speed after
    0.3 s to 1e-3 of V, and the normal force of the plate once the rod rides on it (the
    weight rhoA L g) to 1 %; a stiff penalty (k = 1e6 N/m^2, rho_inf = 0.5 damps its fast
    oscillation) keeps the penetration below 1 % of the radius."""
    V = 0.5
    res = sj.run(_scene([1.0, 0.0, 0.0], V, G, 1e6, -R_CONTACT, 0.5))
    assert res.converged
    v = _world_velocity(res)[:, 0]
    slipping = (res.time >= 0.05) & (res.time <= 0.15)
    np.testing.assert_allclose(v[slipping], MU * G * res.time[slipping], rtol=2e-2)
    late = res.time > 0.3
    np.testing.assert_allclose(v[late], V, rtol=1e-3)
    plate = res.contacts["plate"]
    np.testing.assert_allclose(plate["normal_force"][late], RHO_A * L_ROD * G, rtol=1e-2)
    assert plate["max_penetration"].max() < 1e-2 * R_CONTACT


def test_contact_force_of_a_moving_plane_and_its_gradient_in_the_speed():
    """The rod at rest at z = 0, the plane starting at z = -r and rising at V: at time t
    the rod sinks delta = V t into it everywhere (past the smoothing width eps), so the
    plane pushes with k (delta - eps/2) per length on the rod and on its two end caps (a
    length r each), (L + 2 r) k (V t - eps/2) in all, and the derivative of that in V
    (through the motion's time law, a model array, evaluated at t as in a time step) is
    (L + 2 r) k t; both from the residual at t to 1e-9, the derivative by forward mode
    against the closed form and a central difference."""
    V, t, k = 0.05, 0.3, 1e4
    model = sj.build_model(sj.Scene.from_dict(
        _scene([0.0, 0.0, 1.0], V, 0.0, k, -R_CONTACT, 1.0)))
    law = model.obstacle_law

    @jax.jit
    def push(rate):
        m = model.replace(obstacle_law=dataclasses.replace(
            law, params=law.params.at[0, 2].set(rate)))
        r = assembly.residual(loads_at(m, jnp.asarray(t)), model.R0, model.p0)
        return -jnp.sum(r[:, 2])            # residual side: the obstacle's force is -r

    eps = contact.SMOOTHING * R_CONTACT
    assert V * t > eps
    loaded = L_ROD + 2 * R_CONTACT
    assert float(push(V)) == pytest.approx(loaded * k * (V * t - 0.5 * eps), rel=1e-9)
    grad = float(jax.jacfwd(push)(jnp.asarray(V)))
    assert grad == pytest.approx(loaded * k * t, rel=1e-9)
    fd = (float(push(V + 1e-6)) - float(push(V - 1e-6))) / 2e-6
    assert grad == pytest.approx(fd, rel=1e-7)


@pytest.mark.parametrize("change,message", [
    ({"motion": {"displacement": [0, 0, 1]}}, "obstacles[0].motion.profile: required"),
    ({"motion": {"displacement": [0, 1], "profile": {"kind": "constant"}}},
     "obstacles[0].motion.displacement: must have 3 entries"),
    ({"motion": {"displacement": [0, 0, 1], "profile": {"kind": "linear"}, "speed": 1}},
     "obstacles[0].motion.speed: unknown key"),
])
def test_bad_motion_is_rejected_naming_the_key(change, message):
    scene = _scene([0.0, 0.0, 1.0], 1.0, 0.0, 1e4, -1.0, 1.0)
    scene["obstacles"][0].update(change)
    with pytest.raises(ValueError, match=message.replace("[", r"\[").replace("]", r"\]")):
        sj.Scene.from_dict(scene)


def test_static_scene_with_a_moving_obstacle_is_rejected():
    scene = _scene([0.0, 0.0, 1.0], 1.0, 0.0, 1e4, -1.0, 1.0)
    scene["solver"] = {"kind": "static"}
    scene["constraints"] = [{"kind": "clamp", "rod": "rod", "node": 0}]
    with pytest.raises(ValueError, match=r"obstacles\[0\].motion: a static solve cannot"):
        sj.Scene.from_dict(scene)
