"""Curved tube obstacles (issue 14): the signed distance against a brute-force distance to
a finely sampled centreline and its gradients against central finite differences, and a
rod pushed into a curved rigid tube against the closed form of a compressed rod lying on
the tube's outer wall.
"""
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import simsoft_jax as sj
from simsoft_jax.physics import assembly, obstacles
from simsoft_jax.physics.element import relative_twist
from simsoft_jax.scene.scene_contact import parameter_row
from simsoft_jax.physics.terms import contact

# ---------------------------------------------------------------- signed distance
CENTER, NORMAL = np.array([0.1, -0.2, 0.3]), np.array([1.0, 2.0, 2.0]) / 3.0
E1 = np.array([2.0, -2.0, 1.0]) / 3.0          # unit, normal to NORMAL
BEND, ANGLE, RADIUS = 0.5, 2.0, 0.05
ROW = parameter_row("curved_tube", dict(center=CENTER, normal=NORMAL * 2.0, radius=RADIUS,
                                        start=CENTER + BEND * E1, angle=ANGLE))


def brute_force_distance(x):
    """Distance of x from the centreline sampled densely: an inlet, the arc and an outlet
    of 2 m each (the arc written from its angle, the straight parts from the end points
    and tangents of the arc)."""
    t0 = np.cross(NORMAL, E1)
    arc = lambda a: CENTER + BEND * (np.cos(a) * E1 + np.sin(a) * t0)  # noqa: E731
    tangent = lambda a: np.cos(a) * t0 - np.sin(a) * E1                # noqa: E731
    s = np.linspace(0.0, 2.0, 200001)[:, None]
    a = np.linspace(0.0, ANGLE, 200001)[:, None]
    pts = np.concatenate([arc(0.0) - s * tangent(0.0), arc(a),
                          arc(ANGLE) + s * tangent(ANGLE)])
    return np.sqrt(np.min(np.sum((pts - x) ** 2, axis=1)))


@pytest.fixture(scope="module")
def points():
    """Points inside the tube and a little outside, near the inlet, the bend and the
    outlet (and on both sides of the arc plane)."""
    rng = np.random.default_rng(3)
    t0 = np.cross(NORMAL, E1)
    out = []
    for a in (-0.3, 0.0, 0.4, 1.0, 1.7, 2.0, 2.4):       # polar angle along the bend
        if a < 0.0:    # inlet: a length back along -t0 from the start
            base = CENTER + BEND * E1 + a * BEND * t0
        elif a > ANGLE:
            end = CENTER + BEND * (np.cos(ANGLE) * E1 + np.sin(ANGLE) * t0)
            base = end + (a - ANGLE) * BEND * (np.cos(ANGLE) * t0 - np.sin(ANGLE) * E1)
        else:
            base = CENTER + BEND * (np.cos(a) * E1 + np.sin(a) * t0)
        out.append(base + rng.uniform(-1.5 * RADIUS, 1.5 * RADIUS, 3))
    return np.array(out)


def test_curved_tube_distance_matches_a_sampled_centreline(points):
    """phi = radius - (distance to the inlet + arc + outlet centreline), against the
    nearest of 6e5 samples of that centreline (sample spacing 1e-5 m: the brute force is
    good to ~1e-9 m at these distances), to 1e-8 m."""
    f = jax.jit(jax.vmap(lambda x: obstacles.signed_distance("curved_tube",
                                                             jnp.asarray(ROW), x)))
    phi = np.asarray(f(jnp.asarray(points)))
    expected = RADIUS - np.array([brute_force_distance(x) for x in points])
    assert np.abs(expected).max() > 0.02 and (expected < 0).any() and (expected > 0).any()
    np.testing.assert_allclose(phi, expected, atol=1e-8)


