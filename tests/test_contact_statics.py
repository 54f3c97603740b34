"""Contact with rigid obstacles in statics (issue 14): a heavy rod lifted off a table and a
rod wrapped on a drum against beam theory derived here, the contact force against the
derivative of the penalty energy, the two tangent paths against each other, gradients
against central finite differences, signed distances against geometry, and the input
checks.

Both physical scenes share one structure (40 elements, a table and a drum, clamp at node
0, a dead force at the tip, gravity), so the static solver is compiled once.
"""
import json
import subprocess
import sys

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import simsoft_jax as sj
from simsoft_jax.physics import assembly, obstacles
from simsoft_jax.math import lie
from simsoft_jax.physics.terms import contact, element_state

N = 40
R_CONTACT = 0.01


def _scene(length, base, rotation, force, rho_a, gravity, table_z, drum, EI=1.0):
    return {
        "solver": {"kind": "static", "load_steps": 10},
        "gravity": {"vector": [0.0, 0.0, gravity]},
        "rods": [{"name": "rod", "elements": N, "geometry": {"kind": "straight", "length": length},
                  "base": {"position": base, "rotation": rotation},
                  "stiffness": {"EA": 1e9, "GAy": 1e9, "GAz": 1e9, "GJ": 1.0, "EIy": EI,
                                "EIz": EI},
                  "inertia": {"rhoA": rho_a, "rhoJ": 1e-6, "rhoIy": 1e-6, "rhoIz": 1e-6}}],
        "constraints": [{"kind": "clamp", "rod": "rod", "node": 0}],
        "loads": [{"kind": "force", "rod": "rod", "node": -1, "vector": [0.0, 0.0, force]}],
        "obstacles": [{"name": "table", "kind": "plane", "point": [0.0, 0.0, table_z],
                       "normal": [0.0, 0.0, 1.0]},
                      {"name": "drum", "kind": "cylinder", "axis_point": drum[0],
                       "axis": [0.0, 1.0, 0.0], "radius": drum[1]}],
        "contact": {"radius": R_CONTACT}}


# heavy rod on a table (plane at z = -r: the centreline rests at z = 0), lifted at x = 0
EI, Q, L_ROD = 1.0, 3.75, 1.0           # N m^2, N/m, m
F_LIFT = 0.75                            # N: lifted length 2F/q = 0.4 m
LIFT = _scene(L_ROD, [L_ROD, 0.0, 0.0], [0.0, 0.0, np.pi], F_LIFT, Q / 9.81, -9.81,
              -R_CONTACT, ([0.0, 0.0, -10.0], 1.0))
# rod clamped tangent to the top of a drum (axis y through the origin), pulled down at its tip
RC, F_WRAP = 0.1, 200.0
WRAP = _scene(0.25, [0.0, 0.0, RC + R_CONTACT], [0.0, 0.0, 0.0], -F_WRAP, 1.0, 0.0, -10.0,
              ([0.0, 0.0, 0.0], RC))

# a cantilever pressed by a tip force onto a drum below its middle (a smooth contact, away
# from the clamp: the scene of the gradient check)
LEAN = _scene(0.25, [0.0, 0.0, 0.0], [0.0, 0.0, 0.0], -5.0, 1.0, 0.0, -10.0,
              ([0.15, 0.0, -(RC + R_CONTACT + 0.002)], RC))


@pytest.fixture(scope="module")
def lifted():
    return sj.run(LIFT, stability=False)


@pytest.fixture(scope="module")
def wrapped():
    return sj.run(WRAP, stability=False)


