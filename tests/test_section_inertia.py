"""Full 6x6 section inertia with an offset centre of mass (``inertia = { matrix = ... }``,
:func:`simsoft_jax.scene.sections.inertia_matrix`): the diagonal path kept bit for bit, the
kinetic energy of a rigid segment, the weight's twist of a cantilever whose centre of
mass is off its axis (:mod:`simsoft_jax.physics.terms.offset_gravity`), a free spinning rod
falling under gravity against the rigid-body solution, both tangent paths, bad input."""
import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import simsoft_jax as sj
from simsoft_jax.physics import assembly, inertia
from simsoft_jax.math import lie, linalg
from simsoft_jax.model import loads
from simsoft_jax.scene import sections
from simsoft_jax.solvers.dynamics import element_inertia
from simsoft_jax.physics.terms import element_state, offset_gravity

from conftest import iteration_matrices, rot_x

L, RHOA, GJ, EI, GA = 1.0, 0.5, 2.0, 3.0, 1e4
CENTRE = np.array([0.0, 0.04, -0.02])                # centre of mass (m), section frame
J_C = np.array([[2e-4, 0.0, 0.0], [0.0, 1e-4, 2e-5], [0.0, 2e-5, 1.5e-4]])  # kg m, x principal
DIAG = {"rhoA": RHOA, "rhoJ": 3e-4, "rhoIy": 1e-4, "rhoIz": 2e-4}
G_STATIC = 0.00981                                   # m/s^2: a small load (linear theory)


def offset_matrix():
    return sections.offset_inertia(RHOA, CENTRE[1:], J_C)


def cantilever(inertia_table, elements=6, segments=None):
    rod = {"name": "arm", "elements": elements, "geometry": {"kind": "straight", "length": L},
           "stiffness": {"EA": 1e5, "GAy": GA, "GAz": GA, "GJ": GJ, "EIy": EI, "EIz": EI},
           "inertia": inertia_table}
    if segments is not None:     # each segment with the rod's stiffness
        rod["segments"] = [{**seg, "stiffness": rod["stiffness"]} for seg in segments]
        rod = {k: v for k, v in rod.items() if k not in ("elements", "inertia", "stiffness")}
    return {"solver": {"kind": "static", "tolerance": 1e-12}, "rods": [rod],
            "constraints": [{"kind": "clamp", "rod": "arm", "node": 0}],
            "gravity": {"vector": [0.0, 0.0, -G_STATIC]}}


def build(d):
    return sj.build_model(sj.Scene.from_dict(d))


@pytest.fixture(scope="module")
def offset_model():
    model = build(cantilever({"matrix": offset_matrix().tolist()}))
    s = model.structure
    assert s.coupled_inertia and s.inertia_offset and model.inertia.shape == (6, 6, 6)
    return model


# ------------------------------------------------------------------------ the helper, the table
def test_offset_inertia_helper_is_the_spatial_inertia_of_the_section():
    """``offset_inertia`` against the parallel-axis theorem written out: translational block
    ``rhoA I``, coupling ``rhoA skew(c)``, rotary ``J_c + rhoA (|c|^2 I - c c^T)``."""
    M = offset_matrix()
    c = CENTRE
    np.testing.assert_array_equal(M[:3, :3], RHOA * np.eye(3))
    np.testing.assert_allclose(M[3:, :3], RHOA * np.array(
        [[0, -c[2], c[1]], [c[2], 0, -c[0]], [-c[1], c[0], 0]]), rtol=0, atol=1e-18)
    np.testing.assert_allclose(M[3:, 3:], J_C + RHOA * (c @ c * np.eye(3) - np.outer(c, c)),
                               rtol=0, atol=1e-18)
    np.testing.assert_array_equal(M, M.T)
    assert np.linalg.eigvalsh(M).min() > 0.0
    # the centre of mass read back from the matrix
    np.testing.assert_allclose(np.asarray(inertia.centre_of_mass(jnp.asarray(M))), c,
                               rtol=1e-15, atol=1e-18)


