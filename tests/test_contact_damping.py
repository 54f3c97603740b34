"""Normal contact damping (``[contact] damping_ratio``, :mod:`simsoft_jax.physics.terms.contact`
(D1)) in dynamics: a rod thrown flat onto a plane leaves with the restitution of a
damped linear oscillator when the contact time is resolved, none at critical damping,
and never gains energy; its velocity tangent against central finite differences; a
gradient through a rollout in the damping ratio against central finite differences;
the scene key's validation; a stiff impact the step cannot resolve stands with damping
(no rebound above the drop height) where the undamped one is refused.
"""
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import simsoft_jax as sj
from conftest import dropped_rod_scene
from simsoft_jax.physics import assembly
from simsoft_jax.physics.terms import contact
from simsoft_jax.solvers.dynamics.rollout import energy

R_CONTACT, L_ROD, RHO_A, N = 0.02, 0.5, 0.5, 10
T_CONTACT = 0.2                                   # s: pi sqrt(rhoA/k), 20 steps of 0.01 s
K_SOFT = RHO_A * (np.pi / T_CONTACT) ** 2         # N/m^2
V0 = 0.3                                          # m/s: sinks ~v0 T/pi = 19 mm >> eps
# the end caps (a length r of line penalty at each free end, contact.py) add 2r to the
# penalty's length L but no mass: spring and dashpot per mass both grow by (L + 2r)/L,
# so the oscillator's damping ratio is zeta sqrt((L + 2r)/L)
CAPS = np.sqrt((L_ROD + 2 * R_CONTACT) / L_ROD)


def _scene(zeta, t_end=0.5, v0=V0):
    return {
        "solver": {"kind": "dynamic", "t_end": t_end, "dt": 0.01, "rho_inf": 1.0},
        "initial_velocity": [{"rod": "rod", "linear": [0.0, 0.0, -v0], "angular": [0, 0, 0]}],
        "rods": [{"name": "rod", "elements": N, "geometry": {"kind": "straight", "length": L_ROD},
                  "base": {"position": [0.0, 0.0, 0.002]},
                  "stiffness": {"EA": 1e5, "GAy": 1e5, "GAz": 1e5, "GJ": 1.0, "EIy": 1.0,
                                "EIz": 1.0},
                  "inertia": {"rhoA": RHO_A, "rhoJ": 1e-4, "rhoIy": 5e-5, "rhoIz": 5e-5}}],
        "obstacles": [{"name": "floor", "kind": "plane", "point": [0.0, 0.0, -R_CONTACT],
                       "normal": [0.0, 0.0, 1.0]}],
        "contact": {"radius": R_CONTACT, "stiffness": K_SOFT, "damping_ratio": zeta}}


def restitution(zeta):
    """The damped linear oscillator's coefficient of restitution over its half period
    (contact lasting until the penetration returns to zero): exp(-zeta pi/sqrt(1-zeta^2)),
    0 from critical damping on."""
    return float(np.exp(-zeta * np.pi / np.sqrt(1.0 - zeta**2))) if zeta < 1.0 else 0.0


def _total_energy(model, R, p, v):
    """Kinetic + strain + penalty energy (J); no gravity."""
    s = model.structure
    data = assembly.element_data(model)
    penalty = jax.vmap(lambda RA, pA, RB, pB, c, length: contact.energy(
        RA, pA, RB, pB, c, length, s.obstacle_kinds, s.contact_points))(
        *assembly.element_poses(model, R, p), data.contact, model.length)
    return energy(model, R, p, v) + penalty.sum()


@pytest.mark.parametrize("zeta", [0.1, 0.3, 1.0])
def test_resolved_impact_has_the_damped_oscillator_restitution_and_loses_energy(zeta):
    """A straight rod thrown flat at v0 = 0.3 m/s onto a frictionless plane, no gravity,
    the contact time T = 0.2 s resolved by 20 steps (generalized-alpha, rho_inf = 1: no
    numerical damping). Past the penalty's smoothing width (eps = 0.2 mm, against ~19 mm
    of penetration) penalty and damping are a linear spring and dashpot per unit length:
    the rod leaves upwards at e v0 with the oscillator's restitution e (module
    constants: the end caps raise zeta by 4 %), to 2.5 % of v0 (the time step's error);
    at zeta = 1 it does not bounce (upward speed below 1 % of v0). The total energy
    (kinetic + strain + penalty) never exceeds its start (every saved step) and ends at
    e^2 of it (within 5 % of the start)."""
    res = sj.run(_scene(zeta))
    assert res.converged and int(np.max(res.raw.substeps)) == 1
    vz = np.einsum("tnij,tnj->tni", res.rotations("rod"),
                   res.velocities("rod")[..., :3])[..., 2].mean(axis=1)
    e = restitution(zeta * CAPS)
    if zeta < 1.0:
        assert res.contacts["floor"]["max_penetration"][-1] == 0.0     # it has left
        assert abs(vz[-1] - e * V0) < 0.025 * V0
    else:
        assert vz[-1] < 0.01 * V0
    model = res.model
    total = np.asarray(jax.jit(jax.vmap(lambda R, p, v: _total_energy(model, R, p, v)))(
        jnp.asarray(res._R), jnp.asarray(res._p), jnp.asarray(res.raw.v)))
    start = 0.5 * RHO_A * L_ROD * V0**2
    assert total.max() <= start * (1.0 + 1e-6)
    assert abs(total[-1] - e**2 * start) < 0.05 * start


