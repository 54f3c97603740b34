"""Attached masses (``[[masses]]``) and forces at offset points (load ``offset``): weight as
a dead force at a point that turns with the section, inertia with the offset's gyroscopic
terms, exact Euler-Bernoulli tip-mass frequencies, gradients by finite differences."""
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import simsoft_jax as sj
from simsoft_jax.physics import assembly, inertia
from simsoft_jax.math import lie, linalg
from simsoft_jax.physics.terms import masses as mass_term

from conftest import rot_x, rot_y, rot_z

L, EI, RHOA = 1.0, 2.0, 0.5
G = np.array([0.0, 0.0, -9.81])
OFFSET = [0.05, 0.3, -0.1]
MASS = 0.4


def cantilever(elements=8, masses=(), loads=(), gravity=True, kind="static"):
    d = {"solver": {"kind": "static", "tolerance": 1e-12},
         "rods": [{"name": "arm", "elements": elements,
                   "geometry": {"kind": "straight", "length": L},
                   "stiffness": {"EA": 1e6, "GAy": 1e6, "GAz": 1e6, "GJ": 1.5, "EIy": EI,
                                 "EIz": 3.0},
                   "inertia": {"rhoA": RHOA, "rhoJ": 0.0, "rhoIy": 0.0, "rhoIz": 0.0}}],
         "constraints": [{"kind": "clamp", "rod": "arm", "node": 0}],
         "masses": list(masses), "loads": list(loads)}
    if gravity:
        d["gravity"] = {"vector": G.tolist()}
    if kind == "dynamic":
        d["solver"] = {"kind": "dynamic", "t_end": 0.01, "dt": 0.01}
    return d


def build(d):
    return sj.build_model(sj.Scene.from_dict(d))


TIP_MASS = {"rod": "arm", "node": -1, "mass": MASS, "offset": OFFSET}


@pytest.fixture(scope="module")
def tip_mass_equilibrium():
    model = build(cantilever(masses=[TIP_MASS]))
    eq = sj.solve_static(model)
    assert bool(eq.converged)
    return model, eq


def test_offset_weight_is_force_plus_moment_at_the_deformed_pose(tip_mass_equilibrium):
    """The equilibrium with the offset mass satisfies, to round-off, the equations of the
    same rod loaded by the force m g at the tip node plus the dead moment
    ``(R_tip c) x m g`` computed at that deformed pose; without the moment it does not."""
    model, eq = tip_mass_equilibrium
    R_tip = np.asarray(eq.R[-1])
    assert np.linalg.norm(lie.log_so3(eq.R[-1])) > 0.3          # a large rotation
    weight = MASS * G
    moment = np.cross(R_tip @ np.array(OFFSET), weight)
    force_load = {"kind": "force", "rod": "arm", "node": -1, "vector": weight.tolist()}
    moment_load = {"kind": "moment", "rod": "arm", "node": -1, "vector": moment.tolist()}
    with_moment = build(cantilever(loads=[force_load, moment_load]))
    without = build(cantilever(loads=[force_load]))
    residual = jax.jit(assembly.residual)
    scale = MASS * 9.81
    r = np.asarray(residual(with_moment, eq.R, eq.p, 1.0))
    r0 = np.asarray(residual(without, eq.R, eq.p, 1.0))
    assert np.abs(r).max() < 1e-9 * scale
    assert np.abs(r0).max() > 1e-2 * scale
    # the same weight given as a world-frame force at an offset point (load ``offset``)
    offset_load = dict(force_load, offset=OFFSET)
    r1 = np.asarray(residual(build(cantilever(loads=[offset_load])), eq.R, eq.p, 1.0))
    assert np.abs(r1).max() < 1e-9 * scale
    # and a follower force at an offset is the force plus the constant moment c x F
    follower = build(cantilever(loads=[dict(force_load, frame="local", offset=OFFSET)]))
    plain = build(cantilever(loads=[dict(force_load, frame="local"),
                                    {"kind": "moment", "rod": "arm", "node": -1,
                                     "frame": "local",
                                     "vector": np.cross(OFFSET, weight).tolist()}]))
    np.testing.assert_array_equal(np.asarray(follower.nodal_follower),
                                  np.asarray(plain.nodal_follower))


