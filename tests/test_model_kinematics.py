"""Model building, element kinematics, element forces and assembly (simsoft_jax.model.model,
geometry, kinematics, element, assembly); spec: shared/spec/scene-format.md and
shared/spec/algorithm.md §3.1-§3.4, §3.6, §3.8 (S32-S44, S47, S50, S70).

Every reference is computed here, independently of the package: reference shapes in closed
form (line, circle, circular helix, polyline walk), SE(3) exponentials by scipy.linalg.expm,
SE(3) logarithms by scipy's rotation vector plus the closed-form inverse of the left Jacobian,
derivatives by central finite differences under right (body) perturbations
``H <- H expm(hat(xi))``, xi = [linear; angular].
"""
import copy
import dataclasses

import numpy as np
import pytest
from scipy.integrate import simpson
from scipy.linalg import expm
from scipy.spatial.transform import Rotation

import simsoft_jax as sj  # enables float64
import jax
import jax.numpy as jnp
from simsoft_jax.physics import assembly, element
from simsoft_jax.analysis import kinematics
from simsoft_jax.math import linalg
from conftest import rot_z, skew

# Load parts of a Model, None when the scene has no load of that kind (and gravity)
PARTS = ("nodal_dead", "nodal_follower", "distributed_world", "distributed_local", "gravity")

AL_E, AL_G, AL_RHO = 71.7e9, 27.37e9, 2679.0  # aluminum_7075 (scene-format.md)

# jitted once here: eager calls of these small kernels dispatch (and compile) op by op
frame_in_element = jax.jit(kinematics.frame_in_element)
element_twists = jax.jit(kinematics.element_twists)
curvature_torsion = jax.jit(kinematics.curvature_torsion)
sample_shape = jax.jit(kinematics.sample_shape, static_argnums=2)
relative_twist = jax.jit(element.relative_twist)
strain_map = jax.jit(element.strain_map)
internal_force = jax.jit(element.internal_force)


# ----------------------------------------------------------------------------- references
def hat(xi):
    X = np.zeros((4, 4))
    X[:3, :3], X[:3, 3] = skew(xi[3:]), xi[:3]
    return X


def pose(R, p):
    H = np.eye(4)
    H[:3, :3], H[:3, 3] = R, p
    return H


def exp_se3(xi):
    return expm(hat(np.asarray(xi, float)))


def log_se3(H):
    """[U; w] with w the rotation vector of H's rotation and U = V(w)^-1 p (closed form)."""
    w = Rotation.from_matrix(H[:3, :3]).as_rotvec()
    th = np.linalg.norm(w)
    W = skew(w)
    if th < 1e-4:
        c = 1.0 / 12.0 + th**2 / 720.0
    else:
        c = (1.0 - th * np.sin(th) / (2.0 * (1.0 - np.cos(th)))) / th**2
    Vinv = np.eye(3) - 0.5 * W + c * W @ W
    return np.r_[Vinv @ H[:3, 3], w]


def rotvec(v):
    return Rotation.from_rotvec(np.asarray(v, float)).as_matrix()


def random_rotation(rng):
    return Rotation.random(random_state=rng).as_matrix()


def arr(x):
    return np.asarray(x, float)


# ----------------------------------------------------------------------------- scenes
def rod(name="arm", elements=4, geometry=None, **extra):
    r = {"name": name, "material": "aluminum_7075",
         "section": {"shape": "rectangle", "width": 3.2e-3, "height": 12.4e-3},
         "elements": elements,
         "geometry": geometry or {"kind": "straight", "length": 0.5}}
    r.update(extra)
    return r


def scene(rods, constraints=None, loads=(), gravity=None, kind="static"):
    d = {"solver": {"kind": kind}, "rods": list(rods),
         "constraints": list(constraints if constraints is not None
                             else [{"kind": "clamp", "rod": r["name"], "node": 0}
                                   for r in rods]),
         "loads": list(loads)}
    if kind == "dynamic":
        d["solver"].update(t_end=1.0, dt=0.01)
    if gravity is not None:
        d["gravity"] = {"vector": list(gravity)}
    return sj.Scene.from_dict(copy.deepcopy(d))


def build(*args, **kwargs):
    return sj.build_model(scene(*args, **kwargs))