def test_damping_velocity_tangent_matches_central_differences():
    """The C block of the contact (derivative of the nodal contact forces in the nodal
    velocities, :func:`simsoft_jax.physics.assembly.contact_and_tangent`) of a rod sunk into
    the plane and moving, against central differences of the forces (step 1e-6 m/s)."""
    model = sj.build_model(sj.Scene.from_dict(_scene(0.5)))
    rng = np.random.default_rng(5)
    p = jnp.asarray(model.p0).at[:, 2].add(-0.01 + 0.002 * rng.standard_normal(N + 1))
    v = jnp.asarray(0.1 * rng.standard_normal(model.v0.shape))
    forces = jax.jit(lambda v: assembly.contact_and_tangent(model, model.R0, p, v))
    f, _, C = forces(v)
    a = np.asarray(model.structure.element_nodes)
    step = 1e-6
    for node, dof in ((3, 2), (5, 2), (7, 4)):   # normal speeds (frictionless plane)
        dv = jnp.zeros_like(v).at[node, dof].set(step)
        fd = (forces(v + dv)[0] - forces(v - dv)[0]) / (2 * step)      # (E,12)
        column = np.zeros_like(np.asarray(fd))
        for e in range(N):
            if a[e] == node:
                column[e] = C[e][:, dof]
            if a[e] + 1 == node:
                column[e] = C[e][:, 6 + dof]
        scale = float(jnp.abs(fd).max())
        assert scale > 0.0
        np.testing.assert_allclose(column, fd, rtol=0, atol=1e-6 * scale)


@pytest.mark.slow    # compiles the differentiable rollout and its reverse pass
def test_gradient_in_the_damping_ratio_matches_finite_differences():
    """d vz_final / d zeta of the thrown rod after 30 steps (in contact and leaving), by
    reverse mode through ``simulate(differentiable=True)``, against central differences
    of the same rollout (relative step 1e-5; agreement to 1e-4)."""
    settings = sj.DynamicSettings(dt=0.01, steps=30, rho_inf=1.0)
    model = sj.build_model(sj.Scene.from_dict(_scene(0.3)))

    def final_vz(model):
        traj = sj.simulate(model, settings, differentiable=True)
        return jnp.einsum("nij,nj->ni", traj.R[-1], traj.v[-1][:, :3])[:, 2].mean()

    value, gradient = jax.jit(final_vz), jax.jit(jax.grad(final_vz))
    grad = float(gradient(model).contact_damping)
    h = 1e-5 * 0.3
    fd = float(value(model.replace(contact_damping=jnp.asarray(0.3 + h)))
               - value(model.replace(contact_damping=jnp.asarray(0.3 - h)))) / (2 * h)
    assert abs(grad) > 0.0
    assert grad == pytest.approx(fd, rel=1e-4)


@pytest.mark.parametrize("value, message", [(-0.1, "must be in [0, 100]"),
                                            ("1", "must be a number")])
def test_damping_ratio_is_validated_naming_the_field(value, message):
    scene = _scene(0.0)
    scene["contact"]["damping_ratio"] = value
    with pytest.raises(ValueError, match=r"contact\.damping_ratio") as error:
        sj.Scene.from_dict(scene)
    assert message in str(error.value)


def test_no_damping_ratio_is_the_undamped_model():
    """``damping_ratio = 0`` (the default) builds no damping (the undamped contact)."""
    assert sj.build_model(sj.Scene.from_dict(_scene(0.0))).contact_damping is None
    assert float(sj.build_model(sj.Scene.from_dict(_scene(0.4))).contact_damping) == 0.4


def test_stiff_impact_the_step_cannot_resolve_stands_when_damped():
    """The drop of tests/test_dynamics_limits.py on k = 1e9 N/m^2 (contact time 7e-5 s,
    below a tenth of the smallest sub-step dt/64: undamped, the run stops with the cause
    contact_unresolved), critically damped: the steps over the impact stand unless they
    throw the rod back, the run converges, and the rod never rises above its drop height
    h0 after the impact (no energy gained; gravity's potential bounds it) and is back on
    the floor at the end (within 2 % of h0)."""
    h0 = 0.05
    scene = dropped_rod_scene(1e9, h0, R_CONTACT)
    scene["contact"]["damping_ratio"] = 1.0
    res = sj.run(scene)
    assert res.converged
    z = res.positions("rod")[..., 2]
    assert z.max() <= h0 + 1e-12
    impact = int(np.argmax(res.contacts["floor"]["max_penetration"] > 0.0))
    assert impact > 0 and z[impact:].max() < h0
    assert np.abs(z[-1]).max() < 0.02 * h0          # back on the floor (centre at z = 0)