def test_gradients_wrt_mass_and_offset_match_finite_differences(tip_mass_equilibrium):
    model, _ = tip_mass_equilibrium

    def tip(m, c):
        eq = sj.solve_static(model.replace(mass=m, mass_offset=c))
        return eq.p[-1, 2] + 0.3 * eq.p[-1, 1]

    m0, c0 = model.mass, model.mass_offset
    value_and_grad = jax.jit(jax.value_and_grad(tip, argnums=(0, 1)))   # one compile
    _, (gm, gc) = value_and_grad(m0, c0)

    def f(m, c):
        return value_and_grad(m, c)[0]

    h = 1e-6
    fd_m = (f(m0 + h, c0) - f(m0 - h, c0)) / (2 * h)
    np.testing.assert_allclose(np.asarray(gm), np.asarray(fd_m), rtol=1e-5)
    for j in range(3):
        e = jnp.zeros_like(c0).at[0, j].set(h)
        fd = (f(m0, c0 + e) - f(m0, c0 - e)) / (2 * h)
        np.testing.assert_allclose(float(gc[0, j]), float(fd), rtol=1e-5,
                                   atol=1e-7 * float(jnp.abs(gc).max()))


def test_inertial_force_matches_newton_euler_of_a_prescribed_motion():
    """Independent check of the mass term's inertia and gyroscopic force: a node moves
    along a prescribed path ``p(t), R(t)``; the centre ``x = p + R c`` has the acceleration
    ``x''`` (central differences); the force on the node's frame is ``R^T m x''`` and the
    moment about the node ``c x R^T m x'' + J wdot + w x J w`` (Euler, about the centre)."""
    m, c = 0.7, np.array([0.1, -0.2, 0.05])
    J = np.array([[2e-3, 1e-4, 0.0], [1e-4, 3e-3, -2e-4], [0.0, -2e-4, 1e-3]])

    def pose(t):
        R = rot_z(0.8 * t + 0.3 * t**2) @ rot_y(0.5 * np.sin(2 * t)) @ rot_x(0.2 * t)
        p = np.array([np.sin(t), 0.3 * t**2, np.cos(1.5 * t)])
        return R, p

    t, h = 0.37, 1e-4
    (R0, p0), (R1, p1), (R2, p2) = pose(t - h), pose(t), pose(t + h)
    x = [p + R @ c for R, p in ((R0, p0), (R1, p1), (R2, p2))]
    acc = (x[2] - 2 * x[1] + x[0]) / h**2
    # body velocities [v; w] (section frame) by central differences, and their rates
    def body_velocity(t):
        (Ra, pa), (Rb, pb) = pose(t - h), pose(t + h)
        R, _ = pose(t)
        W = R.T @ (Rb - Ra) / (2 * h)
        return np.concatenate([R.T @ (pb - pa) / (2 * h), [W[2, 1], W[0, 2], W[1, 0]]])

    V = body_velocity(t)
    Vdot = (body_velocity(t + h) - body_velocity(t - h)) / (2 * h)
    w, wdot = V[3:], Vdot[3:]
    force = R1.T @ (m * acc)
    moment = np.cross(c, force) + J @ wdot + np.cross(w, J @ w)
    got = np.asarray(mass_term.inertial_force(jnp.asarray(V), jnp.asarray(Vdot), m,
                                              jnp.asarray(c), jnp.asarray(J)))
    np.testing.assert_allclose(got, np.concatenate([force, moment]), rtol=0, atol=2e-5)


def tip_mass_frequency_exact(ratio):
    """Lowest root beta of the Euler-Bernoulli cantilever with a tip point mass
    ``M = ratio * rhoA L``: ``1 + cos b cosh b + ratio b (cos b sinh b - sin b cosh b) = 0``
    (clamped root w = w' = 0; tip moment 0 and shear EI w''' = -M omega^2 w), by bisection.
    omega = b^2 sqrt(EI / (rhoA L^4))."""
    def f(b):
        return (1 + np.cos(b) * np.cosh(b)
                + ratio * b * (np.cos(b) * np.sinh(b) - np.sin(b) * np.cosh(b)))
    lo, hi = 0.1, 1.875104069
    assert f(lo) * f(hi) < 0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if f(lo) * f(mid) <= 0 else (mid, hi)
    return 0.5 * (lo + hi)


