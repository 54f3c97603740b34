"""Contact in dynamics (issue 14), dt = 0.01 s, no damping: a rod thrown flat onto a
frictionless plane bounces off with its energy and speed (the penalty is conservative),
and a rod sliding on a plane with Coulomb friction stops after the distance
``v0^2 / (2 mu g)``. Both runs share one structure (one compiled rollout); the
references are closed forms derived in the tests.
"""
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import simsoft_jax as sj
from simsoft_jax.physics import assembly
from simsoft_jax.solvers.dynamics.rollout import energy
from simsoft_jax.physics.terms import contact

R_CONTACT, L_ROD, RHO_A, N = 0.02, 0.5, 0.5, 10
MU, G = 0.3, 9.81
T_CONTACT = 0.2                                   # s: pi sqrt(rhoA/k), 20 steps
K_SOFT = RHO_A * (np.pi / T_CONTACT) ** 2         # N/m^2


def _scene(velocity, gravity, stiffness, height, rho_inf):
    return {
        "solver": {"kind": "dynamic", "t_end": 0.4, "dt": 0.01, "rho_inf": rho_inf},
        "gravity": {"vector": [0.0, 0.0, -gravity]},
        "initial_velocity": [{"rod": "rod", "linear": velocity, "angular": [0, 0, 0]}],
        "rods": [{"name": "rod", "elements": N, "geometry": {"kind": "straight", "length": L_ROD},
                  "base": {"position": [0.0, 0.0, height]},
                  "stiffness": {"EA": 1e5, "GAy": 1e5, "GAz": 1e5, "GJ": 1.0, "EIy": 1.0,
                                "EIz": 1.0},
                  "inertia": {"rhoA": RHO_A, "rhoJ": 1e-4, "rhoIy": 5e-5, "rhoIz": 5e-5}}],
        "obstacles": [{"name": "floor", "kind": "plane", "point": [0.0, 0.0, -R_CONTACT],
                       "normal": [0.0, 0.0, 1.0], "friction": MU}],
        "contact": {"radius": R_CONTACT, "stiffness": stiffness}}


def _total_energy(model, R, p, v):
    """Kinetic + strain (rollout.energy) + penalty energy of the contact (J); no gravity."""
    s = model.structure
    data = assembly.element_data(model)
    penalty = jax.vmap(lambda RA, pA, RB, pB, c, length: contact.energy(
        RA, pA, RB, pB, c, length, s.obstacle_kinds, s.contact_points))(
        *assembly.element_poses(model, R, p), data.contact, model.length)
    return energy(model, R, p, v) + penalty.sum(), penalty.sum()


def test_rod_thrown_on_a_plane_bounces_back_with_its_energy():
    """A straight rod thrown flat at v0 = 0.03 m/s onto a frictionless plane (friction does
    nothing here: the motion is normal to the plane), no gravity and no damping,
    generalized-alpha with rho_inf = 1. The penalty is a conservative spring per unit
    length; its stiffness k = rhoA (pi/T)^2 makes the contact last T = 0.2 s (20 steps).
    Expected: every step converges without sub-steps; the largest penetration is about
    v0 sqrt(rhoA/k) + eps/2 = v0 T/pi + 0.005 r (energy balance of the quadratic part),
    stated bound 0.11 r; the total energy (kinetic + strain + penalty) stays within 1 % of
    its start at every saved step, and the rod leaves with speed v0 upwards (1 %). Gravity
    is off: a contact soft enough to be resolved at dt = 0.01 s would sink a resting rod by
    g T^2/pi^2 = 0.04 m (2 radii); with gravity see the friction test, which uses a stiff
    penalty."""
    v0 = 0.03
    res = sj.run(_scene([0.0, 0.0, -v0], 0.0, K_SOFT, 0.002, 1.0))
    assert res.converged and int(np.max(res.raw.substeps)) == 1
    pen = res.contacts["floor"]["max_penetration"]
    expected = v0 * T_CONTACT / np.pi + 0.5 * contact.SMOOTHING * R_CONTACT
    assert abs(pen.max() - expected) < 0.1 * expected
    assert pen.max() < 0.11 * R_CONTACT
    model = res.model
    totals = jax.jit(jax.vmap(lambda R, p, v: _total_energy(model, R, p, v)))(
        jnp.asarray(res._R), jnp.asarray(res._p), jnp.asarray(res.raw.v))
    e, e_pen = np.asarray(totals[0]), np.asarray(totals[1])
    np.testing.assert_allclose(e, 0.5 * RHO_A * L_ROD * v0**2, rtol=1e-2)
    touching = np.flatnonzero(e_pen > 0)
    after = touching[-1] + 2
    assert after < len(e) and e_pen[after:].max() == 0.0        # it has left the plane
    vz = np.einsum("tnij,tnj->tni", res.rotations("rod"), res.velocities("rod")[..., :3])[..., 2]
    np.testing.assert_allclose(vz[after:], v0, rtol=1e-2)