# ============================================================================ 1. geometry
def test_straight_rod_with_rotated_shifted_base():
    L, n = 0.7, 4
    pb, rv = [0.3, -1.0, 2.0], [0.4, -0.7, 1.1]
    m = build([rod(elements=n, geometry={"kind": "straight", "length": L},
                   base={"position": pb, "rotation": rv})])
    Rb = rotvec(rv)
    s = np.linspace(0.0, L, n + 1)
    np.testing.assert_allclose(arr(m.p0), arr(pb) + s[:, None] * Rb[:, 0], atol=1e-14)
    np.testing.assert_allclose(arr(m.R0), np.broadcast_to(Rb, (n + 1, 3, 3)), atol=1e-14)
    d0 = np.zeros((n, 6))
    d0[:, 0] = L / n
    np.testing.assert_allclose(arr(m.d0), d0, atol=1e-14)
    np.testing.assert_allclose(arr(m.length), np.full(n, L / n), rtol=1e-14)


def test_base_rotation_axis_angle_form():
    axis, deg = np.array([1.0, 2.0, -2.0]) / 3.0, 70.0
    m = build([rod(base={"rotation": {"axis": [1.0, 2.0, -2.0], "angle_deg": deg}})])
    np.testing.assert_allclose(arr(m.R0[0]), rotvec(axis * np.deg2rad(deg)), atol=1e-14)


def test_arc_nodes_on_circle_and_exact_twists():
    r, a_deg, n = 0.4, 120.0, 4
    pb, rv = [1.0, 2.0, 3.0], [0.3, -0.2, 0.5]
    m = build([rod(elements=n, geometry={"kind": "arc", "radius": r, "angle_deg": a_deg},
                   base={"position": pb, "rotation": rv})])
    Rb = rotvec(rv)
    total = r * np.deg2rad(a_deg)
    s = np.linspace(0.0, total, n + 1)
    local = np.stack([r * np.sin(s / r), r * (1.0 - np.cos(s / r)), 0.0 * s], axis=1)
    np.testing.assert_allclose(arr(m.p0), arr(pb) + local @ Rb.T, atol=1e-14)
    # frames: tangent = local x, bending toward local +y, local z = the circle's normal
    R_ref = np.array([Rb @ rot_z(si / r) for si in s])
    np.testing.assert_allclose(arr(m.R0), R_ref, atol=1e-14)
    tangent = np.stack([np.cos(s / r), np.sin(s / r), 0.0 * s], axis=1) @ Rb.T
    np.testing.assert_allclose(arr(m.R0)[:, :, 0], tangent, atol=1e-14)
    Le = total / n
    np.testing.assert_allclose(arr(m.length), np.full(n, Le), rtol=1e-13)
    d0 = np.tile(Le * np.array([1.0, 0.0, 0.0, 0.0, 0.0, 1.0 / r]), (n, 1))
    np.testing.assert_allclose(arr(m.d0), d0, rtol=1e-12, atol=1e-14)


def test_full_circle_arc_closes():
    r, n = 0.25, 4
    m = build([rod(elements=n, geometry={"kind": "arc", "radius": r, "angle_deg": 360.0})])
    np.testing.assert_allclose(arr(m.p0[-1]), arr(m.p0[0]), atol=1e-13)
    np.testing.assert_allclose(arr(m.R0[-1]), arr(m.R0[0]), atol=1e-13)
    np.testing.assert_allclose(arr(m.length).sum(), 2 * np.pi * r, rtol=1e-13)


def helix_reference(radius, pitch, s):
    """Closed-form circular helix in the rod's base frame, starting at the origin along x,
    curving toward +y (principal normal = local y). Returns (positions, R columns t, n, b, axis)."""
    a, b = radius, pitch / (2.0 * np.pi)
    rho = np.hypot(a, b)
    axis = np.array([b, 0.0, a]) / rho                # Darboux direction (tau, 0, kappa)
    e_r0 = np.array([0.0, -1.0, 0.0])                 # from the axis to the start point
    e_q = np.cross(axis, e_r0)
    th = s / rho
    centre = a * np.array([0.0, 1.0, 0.0])            # a point of the axis
    radial = np.cos(th)[:, None] * e_r0 + np.sin(th)[:, None] * e_q
    p = centre + (b * th)[:, None] * axis + a * radial
    t = ((b / rho) * axis + (a / rho) * (-np.sin(th)[:, None] * e_r0 + np.cos(th)[:, None] * e_q))
    nrm = -radial
    R = np.stack([t, nrm, np.cross(t, nrm)], axis=2)
    return p, R, axis, centre