def test_curved_tube_gradients_match_finite_differences(points):
    """Gradients in the point (a unit vector) and in all 11 row parameters (centre,
    normal, radius, start, angle) against central differences (step 1e-6), to 1e-7."""
    f = jax.jit(lambda x, row: obstacles.signed_distance("curved_tube", row, x))
    g = jax.jit(jax.grad(f, argnums=(0, 1)))
    row = jnp.asarray(ROW)
    for x in points:
        gx, gp = g(jnp.asarray(x), row)
        assert float(jnp.linalg.norm(gx)) == pytest.approx(1.0, abs=1e-12)
        full = np.concatenate([x, ROW])
        fd = []
        for i in range(14):
            e = np.zeros(14)
            e[i] = 1e-6
            plus, minus = full + e, full - e
            fd.append((float(f(jnp.asarray(plus[:3]), jnp.asarray(plus[3:])))
                       - float(f(jnp.asarray(minus[:3]), jnp.asarray(minus[3:])))) / 2e-6)
        np.testing.assert_allclose(np.concatenate([gx, gp]), fd, atol=1e-7)


def test_curved_tube_gradient_is_finite_on_its_centreline_and_axis():
    """On the centreline (distance 0) and on the bend's axis (|u| = 0) the gradient is
    finite (safe norms)."""
    g = jax.grad(lambda x, row: obstacles.signed_distance("curved_tube", row, x), (0, 1))
    for x in (CENTER + BEND * E1, CENTER, CENTER + 0.3 * NORMAL):
        gx, gp = g(jnp.asarray(x), jnp.asarray(ROW))
        assert np.isfinite(gx).all() and np.isfinite(gp).all()


# ---------------------------------------------------------------- a rod pushed into the bend
N, EI, EA, R_CONTACT = 40, 1.0, 1.0e6, 0.005
R_BEND, R_TUBE = 0.1, 0.01
RHO = R_BEND + R_TUBE - R_CONTACT        # the rod's centreline on the outer wall, m
L_ROD, SQUEEZE = 0.15, 5.0e-4            # stress-free length; its shortening on the arc


def pushed_scene():
    """A rod of stress-free length L, pushed into an arc of the outer wall of length
    (1 - SQUEEZE) L: started on that arc with its sections normal to it, both ends
    clamped where they start (tangent to the wall)."""
    phi = np.linspace(0.0, (1.0 - SQUEEZE) * L_ROD / RHO, N + 1)
    c, s, z = np.cos(phi), np.sin(phi), 0 * phi
    points = np.stack([RHO * s, RHO * (1.0 - c), z], 1)
    rotations = np.stack([np.stack([c, -s, z], 1), np.stack([s, c, z], 1),
                          np.stack([z, z, z + 1], 1)], 1)      # about z by phi
    return {
        "solver": {"kind": "static"},
        "rods": [{"name": "rod", "elements": N,
                  "geometry": {"kind": "straight", "length": L_ROD},
                  "stiffness": {"EA": EA, "GAy": 1e6, "GAz": 1e6, "GJ": 1.0, "EIy": EI,
                                "EIz": EI},
                  "inertia": {"rhoA": 1.0, "rhoJ": 1e-6, "rhoIy": 1e-6, "rhoIz": 1e-6},
                  "initial": {"points": points.tolist(), "rotations": rotations.tolist()}}],
        "constraints": [{"kind": "clamp", "rod": "rod", "node": 0},
                        {"kind": "clamp", "rod": "rod", "node": -1}],
        "obstacles": [{"name": "vessel", "kind": "curved_tube", "center": [0.0, RHO, 0.0],
                       "normal": [0.0, 0.0, 1.0], "start": [0.0, RHO - R_BEND, 0.0],
                       "angle": np.pi, "radius": R_TUBE}],
        "contact": {"radius": R_CONTACT}}