def test_rod_sliding_on_a_plane_with_friction_stops_after_coulomb_distance():
    """A rod lying on a plane under gravity, launched along it at v0 = 0.5 m/s, friction
    mu = 0.3 (regularized Coulomb, slip-velocity scale 1e-3 m/s): Coulomb's law decelerates
    it at mu g, so it slides v0^2/(2 mu g) = 42.5 mm in v0/(mu g) = 0.17 s and stays at
    rest. Checked: the sliding distance to 1 %, the speed after 0.3 s below 1e-4 m/s
    (creep of the regularization), penetration below 1 % of the radius (a stiff penalty,
    k = 1e6 N/m^2, not resolved in time: rho_inf = 0.5 damps its fast oscillation)."""
    v0 = 0.5
    res = sj.run(_scene([v0, 0.0, 0.0], G, 1e6, 0.0, 0.5))
    assert res.converged
    x = res.positions("rod")[:, :, 0].mean(axis=1)
    np.testing.assert_allclose(x[-1] - x[0], v0**2 / (2 * MU * G), rtol=1e-2)
    late = res.time > 0.3
    assert np.abs(res.velocities("rod")[late][..., :3]).max() < 1e-4
    assert res.contacts["floor"]["max_penetration"].max() < 1e-2 * R_CONTACT


@pytest.mark.slow
def test_friction_tangent_in_the_velocities_matches_autodiff():
    """The dynamic iteration matrix with friction (C block by jacfwd in the velocities) is
    the same on the closed-form and the autodiff paths, at a sliding state."""
    from simsoft_jax.solvers.dynamics.residual import element_inertia, residual_and_iteration_matrix
    model = sj.build_model(sj.Scene.from_dict(_scene([0.5, 0, 0], G, 1e6, -1e-4, 0.5)))
    rng = np.random.default_rng(3)
    v = jnp.asarray(model.v0 + 0.05 * rng.standard_normal(model.v0.shape))
    vd = jnp.asarray(rng.standard_normal(model.v0.shape))
    w = jnp.asarray(1e-3 * rng.standard_normal(model.v0.shape))

    @jax.jit
    def both(model):
        inert = element_inertia(model)
        return [residual_and_iteration_matrix(model, inert, model.R0, model.p0, v, vd, w,
                                              100.0, 10.0, tangent=t)
                for t in ("closed_form", "autodiff")]

    (r1, b1), (r2, b2) = both(model)
    assert float(jnp.abs(r1).max()) > 1e-3
    np.testing.assert_allclose(r1, r2, atol=1e-9)
    for a, b in zip(b1, b2):
        np.testing.assert_allclose(a, b, atol=1e-9 * float(jnp.abs(b1[0]).max()))


def test_contact_is_looked_for_between_nodes():
    """A sphere smaller than an element, pressed against the element's middle, is felt
    (quadrature points along the helical interpolation), though both nodes are clear."""
    scene = _scene([0, 0, 0], 0.0, 1e4, 0.0, 0.5)
    h = L_ROD / N
    scene["obstacles"] = [{"name": "ball", "kind": "sphere", "radius": 0.2 * h,
                           "center": [2.5 * h, 0.0, -R_CONTACT - 0.15 * h]}]
    model = sj.build_model(sj.Scene.from_dict(scene))
    r = jax.jit(assembly.residual)(model, model.R0, model.p0)
    assert float(jnp.linalg.norm(r[:, 2])) > 0.0
    assert float(jnp.abs(r[[0, 1, 4, 5], :]).max()) == 0.0
    # the two nodes of the touched element are clear of the ball
    d = np.linalg.norm(np.asarray(model.p0)[2:4] - scene["obstacles"][0]["center"], axis=1)
    assert (d - 0.2 * h - R_CONTACT > 0.1 * h).all()