def test_helix_nodes_frames_lengths_and_curvature():
    radius, pitch, turns, n = 0.05, 0.03, 2.0, 8
    pb, rv = [0.1, 0.2, -0.3], [-0.5, 0.2, 0.9]
    m = build([rod(elements=n, geometry={"kind": "helix", "radius": radius, "pitch": pitch,
                                         "turns": turns},
                   base={"position": pb, "rotation": rv})])
    Rb = rotvec(rv)
    total = turns * np.hypot(2 * np.pi * radius, pitch)
    np.testing.assert_allclose(arr(m.length).sum(), total, rtol=1e-13)
    np.testing.assert_allclose(arr(m.length), np.full(n, total / n), rtol=1e-13)

    s = np.linspace(0.0, total, n + 1)
    p_ref, R_ref, axis, centre = helix_reference(radius, pitch, s)
    p = (arr(m.p0) - arr(pb)) @ Rb          # back to the base frame
    np.testing.assert_allclose(p, p_ref, atol=1e-13)
    np.testing.assert_allclose(np.einsum("ij,njk->nik", Rb.T, arr(m.R0)), R_ref, atol=1e-12)

    # geometric fit: constant distance from the axis, rise per turn = pitch
    w = p - centre
    h = w @ axis
    np.testing.assert_allclose(np.linalg.norm(w - h[:, None] * axis, axis=1), radius, rtol=1e-12)
    per_turn = n / turns                    # 4 elements per turn
    k = int(round(per_turn))
    np.testing.assert_allclose(arr(m.p0[k]) - arr(m.p0[0]), pitch * (Rb @ axis), atol=1e-13)
    np.testing.assert_allclose(h[k:] - h[:-k], pitch, rtol=1e-11)

    b = pitch / (2 * np.pi)
    kappa, tau = radius / (radius**2 + b**2), b / (radius**2 + b**2)
    for d0 in np.asarray(m.d0):
        k_e, t_e = curvature_torsion(jnp.asarray(d0))
        np.testing.assert_allclose([float(k_e), float(t_e)], [kappa, tau], rtol=1e-12)


def test_left_turning_helix_zero_pitch_is_a_circle():
    radius, n = 0.1, 4
    m = build([rod(elements=n, geometry={"kind": "helix", "radius": radius, "pitch": 0.0,
                                         "turns": 1.0})])
    np.testing.assert_allclose(arr(m.p0[-1]), arr(m.p0[0]), atol=1e-13)
    k_e, t_e = curvature_torsion(m.d0[0])
    np.testing.assert_allclose([float(k_e), float(t_e)], [1.0 / radius, 0.0], atol=1e-12)


def walk_polyline(points, s):
    """Point at arc length s along a polyline, and the index of its segment."""
    seg = np.diff(points, axis=0)
    lengths = np.linalg.norm(seg, axis=1)
    cum = np.r_[0.0, np.cumsum(lengths)]
    j = min(np.searchsorted(cum, s, side="right") - 1, len(seg) - 1)
    return points[j] + (s - cum[j]) / lengths[j] * seg[j], j


def test_polyline_nodes_and_frames():
    pts = np.array([[0.0, 0.0, 0.0], [0.12, 0.0, 0.0], [0.12, 0.09, 0.0],
                    [0.12, 0.09, 0.15], [0.2, 0.15, 0.15]])
    seg = np.diff(pts, axis=0)
    dirs = seg / np.linalg.norm(seg, axis=1, keepdims=True)
    total = np.linalg.norm(seg, axis=1).sum()
    n = 8
    m = build([rod(elements=n, geometry={"kind": "polyline", "points": pts.tolist()})])
    p, R = arr(m.p0), arr(m.R0)
    s = np.linspace(0.0, total, n + 1)
    for i, si in enumerate(s):
        ref, j = walk_polyline(pts, si)
        np.testing.assert_allclose(p[i], ref, atol=1e-14)
        # local x close to the polyline direction of the segment(s) the node lies on
        assert R[i][:, 0] @ dirs[j] > np.cos(np.deg2rad(50.0))
    # at nodes whose neighbours lie on the same segment, local x is that segment's direction
    exact = 0
    for i in range(1, n):
        _, ja = walk_polyline(pts, s[i - 1] + 1e-12)
        _, jb = walk_polyline(pts, s[i + 1] - 1e-12)
        if ja == jb:
            np.testing.assert_allclose(R[i][:, 0], dirs[ja], atol=1e-12)
            exact += 1
    assert exact >= 2
    np.testing.assert_allclose(R[0][:, 0], dirs[0], atol=1e-12)
    np.testing.assert_allclose(R[-1][:, 0], dirs[-1], atol=1e-12)
    # orthonormal, right-handed
    np.testing.assert_allclose(np.einsum("nji,njk->nik", R, R),
                               np.broadcast_to(np.eye(3), R.shape), atol=1e-13)
    np.testing.assert_allclose(np.linalg.det(R), 1.0, atol=1e-13)
    # d0 = log(H_i^-1 H_i+1) of the stress-free frames (S33, S34), length = |d0_U| (S35)
    d0 = np.array([log_se3(np.linalg.inv(pose(R[i], p[i])) @ pose(R[i + 1], p[i + 1]))
                   for i in range(n)])
    np.testing.assert_allclose(arr(m.d0), d0, atol=1e-12)
    np.testing.assert_allclose(arr(m.length), np.linalg.norm(d0[:, :3], axis=1), rtol=1e-13)