def test_diagonal_matrix_is_bitwise_the_diagonal_path_and_mixed_segments():
    diag = np.array([RHOA, RHOA, RHOA, DIAG["rhoJ"], DIAG["rhoIy"], DIAG["rhoIz"]])
    m_diag = build(cantilever(DIAG))
    m_mat = build(cantilever({"matrix": np.diag(diag).tolist()}))
    assert m_mat.structure == m_diag.structure and not m_mat.structure.coupled_inertia
    assert m_mat.inertia.shape == (6, 6)
    assert np.array_equal(np.asarray(m_mat.inertia), np.asarray(m_diag.inertia))
    masses = [np.asarray(element_inertia(m).masses) for m in (m_diag, m_mat)]
    assert np.array_equal(masses[0], masses[1])
    # the (6,6) kernels on a diagonal matrix give the diagonal kernels' numbers: the
    # consistent mass matrices, and the lumped gyroscopic force (maps N0(0) = [I, 0],
    # N0(L) = [0, I] at the two nodes)
    full = np.broadcast_to(np.diag(diag), (6, 6, 6))  # (Model.replace keeps shapes)
    np.testing.assert_allclose(
        np.asarray(element_inertia(dataclasses.replace(m_diag, inertia=jnp.asarray(full))).masses),
        masses[0], rtol=1e-14, atol=1e-20)
    maps = jnp.asarray(np.eye(12).reshape(2, 6, 12))
    u = jnp.asarray(np.random.default_rng(0).standard_normal(12))
    a, b = (inertia.gyroscopic_force(maps, L / 6, jnp.asarray(x), u, "lumped")
            for x in (diag, full[0]))
    np.testing.assert_allclose(np.asarray(b), np.asarray(a), rtol=1e-14, atol=1e-18)
    # a rod of two segments, one centred (diagonal), one offset: every element (6,6)
    mixed = build(cantilever(None, segments=[
        {"elements": 2, "inertia": DIAG},
        {"elements": 4, "inertia": {"matrix": offset_matrix().tolist()}}]))
    table = np.asarray(mixed.inertia)
    assert table.shape == (6, 6, 6) and mixed.structure.inertia_offset
    assert np.array_equal(table[:2], np.broadcast_to(np.diag(diag), (2, 6, 6)))
    assert np.array_equal(table[2:], np.broadcast_to(offset_matrix(), (4, 6, 6)))


def test_kinetic_energy_of_a_rigid_segment(offset_model):
    """The straight rod moving rigidly (twist ``[v; w]`` of node 0, the matching rigid
    velocities at every node) has the kinetic energy of the rigid body: mass
    ``m = rhoA L``, centre of mass ``r_G = (L/2, cy, cz)``, inertia about it
    ``J_G = L J_c + rhoA L^3/12 diag(0, 1, 1)``: ``m |v + w x r_G|^2 / 2 + w^T J_G w / 2``.
    Exact for the consistent rule (4-point Gauss on polynomials of degree <= 6)."""
    model = offset_model
    masses = np.asarray(element_inertia(model).masses)          # (E, 12, 12)
    rng = np.random.default_rng(3)
    s = np.asarray(model.p0)[:, 0]
    for _ in range(3):
        v, w = rng.standard_normal(3), rng.standard_normal(3)
        nodes = np.array([np.concatenate([v + np.cross(w, [si, 0.0, 0.0]), w]) for si in s])
        ve = np.concatenate([nodes[:-1], nodes[1:]], axis=1)
        kinetic = 0.5 * np.einsum("ei,eij,ej->", ve, masses, ve)
        m, r_G = RHOA * L, np.array([L / 2, CENTRE[1], CENTRE[2]])
        J_G = L * J_C + RHOA * L**3 / 12 * np.diag([0.0, 1.0, 1.0])
        exact = 0.5 * m * np.sum((v + np.cross(w, r_G)) ** 2) + 0.5 * w @ J_G @ w
        np.testing.assert_allclose(kinetic, exact, rtol=1e-13)


