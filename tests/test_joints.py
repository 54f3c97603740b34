"""Rigid bodies and joints in statics (issue 13, items 3-4), against independent
references: two coincident welded rods are one rod of twice the stiffness (exact); a
Y-branched rod and a planar parallel robot (two rods welded to a rigid platform) against
a shooting solution of the planar Reissner rod equations written here (scipy); gradients
through the bordered solve against central differences; the stability count of a welded
mechanism; scene errors that name the key."""
import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import fsolve

import jax
import simsoft_jax as sj
from simsoft_jax.model.model import build_model

L, E, NU, D = 1.0, 2.0e7, 0.5, 0.01


def rod(name, elements=8, length=L, E_=E, position=(0.0, 0.0, 0.0), angle_deg=0.0):
    return {"name": name, "material": {"name": "m_" + name, "E": E_, "nu": NU,
                                        "density": 1000.0},
            "section": {"shape": "circle", "diameter": D}, "elements": elements,
            "geometry": {"kind": "straight", "length": length},
            "base": {"position": list(position),
                     "rotation": {"axis": [0.0, 0.0, 1.0], "angle_deg": angle_deg}}}


def clamp(name):
    return {"kind": "clamp", "rod": name, "node": 0}


def force(name, vector, node=-1):
    return {"kind": "force", "rod": name, "node": node, "vector": list(vector),
            "frame": "world"}


# ---------------------------------------------------------------- planar reference

def planar_rod(theta0, p0, n0, m0, length, K, q=(0.0, 0.0)):
    """Planar Reissner rod in the x-y plane from s = 0 (written here): p' = R(theta)
    [1 + n_1/EA, n_2/GA], theta' = m/EI, n' = -q, m' = -(p' x n)_z, with the internal
    force n (world) and moment m at s acting on [0, s] from beyond. Returns the state
    (p (2), theta, n (2), m) at s = length."""
    EA, GA, EI = K

    def rate(_, y):
        th, n, m = y[2], y[3:5], y[5]
        c, s = np.cos(th), np.sin(th)
        n_loc = np.array([c * n[0] + s * n[1], -s * n[0] + c * n[1]])
        t = np.array([1.0 + n_loc[0] / EA, n_loc[1] / GA])
        dp = np.array([c * t[0] - s * t[1], s * t[0] + c * t[1]])
        return np.concatenate([dp, [m / EI], -np.asarray(q), [-(dp[0] * n[1] - dp[1] * n[0])]])

    y0 = np.concatenate([p0, [theta0], n0, [m0]])
    sol = solve_ivp(rate, (0.0, length), y0, method="DOP853", rtol=1e-12, atol=1e-14)
    return sol.y[:, -1]


def planar_constants(model):
    K = np.asarray(model.stiffness)[0]
    return K[0], K[1], K[5]          # EA, GAy, EIz (bending in the x-y plane)


# ---------------------------------------------------------------- tests

@pytest.fixture(scope="module")
def welded_pair():
    F = [0.0, 0.02, -0.05]
    pair = {"solver": {"kind": "static"}, "rods": [rod("a"), rod("b")],
            "constraints": [clamp("a"), clamp("b")],
            "joints": [{"kind": "weld", "a": {"rod": "a", "node": -1},
                        "b": {"rod": "b", "node": -1}}],
            "loads": [force("a", F)]}
    one = {"solver": {"kind": "static"}, "rods": [rod("a", E_=2 * E)],
           "constraints": [clamp("a")], "loads": [force("a", F)]}
    return sj.run(pair), sj.run(one), np.asarray(F)


def test_two_coincident_welded_rods_are_one_rod_of_twice_the_stiffness(welded_pair):
    pair, one, F = welded_pair
    assert pair.converged and one.converged
    scale = np.abs(one.positions("a")[-1]).max()
    for name in ("a", "b"):     # large deflection: the tip turns by more than a radian
        assert np.abs(pair.positions(name) - one.positions("a")).max() < 1e-10 * scale
        assert np.abs(pair.rotations(name) - one.rotations("a")).max() < 1e-10
    # each weld carries half the load (the two rods are identical)
    mu = np.asarray(pair.raw.multipliers)
    assert np.allclose(np.abs(mu[:3]), np.abs(F) / 2, atol=1e-6 * np.abs(F).max())
    assert pair.stability == {"negative_eigenvalues": 0, "stable": True}