def test_initial_points_change_start_but_not_stress_free_twists():
    L, n = 0.4, 4
    init = [[0.0, 0.0, 0.0], [0.2, 0.0, 0.0], [0.2, 0.0, -0.2]]
    m = build([rod(elements=n, geometry={"kind": "straight", "length": L},
                   initial={"points": init})])
    d0 = np.zeros((n, 6))
    d0[:, 0] = L / n
    np.testing.assert_allclose(arr(m.d0), d0, atol=1e-14)
    s = np.linspace(0.0, 0.4, n + 1)
    ref = np.array([walk_polyline(np.array(init), si)[0] for si in s])
    np.testing.assert_allclose(arr(m.p0), ref, atol=1e-14)


# ============================================================================ 2. kinematics
def test_sample_shape_reproduces_arc_between_nodes():
    r, a_deg, n, k = 0.3, 150.0, 4, 7
    pb, rv = [0.0, 1.0, -1.0], [0.2, 0.6, -0.4]
    m = build([rod(elements=n, geometry={"kind": "arc", "radius": r, "angle_deg": a_deg},
                   base={"position": pb, "rotation": rv})])
    R_s, p_s = sample_shape(m.R0, m.p0, k)
    assert p_s.shape == (n * k + 1, 3) and R_s.shape == (n * k + 1, 3, 3)
    Rb = rotvec(rv)
    s = np.linspace(0.0, r * np.deg2rad(a_deg), n * k + 1)
    local = np.stack([r * np.sin(s / r), r * (1.0 - np.cos(s / r)), 0.0 * s], axis=1)
    np.testing.assert_allclose(arr(p_s), arr(pb) + local @ Rb.T, atol=1e-14)
    np.testing.assert_allclose(arr(R_s), np.array([Rb @ rot_z(si / r) for si in s]),
                               atol=1e-13)


def random_twist(rng, lin=1.0, ang=2.0):
    d = rng.normal(size=6)
    d[:3] *= lin / np.linalg.norm(d[:3])
    d[3:] *= rng.uniform(0.2, ang) / np.linalg.norm(d[3:])
    return d


def test_forward_and_inverse_kinematics():
    rng = np.random.default_rng(1)
    for _ in range(5):
        d = random_twist(rng, lin=rng.uniform(0.1, 2.0), ang=2.8)
        RA, pA = random_rotation(rng), rng.normal(size=3)
        for f in (0.0, 0.37, 1.0):
            Rf, pf = frame_in_element(jnp.asarray(RA), jnp.asarray(pA),
                                                 jnp.asarray(d), f)
            H = pose(RA, pA) @ exp_se3(f * d)
            np.testing.assert_allclose(arr(Rf), H[:3, :3], atol=1e-13)
            np.testing.assert_allclose(arr(pf), H[:3, 3], atol=1e-13)
        RB, pB = frame_in_element(jnp.asarray(RA), jnp.asarray(pA),
                                             jnp.asarray(d), 1.0)
        got = element_twists(jnp.stack([jnp.asarray(RA), RB]),
                                        jnp.stack([jnp.asarray(pA), pB]))
        assert got.shape == (1, 6)
        np.testing.assert_allclose(arr(got[0]), d, atol=1e-12)
        # and relative_twist agrees with the independent logarithm
        H_B = pose(RA, pA) @ exp_se3(d)
        np.testing.assert_allclose(
            arr(relative_twist(jnp.asarray(RA), jnp.asarray(pA),
                                       jnp.asarray(H_B[:3, :3]), jnp.asarray(H_B[:3, 3]))),
            log_se3(np.linalg.inv(pose(RA, pA)) @ H_B), atol=1e-12)