@pytest.mark.slow     # one static solve with contact, mostly compiling (~75 s at load 11)
def test_rod_pushed_into_a_curved_tube_takes_its_curvature():
    """A straight rod (EI, EA) pushed into a bend whose outer wall leaves it an arc
    shorter than the rod by the fraction SQUEEZE is compressed, N = EA SQUEEZE, and
    pressed outwards: it lies on the outer wall, an arc of radius rho = R + a - r (bend
    radius R, tube radius a, rod radius r) of curvature 1/rho, with the bending moment
    M = EI/rho constant, so no shear force, and the compression turned by the wall's line
    load q = N/rho (n' + q = 0). Without the tube the compressed rod would bulge out of
    the arc. Checked to 1e-3 of the closed forms: the curvature from the node rotations
    and positions and the bending moment EI kappa_z of the element strains 3 elements away
    from the clamps (where the clamps, on the arc, meet the rod resting slightly deeper
    in the penalty), the contact line load on the middle half (the soft cubic start of
    the penalty spreads those boundary layers over a few elements), the axial force
    EA eps_x on all elements (its closed form with the rod's sinking delta into the
    penalty, which lengthens the arc: delta/rho = 2.9e-6 relieves 0.6 % of the
    compression); the penetration below 1e-3 r."""
    result = sj.run(pushed_scene(), stability=False)
    assert result.converged, result.message
    p, R = result.positions("rod"), result.rotations("rod")
    angle = np.array([np.arccos(np.clip((np.trace(R[i].T @ R[i + 1]) - 1) / 2, -1, 1))
                      for i in range(N)])
    chord = np.linalg.norm(np.diff(p, axis=0), axis=1)
    inner = slice(3, N - 3)
    np.testing.assert_allclose(angle[inner] / chord[inner] * RHO, 1.0, atol=1e-3)
    h = L_ROD / N
    d = np.asarray(jax.vmap(relative_twist)(R[:-1], p[:-1], R[1:], p[1:]))
    np.testing.assert_allclose(EI * d[inner, 5] / h * RHO / EI, 1.0, atol=1e-3)
    # the rod sinks into the wall's penalty by delta (cubic start: q = k delta^2/(2 eps)),
    # which lengthens its arc by delta/rho and relieves the compression by EA delta/rho
    k, eps = float(result.model.contact_stiffness[0]), contact.SMOOTHING * R_CONTACT
    delta = 0.0
    for _ in range(50):
        compression = EA * (1.0 - (1.0 - SQUEEZE) * (1.0 + delta / RHO))
        delta = np.sqrt(2.0 * eps * compression / (RHO * k))
    assert delta < eps
    np.testing.assert_allclose(-EA * (d[:, 0] / h - 1.0) / compression, 1.0, atol=1e-3)
    model = result.model
    _, normal, _ = jax.vmap(lambda RA, pA, dd, data, length: contact.summary(
        RA, pA, dd, data, length, ("curved_tube",), model.structure.contact_points))(
        R[:-1], p[:-1], d, assembly.contact_data(model), model.length)
    middle = slice(N // 4, 3 * N // 4)
    np.testing.assert_allclose(np.asarray(normal)[middle, 0] / h * RHO / compression, 1.0,
                               atol=1e-3)
    assert float(result.contacts["vessel"]["max_penetration"]) < 1e-3 * R_CONTACT


@pytest.mark.parametrize("change,message", [
    ({"start": [0.0, RHO, 0.0]}, "obstacles[0].start: must differ from center"),
    ({"start": [0.0, RHO - R_BEND, 0.01]}, "obstacles[0].start: start - center must be normal"),
    ({"radius": 0.2}, "obstacles[0].radius: must be below the bend radius"),
    ({"angle": 7.0}, "obstacles[0].angle: must be in (0, 2 pi)"),
    ({"angle": 0.0}, "obstacles[0].angle: must be > 0"),
    ({"axis": [1.0, 0.0, 0.0]}, "obstacles[0].axis: unknown key"),
])
def test_bad_curved_tube_is_rejected_naming_the_key(change, message):
    scene = pushed_scene()
    scene["obstacles"][0].update(change)
    with pytest.raises(ValueError, match=message.replace("[", r"\[").replace("]", r"\]")
                       .replace("(", r"\(").replace(")", r"\)")):
        sj.Scene.from_dict(scene)