def test_heavy_rod_lifted_off_a_table_matches_beam_theory(lifted):
    """Small-deflection beam theory of a heavy rod (weight q per length, EI) on a rigid
    table, lifted at its free end by a vertical force F. The lifted part 0 <= x <= l
    leaves the table at x = l with w = w' = 0 and zero moment (the part on the table is
    straight, so its curvature, hence the moment, vanishes, and so does the moment at
    lift-off by continuity). Moments about x = l of the lifted part: F l = q l^2/2, so
    l = 2F/q (the table then pushes q l/2 at the lift-off point). With s = l - x the part
    is a cantilever clamped at s = 0 with the tip force F up and the load q down:
    w(s) = F s^2 (3l - s)/(6EI) - q s^2 (6l^2 - 4ls + s^2)/(24EI), so the tip lift is
    delta = q l^4/(24 EI): the force-lift relation F = (q/2) (24 EI delta/q)^(1/4).
    Checked: the lifted length from the tip lift to 1e-3 of the rod length, the shape of
    the lifted part to 1 % of the lift, the penetration below 1e-3 of the contact radius
    (default penalty 1e3 EI/h^4), and the nodes reported in contact."""
    assert lifted.converged
    p = lifted.positions("rod")
    x, z = p[:, 0], p[:, 2]
    l_exact = 2.0 * F_LIFT / Q
    delta = z[-1]
    assert abs((24.0 * EI * delta / Q) ** 0.25 - l_exact) < 1e-3 * L_ROD
    s = np.clip(l_exact - x, 0.0, None)
    w = (F_LIFT * s**2 * (3 * l_exact - s) / (6 * EI)
         - Q * s**2 * (6 * l_exact**2 - 4 * l_exact * s + s**2) / (24 * EI))
    np.testing.assert_allclose(z, w, atol=1e-2 * delta)
    table = lifted.contacts["table"]
    assert table["max_penetration"] < 1e-3 * R_CONTACT
    assert lifted.contacts["drum"]["nodes"] == {"rod": []}
    touching = np.zeros(N + 1, bool)
    touching[table["nodes"]["rod"]] = True
    h = L_ROD / N
    assert touching[x > l_exact + h].all() and not touching[x < l_exact - 2 * h].any()
    # vertical balance: table + clamp + F = q L; the clamp (at table height) carries little
    assert 0.0 < Q * L_ROD - F_LIFT - table["normal_force"] < 0.1 * Q * L_ROD


# large lift: the same structure (compiled once) with a heavier rod and a larger force
Q_BIG, F_BIG = 40.0, 14.0               # N/m, N: lifted length ~0.65 L, tip turned ~46 deg
LIFT_BIG = _scene(L_ROD, [L_ROD, 0.0, 0.0], [0.0, 0.0, np.pi], F_BIG, Q_BIG / 9.81, -9.81,
                  -R_CONTACT, ([0.0, 0.0, -10.0], 1.0))


def shooting_lift(F, q, EI):
    """Planar inextensible elastica of the lifted part, by shooting: arc length s from the
    lift-off point A (s = 0) to the tip (s = l), tangent angle th from the table, bending
    moment m = EI th'. The loads on [s, l] are the tip force F (up) and the weight q (down)
    only (a frictionless table pushes vertically, so no horizontal force reaches the lifted
    part); their moment about the section at s is
    m(s) = F (x(l) - x(s)) - q int_s^l (x(t) - x(s)) dt, so m' = -cos th (F - q (l - s)).
    At A the rod leaves a flat resting part with zero curvature: th = 0, m = 0, x = z = 0
    (the jump of the shear there, q l - F, is the table's point reaction at A). At the
    free tip m(l) = 0, the condition that fixes the lifted length l: a root of
    m(l; l) found by bracketing on a grid and Brent's method. Returns l and the dense
    solution (th, m, x, z)(s)."""
    from scipy.integrate import solve_ivp
    from scipy.optimize import brentq

    def shoot(l):
        def rhs(s, y):
            th, m, _, _ = y
            return [m / EI, -np.cos(th) * (F - q * (l - s)), np.cos(th), np.sin(th)]
        return solve_ivp(rhs, (0.0, l), [0.0, 0.0, 0.0, 0.0], rtol=1e-12, atol=1e-14,
                         dense_output=True)

    grid = np.linspace(0.1, 1.5, 15) * 2.0 * F / q
    tip = np.array([shoot(l).y[1, -1] for l in grid])
    k = np.flatnonzero(np.sign(tip[:-1]) != np.sign(tip[1:]))[0]     # the shortest root
    l = brentq(lambda l: shoot(l).y[1, -1], grid[k], grid[k + 1], xtol=1e-14)
    return l, shoot(l).sol