@pytest.mark.parametrize("d", [
    [0.3, 0.05, -0.02, 0.4, -0.3, 0.6],
    [1.2, -0.3, 0.4, -0.8, 1.1, 0.2],
    [0.5, 0.0, 0.0, 0.0, 0.0, 0.9],     # planar arc: zero torsion
])
def test_curvature_torsion_against_frenet_finite_differences(d):
    d = np.asarray(d, float)
    rng = np.random.default_rng(7)
    RA, pA = jnp.asarray(random_rotation(rng)), jnp.asarray(rng.normal(size=3))
    x0, h = 0.45, 1e-3
    xs = x0 + h * np.arange(-2, 3)
    pos = np.asarray(jax.vmap(lambda f: frame_in_element(RA, pA, jnp.asarray(d), f)[1])(
        jnp.asarray(xs)))
    p1 = (pos[3] - pos[1]) / (2 * h)
    p2 = (pos[3] - 2 * pos[2] + pos[1]) / h**2
    p3 = (pos[4] - 2 * pos[3] + 2 * pos[1] - pos[0]) / (2 * h**3)
    c = np.cross(p1, p2)
    kappa = np.linalg.norm(c) / np.linalg.norm(p1) ** 3
    tau = c @ p3 / (c @ c)
    k_e, t_e = curvature_torsion(jnp.asarray(d))
    scale = np.linalg.norm(d[3:]) / np.linalg.norm(d[:3])
    np.testing.assert_allclose(float(k_e), kappa, rtol=1e-5)
    np.testing.assert_allclose(float(t_e), tau, atol=1e-5 * scale)
    np.testing.assert_allclose(np.hypot(float(k_e), float(t_e)), scale, rtol=1e-13)


def test_curvature_torsion_of_straight_element_is_zero_and_finite():
    k_e, t_e = curvature_torsion(jnp.array([0.2, 0, 0, 0, 0, 0.0]))
    assert float(k_e) == 0.0 and float(t_e) == 0.0
    g = jax.grad(lambda d: sum(curvature_torsion(d)))(jnp.array([0.2, 0, 0, 0, 0, 0.0]))
    assert np.all(np.isfinite(np.asarray(g)))


# ============================================================================ 3. model tables
def test_load_tables_and_constraint_masks_two_rods():
    arc = {"kind": "arc", "radius": 0.3, "angle_deg": 90.0}
    arc_len = 0.3 * np.pi / 2
    f1, m1, f2, m2 = [1.0, 2.0, 3.0], [4.0, 5.0, 6.0], [-1.0, 0.5, 0.25], [0.1, -0.2, 0.3]
    v1, v2, qw, ql = [7.0, 0.0, -1.0], [0.0, 2.0, 1.0], [0.0, 0.0, -3.0], [0.5, 0.0, 0.0]
    sc = scene(
        [rod("a", elements=4), rod("b", elements=4, geometry=arc,
                                   base={"position": [0.0, 1.0, 0.0]})],
        constraints=[{"kind": "clamp", "rod": "a", "node": 0},
                     {"kind": "pin", "rod": "a", "node": -1},
                     {"kind": "drive", "rod": "b", "node": 1, "times": [0.0, 1.0],
                      "rotation": [[0, 0, 0], [0, 0.5, 0]]},
                     {"kind": "pin", "rod": "b", "s": arc_len}],
        loads=[{"kind": "force", "rod": "a", "node": -1, "vector": f1},
               {"kind": "moment", "rod": "a", "node": 1, "vector": m1, "frame": "world"},
               {"kind": "force", "rod": "b", "node": 0, "vector": f2, "frame": "local"},
               {"kind": "moment", "rod": "b", "s": arc_len * 0.55, "vector": m2,
                "frame": "local"},
               {"kind": "force", "rod": "b", "node": -2, "vector": v1},
               {"kind": "force", "rod": "b", "node": 3, "vector": v2},
               {"kind": "distributed_force", "rod": "a", "vector": qw},
               {"kind": "distributed_force", "rod": "b", "vector": ql, "frame": "local"}],
        kind="dynamic")                        # a static scene rejects a moving drive
    m = sj.build_model(sc)
    st = m.structure
    # node numbering: rod a nodes 0..4, rod b nodes 5..9; elements 0..3 and 4..7
    a, b = st.rod("a"), st.rod("b")
    assert (a.first_node, a.nodes, a.first_element, a.elements) == (0, 5, 0, 4)
    assert (b.first_node, b.nodes, b.first_element, b.elements) == (5, 5, 4, 4)
    assert st.n_nodes == 10 and st.n_elements == 8
    assert tuple(st.element_nodes) == (0, 1, 2, 3, 5, 6, 7, 8)
    assert 4 not in st.element_nodes           # no element joins a's tip to b's base
    assert m.R0.shape == (10, 3, 3) and m.p0.shape == (10, 3) and m.d0.shape == (8, 6)
    np.testing.assert_allclose(arr(m.p0[5]), [0.0, 1.0, 0.0], atol=1e-15)
    np.testing.assert_allclose(arr(m.p0[4]), [0.5, 0.0, 0.0], atol=1e-15)
    np.testing.assert_allclose(arr(m.p0[9]), [0.3, 1.3, 0.0], atol=1e-14)
    np.testing.assert_allclose(arr(m.d0[:4, 0]), np.full(4, 0.125), rtol=1e-14)
    np.testing.assert_allclose(arr(m.d0[4:, 5]), np.full(4, np.pi / 8), rtol=1e-13)

    dead = np.zeros((10, 6))
    dead[4, :3] = f1
    dead[1, 3:] = m1
    dead[8, :3] = np.add(v1, v2)               # node -2 of b is node 3 of b: they add up
    follower = np.zeros((10, 6))
    follower[5, :3] = f2
    np.testing.assert_allclose(arr(m.nodal_dead), dead, atol=0)
    np.testing.assert_allclose(arr(m.nodal_follower), follower, atol=0)
    point = np.zeros((8, 6))
    point[6, 3:] = m2                          # s = 0.55 of the arc: element 2 of b, xi 0.2
    np.testing.assert_allclose(arr(m.element_point_follower), point, atol=0)
    np.testing.assert_allclose(arr(m.element_point_xi[6]), 0.2, rtol=1e-12)
    assert m.element_point_follower is not None and m.element_point_dead is None
    dw, dl = np.zeros((8, 3)), np.zeros((8, 3))
    dw[:4] = qw
    dl[4:] = ql
    np.testing.assert_allclose(arr(m.distributed_world), dw, atol=0)
    np.testing.assert_allclose(arr(m.distributed_local), dl, atol=0)
    assert [getattr(m, k) is not None for k in PARTS] == [True, True, True, True, False]

    free = np.ones((10, 6), bool)
    free[0] = False                 # clamp
    free[4, :3] = False             # pin: position held, rotation free
    free[6] = False                 # drive: clamped node that moves
    free[9, :3] = False             # pin at s = arc length (the tip)
    assert len(st.free) == 60
    np.testing.assert_array_equal(np.array(st.free).reshape(10, 6), free)
    np.testing.assert_array_equal(np.asarray(st.free_mask()), free.astype(float))