@pytest.mark.slow
def test_y_branched_rod_converges_to_a_planar_shooting_solution():
    # a trunk with two branches welded to its end at +-35 degrees, tip loads bend the
    # upper branch through more than 90 degrees; the helical elements converge to the
    # shooting solution at second order (linear moments along the rods)
    trunk_len, branch_len, alpha = 0.5, 0.4, 35.0
    F1, F2 = np.array([0.01, -0.03]), np.array([-0.02, -0.01])

    def scene(n):
        return {"solver": {"kind": "static"},
                "rods": [rod("trunk", n, trunk_len),
                         rod("up", n, branch_len, position=(trunk_len, 0, 0), angle_deg=alpha),
                         rod("down", n, branch_len, position=(trunk_len, 0, 0),
                             angle_deg=-alpha)],
                "constraints": [clamp("trunk")],
                "joints": [{"kind": "weld", "a": {"rod": "trunk", "node": -1},
                            "b": {"rod": b, "node": 0}} for b in ("up", "down")],
                "loads": [force("up", [*F1, 0.0]), force("down", [*F2, 0.0])]}

    results = [sj.run(scene(n), stability=False) for n in (8, 16)]
    assert all(r.converged for r in results)
    K = planar_constants(results[0].model)

    def shoot(u):
        n0, m0, n_up, m_up = u[:2], u[2], u[3:5], u[5]
        t = planar_rod(0.0, np.zeros(2), n0, m0, trunk_len, K)
        up = planar_rod(t[2] + np.radians(alpha), t[:2], n_up, m_up, branch_len, K)
        down = planar_rod(t[2] - np.radians(alpha), t[:2], t[3:5] - n_up, t[5] - m_up,
                          branch_len, K)
        return np.concatenate([up[3:5] - F1, [up[5]], down[3:5] - F2, [down[5]]]), up, down

    F = F1 + F2
    guess = np.array([*F, -(trunk_len * F[1]), *F1, 0.0])
    u = fsolve(lambda u: shoot(u)[0], guess, xtol=1e-13)
    residual, up, down = shoot(u)
    assert np.abs(residual).max() < 1e-10
    assert np.arctan2(up[1] - 0.0, up[0] - trunk_len) < -np.pi / 4   # bent far down
    errors = [max(np.linalg.norm(r.positions(name)[-1][:2] - ref[:2])
                  for name, ref in (("up", up), ("down", down))) for r in results]
    assert errors[1] < 2e-4 * (trunk_len + branch_len)
    assert 3.5 < errors[0] / errors[1] < 4.5, errors


F_PLATFORM = 2.0      # N, sideways at the left rod's tip (the columns' weight stays far
                      # below their buckling load)


def parallel_robot_scene(n):
    w = 0.15
    return {"solver": {"kind": "static"},
            "gravity": {"vector": [0.0, -9.81, 0.0]},
            "rods": [rod("left", n, E_=100 * E, position=(-w, 0, 0), angle_deg=90.0),
                     rod("right", n, E_=100 * E, position=(w, 0, 0), angle_deg=90.0)],
            "bodies": [{"name": "platform", "mass": 0.02,
                        "inertia": [[1e-4, 0, 0], [0, 1e-4, 0], [0, 0, 2e-4]],
                        "position": [0.0, L, 0.0]}],
            "constraints": [clamp("left"), clamp("right")],
            "joints": [{"kind": "weld", "a": {"rod": "left", "node": -1},
                        "b": {"body": "platform", "offset": [-w, 0.0, 0.0]}},
                       {"kind": "weld", "a": {"rod": "right", "node": -1},
                        "b": {"body": "platform", "offset": [w, 0.0, 0.0]}}],
            "loads": [force("left", [F_PLATFORM, 0.0, 0.0])]}


@pytest.fixture(scope="module")
def parallel_robot():
    scene = parallel_robot_scene(8)
    return scene, sj.run(scene)