def test_heavy_rod_lifted_far_off_a_table_matches_the_elastica():
    """Large lift (tip turned ~46 degrees, beyond beam theory: its tip lift q l^4/(24 EI)
    is 20 % off): every node against the shooting solution of the elastica
    (:func:`shooting_lift`) to 1e-3 of the rod length at 40 elements. Nodes at distance S
    from the clamp (x = L - S on the table) lie flat for S < L - l; beyond, at
    x = l - x_e(S - (L - l)), z = z_e(S - (L - l)). Where the rod leaves the table is set
    by the lifted length l, so a wrong l shifts the whole lifted shape (checked also on
    its own: the tip's horizontal position l - x_e(l) and height z_e(l))."""
    pytest.importorskip("scipy")
    res = sj.run(LIFT_BIG, stability=False)
    assert res.converged, res.message
    l, sol = shooting_lift(F_BIG, Q_BIG, EI)
    assert 0.5 < l < 0.8 and np.degrees(sol(l)[0]) > 40.0
    p = res.positions("rod")
    S = np.linspace(0.0, L_ROD, N + 1)
    s = np.clip(S - (L_ROD - l), 0.0, None)
    _, _, xe, ze = sol(s)
    lifted = S > L_ROD - l
    expected = np.stack([np.where(lifted, l - xe, L_ROD - S), np.zeros_like(S),
                         np.where(lifted, ze, 0.0)], axis=1)
    assert np.abs(p - expected).max() < 1e-3 * L_ROD
    assert abs(p[-1, 0] - (l - sol(l)[2])) < 1e-3 * L_ROD
    assert abs(p[-1, 2] - sol(l)[3]) < 1e-3 * L_ROD


def test_rod_wrapped_on_a_drum_takes_its_curvature(wrapped):
    """Where a rod lies on a rigid frictionless drum its centreline is the circle of radius
    Rc + r, so its curvature is 1/(Rc + r) and its bending moment EI/(Rc + r): checked on
    the elements away from the clamp and the lift-off point to 1e-3, from the relative
    rotation of consecutive sections over their distance."""
    assert wrapped.converged
    p, R = wrapped.positions("rod"), wrapped.rotations("rod")
    angle = np.array([lie_angle(R[i].T @ R[i + 1]) for i in range(N)])
    kappa = angle / np.linalg.norm(np.diff(p, axis=0), axis=1)
    nodes = wrapped.contacts["drum"]["nodes"]["rod"]
    assert len(nodes) > 12
    inner = slice(2, nodes[-1] - 4)
    np.testing.assert_allclose(kappa[inner] * (RC + R_CONTACT), 1.0, atol=1e-3)
    assert wrapped.contacts["drum"]["max_penetration"] < 1e-3 * R_CONTACT


def lie_angle(R):
    return np.arccos(np.clip((np.trace(R) - 1.0) / 2.0, -1.0, 1.0))


def test_contact_force_is_the_derivative_of_the_penalty_energy(wrapped):
    """The element contact force (velocity-field map form) equals ``jax.grad`` of the
    penalty energy through ``H exp(y)`` of the two nodal frames (spec S38 vs S54)."""
    model = wrapped.model
    R, p = jnp.asarray(wrapped._R), jnp.asarray(wrapped._p)
    data = assembly.element_data(model)
    kinds, n = model.structure.obstacle_kinds, model.structure.contact_points
    e = 6                                    # an element on the drum
    one = jax.tree_util.tree_map(lambda a: a[e], data)
    RA, pA, RB, pB = R[e], p[e], R[e + 1], p[e + 1]

    def energy(y):
        RA1, pA1 = lie.compose_exp(RA, pA, y[:6])
        RB1, pB1 = lie.compose_exp(RB, pB, y[6:])
        return contact.energy(RA1, pA1, RB1, pB1, one.contact, one.length, kinds, n)

    zero = jnp.zeros(12)
    force = jax.jit(lambda: contact.force(element_state(RA, pA, RB, pB, zero, zero),
                                          one.contact, one.length, kinds, n))()
    expected = jax.jit(jax.grad(energy))(zero)
    assert float(jnp.abs(expected).max()) > 1.0
    np.testing.assert_allclose(force, expected, rtol=1e-9, atol=1e-9 * float(
        jnp.abs(expected).max()))