def test_load_parts_only_for_load_kinds_present():
    m = build([rod()], loads=[{"kind": "force", "rod": "arm", "node": -1,
                               "vector": [0, 0, 1.0], "frame": "local"}])
    assert [getattr(m, k) is not None for k in PARTS] == [False, True, False, False, False]
    assert m.channels.nodal_follower is not None and m.channels.nodal_dead is None


def test_gravity_part_only_when_gravity_table_exists():
    assert build([rod()]).gravity is None
    m = build([rod()], gravity=[0.0, 0.0, -9.81])
    np.testing.assert_allclose(arr(m.gravity), [0.0, 0.0, -9.81])
    # a [gravity] table is a structural choice even when its vector is zero
    np.testing.assert_array_equal(arr(build([rod()], gravity=[0.0, 0.0, 0.0]).gravity), 0.0)


def test_stiffness_from_section_material_and_override():
    w, h = 3.2e-3, 12.4e-3
    K_over = {"EA": 2.842e6, "GAy": 0.6401e6, "GAz": 0.9039e6, "GJ": 3.104, "EIy": 36.28,
              "EIz": 2.429}
    m = build([rod("a", elements=4),
               rod("b", elements=4, stiffness=K_over),
               rod("c", elements=4, shear_coefficients=[0.59, 0.833])])
    K = arr(m.stiffness)
    assert K.shape == (12, 6)
    material = sj.get_material("aluminum_7075")
    section = sj.rectangle(w, h)
    np.testing.assert_allclose(K[:4], np.tile(sj.stiffness_diagonal(section, material), (4, 1)),
                               rtol=1e-15)
    # closed forms: EA = E w h, EIy = E w h^3/12 (height along local z), EIz = E h w^3/12
    np.testing.assert_allclose(K[0, [0, 4, 5]],
                               [AL_E * w * h, AL_E * w * h**3 / 12, AL_E * h * w**3 / 12],
                               rtol=1e-12)
    np.testing.assert_allclose(K[4:8], np.tile(list(K_over.values()), (4, 1)), rtol=0)
    np.testing.assert_allclose(K[8:, 1:3],
                               np.tile([AL_G * 0.59 * w * h, AL_G * 0.833 * w * h], (4, 1)),
                               rtol=1e-12)
    np.testing.assert_allclose(arr(m.inertia[:, 0]), AL_RHO * w * h, rtol=1e-12)


# ============================================================================ 4. element
def perturbed(H, xi):
    return H @ exp_se3(xi)


def element_d(HA, HB, x):
    """d = log((H_A exp xA)^-1 (H_B exp xB)) by the independent logarithm."""
    return log_se3(np.linalg.inv(perturbed(HA, x[:6])) @ perturbed(HB, x[6:]))