# ------------------------------------------------------------------------------------ statics
def test_offset_weight_twists_the_cantilever(offset_model):
    """Horizontal cantilever along x, centre of mass at ``cy`` in the section, gravity -z:
    the weight per length ``rhoA g`` at the offset makes the torque ``-rhoA g cy`` per
    length, so the tip twists by ``-rhoA g cy L^2 / (2 GJ)`` (linear theory; nodal values
    of the helical elements are exact for it); the deflection is the centred section's
    (the same rod with ``c = 0``, through the same compiled solver)."""
    model = offset_model
    centred = model.replace(inertia=jnp.broadcast_to(
        jnp.asarray(sections.offset_inertia(RHOA, (0.0, 0.0), J_C)), model.inertia.shape))
    eq, eq0 = sj.solve_static(model), sj.solve_static(centred)
    assert bool(eq.converged) and bool(eq0.converged)
    twist = np.asarray(lie.log_so3(eq.R[-1]))[0]
    exact = -RHOA * G_STATIC * CENTRE[1] * L**2 / (2 * GJ)
    assert abs(exact) > 4e-5
    np.testing.assert_allclose(twist, exact, rtol=1e-4)     # nonlinear terms ~ cz twist / cy
    assert abs(np.asarray(lie.log_so3(eq0.R[-1]))[0]) < 1e-12
    tip, tip0 = np.asarray(eq.p[-1]), np.asarray(eq0.p[-1])
    assert tip0[2] < -2e-4
    # the lever arm of the weight shifts by cz times the bending slope: relative ~1e-5
    np.testing.assert_allclose(tip[[0, 2]], tip0[[0, 2]], rtol=1e-4)
    assert abs(tip[1]) < 1e-3 * abs(tip0[2])          # the twist tilts the bending, 2nd order


def deformed(model, seed, size=0.1):
    x = size * np.random.default_rng(seed).standard_normal((model.structure.n_nodes, 6))
    return jax.vmap(lie.compose_exp)(model.R0, model.p0, jnp.asarray(x))


def test_offset_weight_is_the_gradient_of_its_potential(offset_model):
    """The nodal forces of :mod:`~simsoft_jax.physics.terms.offset_gravity` at a configuration
    with large rotations are the gradient (right perturbations of the nodal frames) of the
    potential of the weight's offset, written here from the helical interpolation
    ``R(s) = R_A exp(xi d)`` directly: ``-lam int rhoA g . R(s) c ds`` (3-point Gauss, the
    rule of the loads); with ``c = 0`` they vanish."""
    model = offset_model.replace(gravity=jnp.array([0.0, -3.0, -9.81]))  # the same structure
    lam = 0.7
    R, p = deformed(model, 0, 0.5)
    s = model.structure
    x, wts = np.polynomial.legendre.leggauss(3)
    xi, wts = jnp.asarray(0.5 * (x + 1.0)), jnp.asarray(0.5 * wts)
    weight = RHOA * model.gravity

    @jax.jit
    def nodal_forces(model):
        zero = jnp.zeros(12)
        f = jax.vmap(lambda RA, pA, RB, pB, data: offset_gravity.force(
            element_state(RA, pA, RB, pB, zero, zero), data, lam))(
            *assembly.element_poses(model, R, p), offset_gravity.per_element(model))
        return assembly.assemble_vector(s.n_nodes, s.element_nodes, f)

    def element_potential(RA, pA, RB, pB, length):
        d = lie.log_se3(lie.relative_pose(RA, pA, RB, pB))
        rotations = jax.vmap(lambda x: lie.exp_so3(x * d[3:]))(xi)          # (3, 3, 3)
        return -lam * length * jnp.sum(wts * ((RA @ rotations @ CENTRE) @ weight))

    @jax.jit
    def gradient(y):
        def potential(y):
            Ry, py = jax.vmap(lie.compose_exp)(R, p, y)
            return jnp.sum(jax.vmap(element_potential)(Ry[:-1], py[:-1], Ry[1:], py[1:],
                                                       model.length))
        return jax.grad(potential)(y)

    grad = np.asarray(gradient(jnp.zeros((s.n_nodes, 6))))
    forces = np.asarray(nodal_forces(model))
    assert np.abs(grad).max() > 0.01
    np.testing.assert_allclose(forces, grad, rtol=0, atol=1e-14 * np.abs(grad).max())
    centred = model.replace(inertia=model.inertia.at[:, 3:, :3].set(0.0)
                            .at[:, :3, 3:].set(0.0))
    assert not np.any(np.asarray(nodal_forces(centred)))