def test_tangent_paths_agree_in_contact(wrapped):
    """The closed-form path (contact blocks by jacfwd) and the autodiff path (jacfwd of the
    sum of all terms) give the same residual and tangent at a state in contact."""
    model = wrapped.model
    R, p = jnp.asarray(wrapped._R), jnp.asarray(wrapped._p)
    paths = jax.jit(lambda m, R, p: [assembly.residual_and_tangent(m, R, p, 1.0, path)
                                     for path in ("closed_form", "autodiff")])
    (r1, b1), (r2, b2) = paths(model, R, p)
    np.testing.assert_allclose(r1, r2, atol=1e-8)
    scale = float(jnp.abs(b1[0]).max())
    for a, b in zip(b1, b2):
        np.testing.assert_allclose(a, b, atol=1e-10 * scale)


@pytest.mark.slow
def test_gradients_in_contact_match_finite_differences():
    """Derivatives of the tip height of a cantilever pressed onto a drum with respect to the
    drum's position (x, z) and the rod's bending stiffness (a factor on EIy), by forward
    mode through the solve (implicit function theorem, contact included) against central
    differences of the same solve, to 1e-4."""
    model = sj.build_model(sj.Scene.from_dict(LEAN))
    settings = sj.StaticSettings(tolerance=1e-13)

    @jax.jit
    def tip_z(x):
        m = model.replace(obstacles=model.obstacles.at[1, 0].add(x[0]).at[1, 2].add(x[1]),
                          stiffness=model.stiffness.at[:, 4].multiply(x[2]))
        eq = sj.solve_static(m, settings)
        return jnp.where(eq.converged, eq.p[-1, 2], jnp.nan)

    base = jnp.array([0.0, 0.0, 1.0])
    jac = jax.jit(jax.jacfwd(lambda x: tip_z(x)))(base)
    for i, step in enumerate([1e-6, 1e-6, 1e-5]):
        e = jnp.zeros(3).at[i].set(step)
        fd = (float(tip_z(base + e)) - float(tip_z(base - e))) / (2 * step)
        assert abs(fd) > 1e-3
        assert abs(float(jac[i]) - fd) <= 1e-4 * abs(fd), (i, float(jac[i]), fd)


@pytest.mark.parametrize("kind,row,x,expected", [
    ("plane", [0, 0, 1, 0, 0, 2, 0], [3, 4, 1.5], 0.5),
    ("sphere", [1, 0, 0, 0, 0, 0, 2], [1, 3, 4], 3.0),
    ("capsule", [0, 0, 0, 2, 0, 0, 0.5], [3, 0, 0], 0.5),      # beyond end b
    ("capsule", [0, 0, 0, 2, 0, 0, 0.5], [1, 2, 0], 1.5),      # beside the segment
    ("cylinder", [0, 0, 0, 0, 0, 3, 1], [3, 4, 7], 4.0),
    ("tube", [0, 0, 0, 0, 0, 3, 1], [0.6, 0, 7], 0.4),
])
def test_signed_distances(kind, row, x, expected):
    """Distances from elementary geometry; gradients unit normals away from the axis."""
    row, x = jnp.asarray(row, float), jnp.asarray(x, float)
    value, grad = jax.value_and_grad(lambda y: obstacles.signed_distance(kind, row, y))(x)
    assert float(value) == pytest.approx(expected, abs=1e-14)
    assert float(jnp.linalg.norm(grad)) == pytest.approx(1.0, abs=1e-14)