@pytest.mark.slow
def test_tip_mass_cantilever_frequency_matches_euler_bernoulli():
    """Small-amplitude frequency of a clamped rod with a tip mass (20 elements): the
    generalized eigenvalues of the tangent K and the mass matrix (element masses plus the
    mass term's ``M6``) at the stress-free state, against the exact tip-mass frequency
    equation (derived above), to 0.5 %."""
    ratio = 0.6
    mass = {"rod": "arm", "node": -1, "mass": ratio * RHOA * L}
    model = build(cantilever(elements=20, masses=[mass], gravity=False, kind="dynamic"))
    R, p = model.R0, model.p0
    _, blocks = jax.jit(assembly.residual_and_tangent)(model, R, p)
    K = np.asarray(linalg.dense(blocks))
    _, masses = inertia.element_inertia(model.d0, model.length, model.inertia, "consistent")
    s = model.structure
    mblocks = assembly.assemble_blocks(s.n_nodes, s.element_nodes, masses)
    zeros = jnp.zeros((s.n_nodes, 6))
    attached = assembly.attachments_and_tangents(model, 1.0, R, zeros, zeros, dynamic=True)
    mblocks = (mblocks[0] + attached[3],) + mblocks[1:]
    M = np.asarray(linalg.dense(mblocks))
    free = np.asarray(s.free_mask()).ravel() > 0
    Kf, Mf = K[np.ix_(free, free)], M[np.ix_(free, free)]
    # rotary inertia is zero (rhoJ, rhoIy, rhoIz = 0): condense the massless rotations
    lin = np.tile([True, True, True, False, False, False], s.n_nodes)[free]
    rot = ~lin
    Kc = Kf[np.ix_(lin, lin)] - Kf[np.ix_(lin, rot)] @ np.linalg.solve(
        Kf[np.ix_(rot, rot)], Kf[np.ix_(rot, lin)])
    Mc = Mf[np.ix_(lin, lin)]
    omega2 = np.sort(np.real(np.linalg.eigvals(np.linalg.solve(Mc, Kc))))
    beta = tip_mass_frequency_exact(ratio)
    exact = beta**2 * np.sqrt(EI / (RHOA * L**4))
    omega = np.sqrt(omega2[omega2 > 0][0])
    assert abs(omega / exact - 1) < 5e-3, (omega, exact)
    assert beta < 1.5    # the tip mass lowers it well below the bare 1.8751


def test_masses_validated_with_key_paths():
    bad = [({"mass": -1.0}, r"masses\[0\]\.mass: must be > 0"),
           ({"offset": [0.0, 1.0]}, r"masses\[0\]\.offset: must have 3 entries"),
           ({"inertia": [[1, 2, 0], [0, 1, 0], [0, 0, 1]]}, r"masses\[0\]\.inertia: must be symm"),
           ({"inertia": [[1, 0, 0], [0, -1, 0], [0, 0, 1]]}, r"masses\[0\]\.inertia: must be pos"),
           ({"node": 99}, r"masses\[0\]\.node: out of range"),
           ({"rod": "nope"}, r"masses\[0\]\.rod: no rod named"),
           ({"color": 1}, r"masses\[0\]\.color: unknown key")]
    for change, message in bad:
        with pytest.raises(ValueError, match=message):
            sj.Scene.from_dict(cantilever(masses=[dict(TIP_MASS, **change)]))
    with pytest.raises(ValueError, match=r"loads\[0\]\.offset: only a force"):
        sj.Scene.from_dict(cantilever(loads=[{"kind": "moment", "rod": "arm", "node": -1,
                                              "vector": [0, 0, 1], "offset": [0, 1, 0]}]))
    with pytest.raises(ValueError, match=r"loads\[0\]\.offset: a world-frame force"):
        sj.Scene.from_dict(cantilever(loads=[{"kind": "force", "rod": "arm", "node": -1,
                                              "vector": [0, 0, 1], "offset": [0, 1, 0],
                                              "profile": {"kind": "ramp", "t1": 1.0}}]))