def random_element(rng):
    HA = pose(random_rotation(rng), rng.normal(size=3))
    d = random_twist(rng, lin=0.3, ang=1.2)
    HB = HA @ exp_se3(d)
    d0 = d + 0.1 * rng.normal(size=6)
    L = 0.3
    K = rng.uniform(0.5, 5.0, size=6)
    return HA, HB, d, d0, L, K


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_internal_force_is_energy_gradient(seed):
    rng = np.random.default_rng(seed)
    HA, HB, d, d0, L, K = random_element(rng)

    def energy(x):
        eps = (element_d(HA, HB, x) - d0) / L
        return 0.5 * L * eps @ (K * eps)

    hstep = 1e-6
    grad = np.array([(energy(hstep * e) - energy(-hstep * e)) / (2 * hstep)
                     for e in np.eye(12)])
    dj = jnp.asarray(d)
    P = strain_map(dj)
    f = internal_force(P, dj, jnp.asarray(d0), L, jnp.asarray(K))
    assert f.shape == (12,)
    np.testing.assert_allclose(arr(f), grad, rtol=0, atol=1e-7 * np.abs(grad).max())
    # self-equilibrated: the element's world force and moment (about the origin) vanish
    RA, RB = HA[:3, :3], HB[:3, :3]
    fa, fb = arr(f[:6]), arr(f[6:])
    np.testing.assert_allclose(RA @ fa[:3] + RB @ fb[:3], 0.0, atol=1e-12 * np.abs(f).max())
    moment = (RA @ fa[3:] + np.cross(HA[:3, 3], RA @ fa[:3])
              + RB @ fb[3:] + np.cross(HB[:3, 3], RB @ fb[:3]))
    np.testing.assert_allclose(moment, 0.0, atol=1e-12 * np.abs(f).max() * 10)


@pytest.mark.parametrize("seed", [3, 4])
def test_strain_map_matches_finite_differences(seed):
    rng = np.random.default_rng(seed)
    HA, HB, d, *_ = random_element(rng)
    hstep = 1e-6
    P_fd = np.stack([(element_d(HA, HB, hstep * e) - element_d(HA, HB, -hstep * e))
                     / (2 * hstep) for e in np.eye(12)], axis=1)
    P = arr(strain_map(jnp.asarray(d)))
    assert P.shape == (6, 12)
    np.testing.assert_allclose(P, P_fd, atol=1e-8)


def tangent_scene():
    return scene(
        [rod(elements=4, geometry={"kind": "arc", "radius": 0.6, "angle_deg": 40.0},
             base={"position": [0.1, 0.0, 0.2], "rotation": [0.2, -0.4, 0.3]},
             stiffness={"EA": 50.0, "GAy": 30.0, "GAz": 40.0, "GJ": 0.8, "EIy": 1.5,
                        "EIz": 2.5})],
        gravity=[0.5, -3.0, -9.81],
        loads=[{"kind": "force", "rod": "arm", "node": -1, "vector": [0.3, -0.5, 1.2]},
               {"kind": "moment", "rod": "arm", "node": -1, "vector": [0.2, 0.4, -0.3]},
               {"kind": "force", "rod": "arm", "node": 2, "vector": [-0.7, 0.2, 0.4],
                "frame": "local"},
               {"kind": "distributed_force", "rod": "arm", "vector": [0.0, 1.0, 0.5]},
               {"kind": "distributed_force", "rod": "arm", "vector": [0.3, 0.0, -0.6],
                "frame": "local"}])