@pytest.mark.parametrize("kind", ["sphere", "cylinder", "tube", "capsule"])
def test_signed_distance_gradient_is_finite_on_the_axis(kind):
    """At a sphere's centre or on an axis the distance is not differentiable; the safe norm
    gives a finite (zero) gradient in the point and the parameters instead of NaN."""
    row = jnp.array([0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.5])
    gx, gp = jax.grad(lambda y, q: obstacles.signed_distance(kind, q, y), (0, 1))(
        jnp.zeros(3), row)
    assert np.isfinite(gx).all() and np.isfinite(gp).all()


def test_penalty_is_c2_with_the_stated_pieces():
    """psi, psi' continuous at 0 and at eps; psi' is the derivative of psi; past eps the
    line load is k (delta - eps/2)."""
    k, eps = 7.0, 0.2
    d = jnp.array([-0.1, 0.0, 0.5 * eps, eps, 3 * eps])
    slope = jax.vmap(jax.grad(lambda t: contact.penalty(t, k, eps)))(d)
    np.testing.assert_allclose(slope, contact.penalty_slope(d, k, eps), rtol=1e-12)
    np.testing.assert_allclose(contact.penalty_slope(d, k, eps)[-1], k * 2.5 * eps)
    curv = jax.vmap(jax.grad(lambda t: contact.penalty_slope(t, k, eps)))(
        jnp.array([eps - 1e-9, eps + 1e-9, 1e-12]))
    np.testing.assert_allclose(curv, [k, k, 0.0], atol=1e-6)


def _with(**changes):
    scene = {k: v for k, v in WRAP.items()}
    scene.update(changes)
    return scene


@pytest.mark.parametrize("change,message", [
    ({"obstacles": [{"name": "a", "kind": "ball", "center": [0, 0, 0], "radius": 1}]},
     "obstacles[0].kind: must be one of"),
    ({"obstacles": [{"name": "a", "kind": "sphere", "center": [0, 0, 0]}]},
     "obstacles[0].radius: required key missing"),
    ({"obstacles": [{"name": "a", "kind": "sphere", "center": [0, 0, 0], "radius": -1}]},
     "obstacles[0].radius: must be > 0"),
    ({"obstacles": [{"name": "a", "kind": "plane", "point": [0, 0, 0], "normal": [0, 0, 0]}]},
     "obstacles[0].normal: must be a non-zero vector"),
    ({"obstacles": [{"name": "a", "kind": "plane", "point": [0, 0, 0], "normal": [0, 0, 1],
                     "radius": 1}]},
     "obstacles[0].radius: unknown key"),
    ({"obstacles": [{"name": "a", "kind": "capsule", "a": [0, 0, 0], "b": [0, 0, 0],
                     "radius": 1}]},
     "obstacles[0].b: must differ from a"),
    ({"obstacles": [{"name": "a", "kind": "sphere", "center": [0, 0, 0], "radius": 1,
                     "friction": -0.1}]},
     "obstacles[0].friction: must be >= 0"),
    ({"obstacles": [{"name": "a", "kind": "sphere", "center": [0, 0, 0], "radius": 1}] * 2},
     "obstacles[1].name: must be a unique"),
    ({"contact": {"radius": 0.01, "self": "yes"}}, "contact.self: must be true or false"),
    ({"contact": {"radius": 0.0}}, "contact.radius: must be > 0"),
    ({"contact": {"quadrature_points": 0}}, "contact.quadrature_points: must be >= 1"),
    ({"contact": {"radius": 0.01, "slip_displacement": 0.0}},
     "contact.slip_displacement: must be > 0"),
    ({"contact": {"stiffnes": 1.0}}, "contact.stiffnes: unknown key"),
])
def test_bad_contact_input_is_rejected_naming_the_key(change, message):
    with pytest.raises(ValueError, match=message.replace("[", r"\[").replace("]", r"\]")):
        sj.Scene.from_dict(_with(**change))


def test_contact_radius_needed_without_a_circular_section():
    """A rod given by stiffness tables has no section radius: contact.radius or
    rods[i].contact_radius is required (checked while the scene is read)."""
    scene = _with(contact={})
    with pytest.raises(ValueError, match=r"contact.radius: required"):
        sj.Scene.from_dict(scene)
    scene["rods"] = [dict(WRAP["rods"][0], contact_radius=0.02)]
    model = sj.build_model(sj.Scene.from_dict(scene))
    np.testing.assert_allclose(model.contact_radius, 0.02)


