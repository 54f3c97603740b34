"""Rod-rod contact in dynamics (issue 14, ``[contact] self = true``, generalized-alpha with
rho_inf = 1, no damping, no gravity): two free rods crossing at right angles collide and
separate. References derived here: the total energy (kinetic + strain + the pair
penalty, a conservative potential) is kept; the rods leave with the velocities of an
elastic collision of two rigid bodies of their masses (momentum and energy balance);
Newton's third law holds in the result's ``contacts.rods`` entry at every saved time.
"""
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import simsoft_jax as sj
from simsoft_jax.couplings import rod_pairs
from simsoft_jax.solvers.dynamics.rollout import energy

N, L, R_C, V0 = 4, 0.2, 0.005, 0.01           # elements, m, m, m/s
RHO_TOP, RHO_BOTTOM = 2.0, 1.0                 # kg/m
POINTS = 4
REDUCED = RHO_TOP * RHO_BOTTOM * L / (RHO_TOP + RHO_BOTTOM)   # kg, rigid reduced mass
T_CONTACT = 0.2                                # s: pi sqrt(mu / (l k)), l = L/(N POINTS)
K = REDUCED * (np.pi / T_CONTACT) ** 2 / (L / N / POINTS)     # N/m^2


def _rod(name, along_y, z, rho_a):
    return {"name": name, "elements": N, "geometry": {"kind": "straight", "length": L},
            "base": {"position": [0.0, -L / 2, z] if along_y else [-L / 2, 0.0, z],
                     "rotation": [0.0, 0.0, np.pi / 2 if along_y else 0.0]},
            "stiffness": {"EA": 1e5, "GAy": 1e5, "GAz": 1e5, "GJ": 1.0, "EIy": 1.0,
                          "EIz": 1.0},
            "inertia": {"rhoA": rho_a, "rhoJ": 1e-5, "rhoIy": 5e-6, "rhoIz": 5e-6}}


SCENE = {"solver": {"kind": "dynamic", "t_end": 0.4, "dt": 0.01, "rho_inf": 1.0},
         "rods": [_rod("top", False, 2 * R_C + 1e-3, RHO_TOP), _rod("bottom", True, 0.0, RHO_BOTTOM)],
         "initial_velocity": [{"rod": "top", "linear": [0.0, 0.0, -V0], "angular": [0, 0, 0]},
                              {"rod": "bottom", "linear": [0.0, 0.0, V0], "angular": [0, 0, 0]}],
         "contact": {"radius": R_C, "self": True, "max_pairs": 4, "stiffness": K,
                     "quadrature_points": POINTS}}


@pytest.fixture(scope="module")
def collision():
    result = sj.run(SCENE)
    assert result.converged, result.message
    return result


def test_crossing_rods_collide_and_keep_their_energy(collision):
    """Kinetic + strain + pair-penalty energy within 1 % of the start's kinetic energy
    ``(m_top + m_bottom) v0^2 / 2`` at every saved time; the contact does happen (the
    penalty holds energy at some time) and ends (none at the end); no sub-steps."""
    res = collision
    assert int(np.max(res.raw.substeps)) == 1
    model = res.model

    def total(R, p, v):
        return energy(model, R, p, v) + rod_pairs.energy(model, R, p), rod_pairs.energy(model, R, p)

    e, e_pen = (np.asarray(x) for x in jax.jit(jax.vmap(total))(
        jnp.asarray(res._R), jnp.asarray(res._p), jnp.asarray(res.raw.v)))
    start = 0.5 * (RHO_TOP + RHO_BOTTOM) * L * V0**2
    np.testing.assert_allclose(e, start, rtol=1e-2)
    assert e_pen.max() > 0.3 * start and e_pen[-1] == 0.0


def test_crossing_rods_leave_with_the_rigid_elastic_collision_velocities(collision):
    """After the contact the mean vertical velocities are those of an elastic collision of
    rigid bodies of masses rhoA L: ``v_top' = ((m1 - m2) v1 + 2 m2 v2)/(m1 + m2)`` with
    v1 = -v0, v2 = +v0 (v0/3 up) and ``v_bottom' = -5 v0 / 3`` (to 0.5 %: the rods' bending
    vibration keeps a little energy)."""
    res = collision
    m1, m2, v1, v2 = RHO_TOP * L, RHO_BOTTOM * L, -V0, V0
    expected = {"top": ((m1 - m2) * v1 + 2 * m2 * v2) / (m1 + m2),
                "bottom": ((m2 - m1) * v2 + 2 * m1 * v1) / (m1 + m2)}
    for rod, v_after in expected.items():
        world = np.einsum("nij,nj->ni", res.rotations(rod)[-1], res.velocities(rod)[-1][:, :3])
        assert world[:, 2].mean() == pytest.approx(v_after, rel=5e-3)


def test_rod_contact_forces_are_equal_and_opposite_at_every_time(collision):
    """Newton's third law in the result's ``contacts.rods`` (a leading time axis)."""
    entry = collision.contacts["rods"]
    top, bottom = np.asarray(entry["rod_force"]["top"]), np.asarray(entry["rod_force"]["bottom"])
    assert top.shape == (len(collision.time), 3)
    scale = np.abs(top).max()
    assert scale > 0.0
    np.testing.assert_allclose(top, -bottom, atol=1e-12 * scale)
    # the sum of the pairs' normal forces is the size of the force on a rod (one contact
    # point: the normals agree), to the slight tilt of the rods
    np.testing.assert_allclose(entry["normal_force"], np.linalg.norm(top, axis=1), rtol=1e-4,
                               atol=1e-9 * scale)
    assert top[:, 2].max() == pytest.approx(scale)       # the bottom rod pushes the top up


def test_more_pairs_than_max_pairs_end_the_run_with_a_status_naming_it(collision):
    """The collision's model (``max_pairs = 4``) with the bottom rod turned under the top
    one, parallel to it, 1 mm short of touching as in the collision: each top element
    faces two or three bottom ones, far more element pairs than 4. The run stops at its
    first step with the status ``contact_pairs`` (as the cause of the step halved below its
    minimum) and a message naming ``[contact] max_pairs``; the states kept are finite.
    The structure is the collision's, so the rollout is the program compiled for it
    (``max_pairs`` is part of a structure: a scene of its own would compile another)."""
    model = collision.model
    rods = {rod.name: rod for rod in model.structure.rods}
    top, bottom = (slice(rods[n].first_node, rods[n].first_node + rods[n].nodes)
                   for n in ("top", "bottom"))
    p0, R0 = np.array(model.p0), np.array(model.R0)
    p0[bottom], R0[bottom] = p0[top] - [0.0, 0.0, 2 * R_C + 1e-3], R0[top]
    run = sj.simulate(model.replace(p0=p0, R0=R0),
                      sj.DynamicSettings(dt=0.01, steps=2, rho_inf=1.0))
    assert not bool(np.all(run.converged))
    assert sj.Status.CONTACT_PAIRS in (sj.Status(int(run.status)), sj.Status(int(run.cause)))
    assert "[contact] max_pairs" in run.message()
    assert np.all(np.isfinite(run.p))