def test_assembled_tangent_matches_finite_differences_and_block_solve():
    m = sj.build_model(tangent_scene())
    st = m.structure
    assert m.gravity is not None and m.nodal_dead is not None and m.nodal_follower is not None
    n = st.n_nodes
    rng = np.random.default_rng(11)
    H = [pose(R, p) @ exp_se3(0.15 * rng.normal(size=6))
         for R, p in zip(arr(m.R0), arr(m.p0))]
    R = np.array([h[:3, :3] for h in H])
    p = np.array([h[:3, 3] for h in H])
    lam = 0.7
    res = jax.jit(lambda R, p: assembly.residual(m, R, p, lam))
    r, blocks = jax.jit(lambda R, p: assembly.residual_and_tangent(m, R, p, lam))(R, p)
    np.testing.assert_allclose(arr(r), arr(res(R, p)), atol=1e-13)
    Kt = arr(linalg.dense(blocks))
    assert Kt.shape == (6 * n, 6 * n)

    hstep = 1e-6
    K_fd = np.zeros((6 * n, 6 * n))
    for i in range(n):
        for j in range(6):
            e = np.zeros(6)
            e[j] = hstep
            cols = []
            for sign in (1, -1):
                Hi = H[i] @ exp_se3(sign * e)
                Rp, pp = R.copy(), p.copy()
                Rp[i], pp[i] = Hi[:3, :3], Hi[:3, 3]
                cols.append(arr(res(Rp, pp)).ravel())
            K_fd[:, 6 * i + j] = (cols[0] - cols[1]) / (2 * hstep)

    free = np.array(st.free)
    held = ~free
    assert held.sum() == 6
    Kff, Kfd_ff = Kt[np.ix_(free, free)], K_fd[np.ix_(free, free)]
    np.testing.assert_allclose(Kff, Kfd_ff, rtol=0, atol=1e-6 * np.abs(Kfd_ff).max())
    # not symmetric in general (dead moment, follower force, non-equilibrium state)
    assert np.abs(Kff - Kff.T).max() > 1e-4 * np.abs(Kff).max()
    # held dofs: identity rows and columns, zero residual
    np.testing.assert_array_equal(Kt[held][:, held], np.eye(6))
    np.testing.assert_array_equal(Kt[held][:, free], 0.0)
    np.testing.assert_array_equal(Kt[free][:, held], 0.0)
    np.testing.assert_array_equal(arr(r).ravel()[held], 0.0)

    b = rng.normal(size=(n, 6))
    x = arr(jax.jit(linalg.block_solve)(blocks, jnp.asarray(b)))
    np.testing.assert_allclose(x.ravel(), np.linalg.solve(Kt, b.ravel()), rtol=1e-10,
                               atol=1e-12 * np.abs(x).max())
    np.testing.assert_allclose(arr(linalg.block_matvec(blocks, jnp.asarray(x))), b, atol=1e-10)


# ============================================================================ 5. statics
def test_static_equilibrium_global_balance():
    """Clamped rod under gravity + dead tip force and moment: the clamp reaction (the
    unmasked residual at node 0) balances the resultant of the external loads."""
    L, n, dia = 0.5, 8, 2e-3
    F, M, g = np.array([0.01, 0.02, -0.05]), np.array([0.0, 0.003, 0.001]), np.array([0, 0, -9.81])
    sc = scene([{"name": "arm", "material": "aluminum_7075",
                 "section": {"shape": "circle", "diameter": dia}, "elements": n,
                 "geometry": {"kind": "straight", "length": L},
                 "base": {"position": [0.0, 0.0, 1.0], "rotation": [0.0, -0.3, 0.2]}}],
               gravity=g,
               loads=[{"kind": "force", "rod": "arm", "node": -1, "vector": F.tolist()},
                      {"kind": "moment", "rod": "arm", "node": -1, "vector": M.tolist()}])
    m = sj.build_model(sc)
    eq = sj.solve_static(m)
    assert bool(eq.converged)
    R, p = arr(eq.R), arr(eq.p)
    np.testing.assert_allclose(R[0], arr(m.R0[0]), atol=1e-14)   # clamp held
    np.testing.assert_allclose(p[0], arr(m.p0[0]), atol=1e-14)
    rho_a = AL_RHO * np.pi * dia**2 / 4
    q = rho_a * g
    F_total = F + q * L                                      # gravity on the reference length
    tip = p[-1] - p[0]
    assert np.linalg.norm(tip - L * arr(m.R0[0])[:, 0]) > 0.02 * L   # visibly deformed

    all_free = dataclasses.replace(m.structure, free=(True,) * (6 * m.structure.n_nodes))
    m_free = m.replace(structure=all_free)
    r = arr(jax.jit(lambda R, p: assembly.residual(m_free, R, p, 1.0))(eq.R, eq.p))
    scale = np.linalg.norm(F_total)
    np.testing.assert_allclose(r[1:, :3], 0.0, atol=1e-8 * scale)
    # force balance: R_0 r_0[:3] = -(sum of external forces). Round-off floor: the axial
    # term EA (d - d0)/L with EA = 2.3e5 N gives ~1e-11 N per element (seen: 2e-10 N in all,
    # 4e-9 of the loads), so 1e-7 relative; a wrong or missing load term is >= 1e-2.
    np.testing.assert_allclose(R[0] @ r[0, :3], -F_total, rtol=0, atol=1e-7 * scale)
    # moment balance about the clamp, gravity integrated along the helical interpolation
    _, p_s = sample_shape(eq.R, eq.p, 32)
    p_s = arr(p_s)
    s = np.linspace(0.0, L, len(p_s))
    lever = simpson(p_s - p[0], x=s, axis=0)
    M_total = np.cross(tip, F) + M + np.cross(lever, q)
    np.testing.assert_allclose(R[0] @ r[0, 3:], -M_total, rtol=0,
                               atol=1e-8 * np.linalg.norm(M_total))