def test_cli_run_writes_contacts_into_the_result_file(lifted, tmp_path):
    """``simsoft-jax run`` on a scene file with obstacles writes ``"contacts"``: per obstacle
    the normal force, the total force, the penetration and the nodes in contact, the same
    as the Python result (the solver is read from the session's compilation cache)."""
    scene, out = tmp_path / "lift.json", tmp_path / "out.json"
    scene.write_text(json.dumps(LIFT))
    done = subprocess.run([sys.executable, "-m", "simsoft_jax.cli", "run", str(scene), "-o",
                           str(out), "--no-stability"], capture_output=True, text=True,
                          timeout=300)
    assert done.returncode == 0, done.stderr
    written = json.loads(out.read_text())["contacts"]
    assert set(written) == {"table", "drum"}
    table = written["table"]
    assert table["nodes"] == lifted.contacts["table"]["nodes"]
    assert table["normal_force"] == pytest.approx(float(lifted.contacts["table"]["normal_force"]),
                                                  rel=1e-9)
    np.testing.assert_allclose(table["force"], [0.0, 0.0, table["normal_force"]], atol=1e-9)
    assert 0.0 < table["max_penetration"] < 1e-3 * R_CONTACT
    assert written["drum"]["nodes"] == {"rod": []} and written["drum"]["normal_force"] == 0.0


def test_free_end_pushed_into_a_wall_meets_it_at_the_end_cap():
    """A cantilever along x whose tip touches a wall (plane x = L + r) is pulled into it
    by an axial tip force F. The wall acts on the end cap only (the Gauss points stay a
    fraction of an element behind the tip), a length r of the line penalty: the tip's
    penetration delta solves ``F = (EA/L) delta + r psi'(delta)`` (the rod's axial spring
    and the cap; psi' the penalty's stated pieces, solved here by bisection). Before the
    caps the wall did not hold the tip at all (delta = F L / EA, four times more here)."""
    L, r, k, EA, F = 0.2, 1e-3, 9e9, 6e5, 2000.0
    scene = {"solver": {"kind": "static", "load_steps": 4, "tolerance": 1e-12},
             "rods": [{"name": "rod", "elements": 4, "geometry": {"kind": "straight", "length": L},
                       "stiffness": {"EA": EA, "GAy": EA, "GAz": EA, "GJ": 1.0, "EIy": 1.0,
                                     "EIz": 1.0},
                       "inertia": {"rhoA": 1.0, "rhoJ": 1e-6, "rhoIy": 1e-6, "rhoIz": 1e-6}}],
             "constraints": [{"kind": "clamp", "rod": "rod", "node": 0}],
             "loads": [{"kind": "force", "rod": "rod", "node": -1, "vector": [F, 0.0, 0.0]}],
             "obstacles": [{"name": "wall", "kind": "plane", "point": [L + r, 0.0, 0.0],
                            "normal": [-1.0, 0.0, 0.0]}],
             "contact": {"radius": r, "stiffness": k}}
    result = sj.run(scene, stability=False)
    assert result.converged
    eps = contact.SMOOTHING * r

    def slope(delta):                      # the penalty's pieces, as documented
        return k * delta**2 / (2 * eps) if delta < eps else k * (delta - eps / 2)

    lo, hi = 0.0, F * L / EA
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if EA / L * mid + r * slope(mid) < F else (lo, mid)
    delta = 0.5 * (lo + hi)
    assert delta < 0.3 * F * L / EA
    tip = result.positions("rod")[-1]
    assert tip[0] - L == pytest.approx(delta, rel=1e-8)
    wall = result.contacts["wall"]
    assert wall["max_penetration"] == pytest.approx(delta, rel=1e-8)
    assert wall["normal_force"] == pytest.approx(r * slope(delta), rel=1e-8)
    assert wall["nodes"]["rod"] == [3, 4]