@pytest.mark.slow
def test_planar_parallel_robot_converges_to_a_shooting_solution(parallel_robot):
    # two clamped columns welded to a rigid platform (weight, inertia), gravity on all,
    # a sideways force: the platform pose converges at second order in the element
    # size to the shooting solution of the planar rod equations
    scene, result = parallel_robot
    finer = sj.run(parallel_robot_scene(16), stability=False)
    assert result.converged and finer.converged
    K = planar_constants(result.model)
    w, mass, g = 0.15, 0.02, 9.81
    rho_a = float(np.asarray(result.model.inertia)[0, 0])
    q = (0.0, -rho_a * g)
    F_left = np.array([F_PLATFORM, 0.0])

    def shoot(u):
        tips, out = [], []
        for k, x0 in enumerate((-w, w)):
            n0, m0 = u[3 * k:3 * k + 2], u[3 * k + 2]
            tips.append(planar_rod(np.pi / 2, np.array([x0, 0.0]), n0, m0, L, K, q))
        xb, yb, phi = u[6:9]
        c, s = np.cos(phi), np.sin(phi)
        total_f, total_m = np.array([0.0, -mass * g]), 0.0
        for tip, x0, f_ext in zip(tips, (-w, w), (F_left, np.zeros(2))):
            attach = np.array([xb + c * x0, yb + s * x0])
            out += list(tip[:2] - attach) + [tip[2] - (np.pi / 2 + phi)]
            P = tip[3:5] - f_ext          # force of the platform on the rod tip
            total_f = total_f - P
            arm = attach - np.array([xb, yb])
            total_m = total_m - tip[5] - (arm[0] * P[1] - arm[1] * P[0])
        return np.array(out + list(total_f) + [total_m])

    guess = np.array([-F_PLATFORM / 2, 0.5, 0.0, -F_PLATFORM / 2, 0.5, 0.0, 0.0, L, 0.0])
    u = fsolve(shoot, guess, xtol=1e-13)
    assert np.abs(shoot(u)).max() < 1e-9
    assert abs(u[6]) > 0.05        # the platform moves sideways by centimetres
    errors = []
    for r in (result, finer):
        position, rotation = r.body_pose("platform")
        errors.append(np.linalg.norm(position[:2] - u[6:8]))
        assert abs(np.arctan2(rotation[1, 0], rotation[0, 0]) - u[8]) < 2e-4
        assert abs(position[2]) < 1e-12
    assert errors[1] < 5e-4 * L
    assert 3.5 < errors[0] / errors[1] < 4.5, errors
    d = result.to_dict()
    assert np.allclose(d["bodies"]["platform"]["position"], result.body_pose("platform")[0])


def test_gradient_through_a_mechanism_matches_central_differences(parallel_robot):
    scene, _ = parallel_robot
    model = build_model(sj.Scene.from_dict(scene))
    node = dict(model.structure.bodies)["platform"]
    settings = sj.StaticSettings()

    def platform_x(scale, mass):
        m = model.replace(stiffness=model.stiffness * scale, mass=model.mass * mass)
        return sj.solve_static(m, settings).p[node, 0]

    grad = jax.grad(platform_x, argnums=(0, 1))(1.0, 1.0)
    h = 1e-5
    for k, g in enumerate(grad):
        args = [1.0, 1.0]
        args[k] = 1.0 + h
        up = platform_x(*args)
        args[k] = 1.0 - h
        fd = (up - platform_x(*args)) / (2 * h)
        assert abs(float(g) - float(fd)) < 1e-5 * max(abs(float(fd)), 1e-3), (k, g, fd)


@pytest.mark.slow
def test_autodiff_and_closed_form_tangents_agree_with_joints(parallel_robot):
    scene, result = parallel_robot
    other = dict(scene, solver={"kind": "static", "tangent": "autodiff"})
    alt = sj.run(other)
    assert alt.converged
    assert np.abs(alt.body_pose("platform")[0] - result.body_pose("platform")[0]).max() < 1e-10