@pytest.mark.slow
def test_tangent_paths_agree_with_the_offset_weight(offset_model):
    """Away from equilibrium, the closed-form and autodiff tangent paths give the same
    static residual and tangent, and the same dynamic residual and iteration matrix, with
    the offset inertia and its weight's moment (jacfwd on both paths)."""
    model = offset_model.replace(gravity=jnp.array([0.0, -3.0, -9.81]))  # the same structure
    R, p = deformed(model, 0, 0.03)
    tangent = jax.jit(assembly.residual_and_tangent, static_argnums=4)
    (r1, b1), (r2, b2) = (tangent(model, R, p, 0.7, t) for t in ("closed_form", "autodiff"))
    K1, K2 = np.asarray(linalg.dense(b1)), np.asarray(linalg.dense(b2))
    np.testing.assert_allclose(np.asarray(r1), np.asarray(r2), rtol=0,
                               atol=1e-13 * np.abs(np.asarray(r1)).max())
    np.testing.assert_allclose(K1, K2, rtol=0, atol=1e-11 * np.abs(K1).max())

    model = loads.loads_at(build(spinning_rod()), 0.0)
    (r1, S1), (r2, S2) = iteration_matrices(model, *deformed(model, 1))
    np.testing.assert_allclose(r1, r2, rtol=0, atol=1e-13 * np.abs(r1).max())
    np.testing.assert_allclose(S1, S2, rtol=0, atol=1e-11 * np.abs(S1).max())


# ----------------------------------------------------------------------------------- dynamics
W_SPIN, G_DYN = 2.0, 1.0


def spinning_rod():
    """A free rod spinning about its axis at ``W_SPIN`` (node 0 at rest, axis along x),
    centre of mass off the axis, falling under gravity -z."""
    return {"solver": {"kind": "dynamic", "t_end": 0.5, "dt": 0.025, "rho_inf": 1.0},
            "rods": [{"name": "arm", "elements": 4,
                      "geometry": {"kind": "straight", "length": L},
                      "stiffness": {"EA": 1e3, "GAy": 1e3, "GAz": 1e3, "GJ": 1.0, "EIy": 1.0,
                                    "EIz": 1.0},
                      "inertia": {"matrix": offset_matrix().tolist()}}],
            "initial_velocity": [{"rod": "arm", "angular": [W_SPIN, 0.0, 0.0]}],
            "gravity": {"vector": [0.0, 0.0, -G_DYN]}}


def rigid_solution(s, t):
    """Node positions (T, N, 3) of the exact motion: each section's centre of mass, on the
    axis through the body's centre of mass parallel to x (x is a principal axis of
    ``J_C``), falls freely from the velocity ``w e1 x c``, and the sections turn about it
    at the constant rate w with no internal force, so ``p(s, t) = s e1 + c + t (w e1 x c)
    + g t^2 / 2 - rot_x(w t) c``."""
    out = []
    for tk in t:
        shift = (CENTRE + tk * np.cross([W_SPIN, 0, 0], CENTRE)
                 + 0.5 * tk**2 * np.array([0, 0, -G_DYN]) - rot_x(W_SPIN * tk) @ CENTRE)
        out.append(np.outer(s, [1.0, 0.0, 0.0]) + shift)
    return np.array(out)