def test_ball_joint_lets_the_ends_turn_freely():
    # two cantilevers meeting tip to tip, a ball joint and a vertical load at the joint:
    # by symmetry each carries half the load and the joint transmits no moment, so each
    # tip has the slope of a cantilever with tip force F/2 (small deflection:
    # F/2 L^2 / (2 EI)) and the two tips have opposite slopes. The load is small: the
    # tips' foreshortening stretches the pair, and the tension it makes stiffens the
    # beams by T L^2 / EI (3e-5 here, 10 % at a hundred times the load)
    F = -1e-6
    scene = {"solver": {"kind": "static"},
             "rods": [rod("a", 8), rod("b", 8, position=(2 * L, 0, 0), angle_deg=180.0)],
             "constraints": [clamp("a"), clamp("b")],
             "joints": [{"kind": "ball", "a": {"rod": "a", "node": -1},
                         "b": {"rod": "b", "node": -1}}],
             "loads": [force("a", [0.0, F, 0.0])]}
    result = sj.run(scene)
    assert result.converged
    EI = float(np.asarray(result.model.stiffness)[0, 5])
    slope_a = result.rotations("a")[-1][1, 0]
    slope_b = -result.rotations("b")[-1][1, 0]
    expected = (F / 2) * L ** 2 / (2 * EI)
    assert abs(slope_a - expected) < 1e-4 * abs(expected)
    assert abs(slope_a + slope_b) < 1e-9 * abs(expected)
    assert abs(np.asarray(result.raw.multipliers)[1] - F / 2) < 1e-9 * abs(F)
    assert np.linalg.norm(result.positions("a")[-1] - result.positions("b")[-1]) < 1e-12


@pytest.mark.parametrize("change, message", [
    (lambda d: d["joints"][0].update(kind="hinge"), r"^joints\[0\]\.kind: must be one of"),
    (lambda d: d["joints"][0]["b"].update(rod="nope"), r"^joints\[0\]\.b\.rod: no rod"),
    (lambda d: d["joints"][0].update(b={"rod": "a", "node": -1}), r"^joints\[0\]: a joint needs"),
    (lambda d: d["joints"][0]["b"].update(body="x"), r"^joints\[0\]\.b: give exactly one"),
    (lambda d: d.update(bodies=[{"name": "p", "mass": 1.0}]), r"^bodies\[0\]: body 'p' has no"),
    (lambda d: (d["solver"].update(kind="dynamic", t_end=1.0, dt=0.01),
                d.update(bodies=[{"name": "p"}]),
                d["joints"].append({"kind": "ball", "a": {"rod": "a", "node": 2},
                                    "b": {"body": "p"}})),
     r"^bodies\[0\]\.mass: a body without a weld needs a mass > 0"),
    (lambda d: (d["solver"].update(kind="dynamic", t_end=1.0, dt=0.01),
                d.update(bodies=[{"name": "p", "mass": 1.0, "inertia": [[1e-3, 0, 0], [0, 1e-3, 0], [0, 0, 0]]}]),
                d["joints"].append({"kind": "ball", "a": {"rod": "a", "node": 2},
                                    "b": {"body": "p"}})),
     r"^bodies\[0\]\.inertia: a body without a weld needs a positive definite"),
    (lambda d: (d["solver"].update(kind="dynamic", t_end=1.0, dt=0.01),
                d["constraints"][1].update(kind="drive", node=-1, times=[0.0, 1.0],
                                           displacement=[[0, 0, 0], [0.1, 0, 0]],
                                           slides_along=[1.0, 0.0, 0.0])),
     r"^constraints\[1\]\.slides_along: a joint acts on node"),
])
def test_bad_mechanisms_are_rejected_naming_the_key(change, message):
    d = {"solver": {"kind": "static"}, "rods": [rod("a"), rod("b")],
         "constraints": [clamp("a"), clamp("b")],
         "joints": [{"kind": "weld", "a": {"rod": "a", "node": -1},
                     "b": {"rod": "b", "node": -1}}]}
    change(d)
    with pytest.raises(ValueError, match=message):
        sj.Scene.from_dict(d)


def test_joint_points_apart_at_the_start_are_rejected():
    d = {"solver": {"kind": "static"}, "rods": [rod("a"), rod("b", position=(0, 0.1, 0))],
         "constraints": [clamp("a"), clamp("b")],
         "joints": [{"kind": "ball", "a": {"rod": "a", "node": -1},
                     "b": {"rod": "b", "node": -1}}]}
    with pytest.raises(ValueError, match=r"^joints\[0\]: the joint points of ends a and b "
                                         r"are 0\.1 m apart"):
        build_model(sj.Scene.from_dict(d))