def test_free_spinning_rod_with_offset_centre_of_mass_follows_the_rigid_motion():
    """Node 0 starts at rest, so the axis traces a cycloid about the falling centre of mass
    (a centred section would spin in place); generalized-alpha (rho_inf = 1) reaches it to
    second order in dt: halving dt divides the error at t = 0.25 s by 4; the sections turn
    exactly as the rigid body (no internal force)."""
    model = build(spinning_rod())
    assert model.structure.inertia_offset
    s = np.asarray(model.p0)[:, 0]
    errors = []
    for dt in (0.025, 0.0125):
        traj = sj.simulate(model, sj.DynamicSettings(dt=dt, steps=20, rho_inf=1.0,
                                                     tolerance=1e-12))
        assert bool(traj.converged)
        t = np.asarray(traj.time)
        exact = rigid_solution(s, t)
        error = np.abs(np.asarray(traj.p) - exact).max(axis=(1, 2))
        errors.append(error[np.argmin(np.abs(t - 0.25))])
        np.testing.assert_allclose(np.asarray(traj.R[-1]),
                                   np.broadcast_to(rot_x(W_SPIN * t[-1]), (5, 3, 3)),
                                   rtol=0, atol=1e-11)
    tail = 0.5 * np.cross([W_SPIN, 0, 0], CENTRE) + CENTRE - rot_x(W_SPIN * 0.5) @ CENTRE
    assert np.abs(tail).max() > 100 * errors[0]      # the offset's share of the motion
    assert errors[0] < 1.5e-4 and 3.5 < errors[0] / errors[1] < 4.5, errors


# ------------------------------------------------------------------------------------- errors
def _with(**changes):
    M = offset_matrix()
    for (i, j), value in changes.get("entries", {}).items():
        M[i, j] = value
        if changes.get("symmetric", True):
            M[j, i] = value
    return M


@pytest.mark.parametrize("M, message", [
    (_with(entries={(0, 1): 1e-3}, symmetric=False), "must be symmetric"),
    (_with(entries={(1, 1): 0.6}), r"translational block \[0:3\]\[0:3\] must be rhoA I"),
    (_with(entries={(0, 2): 1e-3}), r"translational block .* entry \[0\]\[2\]"),
    (_with(entries={(0, 0): -0.5, (1, 1): -0.5, (2, 2): -0.5}), "rhoA must be > 0"),
    (_with(entries={(3, 1): 0.5 * 0.01}), r"coupling block \[3:6\]\[0:3\] must be rhoA skew"),
    (_with(entries={(4, 2): -0.005, (5, 1): 0.005}), "centre of mass c = \\(0, cy, cz\\)"),
    (_with(entries={(3, 3): 1e-5}), "rotary inertia about the centre of mass.*semi-definite"),
])
def test_bad_matrix_errors_name_the_field(M, message):
    with pytest.raises(ValueError, match=r"^rods\[0\]\.inertia\.matrix: .*" + message):
        sj.Scene.from_dict(cantilever({"matrix": M.tolist()}))


def test_bad_matrix_in_a_segment_and_bad_tables():
    bad = _with(entries={(1, 1): 0.6}).tolist()
    with pytest.raises(ValueError, match=r"^rods\[0\]\.segments\[1\]\.inertia\.matrix: "
                       r"the translational block"):
        sj.Scene.from_dict(cantilever(None, segments=[
            {"elements": 2, "inertia": DIAG}, {"elements": 4, "inertia": {"matrix": bad}}]))
    with pytest.raises(ValueError, match=r"rods\[0\]\.inertia\.rhoA: unknown key"):
        sj.Scene.from_dict(cantilever({"matrix": offset_matrix().tolist(), "rhoA": 1.0}))
    with pytest.raises(ValueError, match=r"rods\[0\]\.inertia\.matrix: must have 6 rows"):
        sj.Scene.from_dict(cantilever({"matrix": offset_matrix()[:5].tolist()}))
    with pytest.raises(ValueError, match=r"rods\[0\]\.inertia\.matrix\[2\]: must have 6"):
        sj.Scene.from_dict(cantilever({"matrix": [[0.0] * 6] * 2 + [[0.0] * 5] * 4}))
    with pytest.raises(ValueError, match=r"centre: must be \(cy, cz\)"):
        sections.offset_inertia(RHOA, (0.0, 0.1, 0.2))
