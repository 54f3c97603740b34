"""Magnetic actuation and fluid loads (the registered terms of
:mod:`simsoft_jax.physics.terms.registry`), against independent references:

- the magnetic elastica: a clamped rod magnetized along its axis in a transverse field,
  ``EI theta'' = -m B cos(theta)``, against a shooting solution written here (second-order
  convergence in the element count);
- a cantilever in a uniform current: uniform drag ``1/2 rho C_n d U^2`` per unit length,
  tip deflection ``q L^4 / (8 EI)`` (small deflection);
- a rod sinking broadside: ``m_eff v' = W - B - k v^2`` with added mass in ``m_eff``,
  ``v(t) = v_t tanh(k v_t t / m_eff)``;
- gradients in the field, the moment and the drag coefficient against central differences;
- bad inputs rejected while the scene is read, naming the key.
"""
import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

import simsoft_jax as sj

EI, LENGTH, MOMENT, FIELD = 2.0, 1.0, 4.0, 1.0      # m B L^2 / EI = 2: large bending
SETTINGS = sj.StaticSettings(tolerance=1e-12)


def magnetic_scene(elements, **solver):
    return sj.Scene.from_dict({
        "solver": {"kind": "static", **solver},
        "magnetic_field": {"vector": [0.0, FIELD, 0.0]},
        "rods": [{"name": "rod", "elements": elements,
                  "geometry": {"kind": "straight", "length": LENGTH},
                  "stiffness": dict(EA=1e5, GAy=1e5, GAz=1e5, GJ=EI, EIy=EI, EIz=EI),
                  "inertia": dict(rhoA=1.0, rhoJ=2e-3, rhoIy=1e-3, rhoIz=1e-3),
                  "magnetic_moment": [MOMENT, 0.0, 0.0]}],
        "constraints": [{"kind": "clamp", "rod": "rod", "node": 0}]})


def elastica_tip(m=MOMENT, b=FIELD):
    """Tip (x, y) of the magnetic elastica by shooting from the free end: theta' = 0 there,
    theta(0) = 0 at the clamp."""
    def from_tip(theta_tip):
        sol = solve_ivp(lambda s, y: [y[1], -m * b / EI * np.cos(y[0]), np.cos(y[0]),
                                      np.sin(y[0])],
                        [LENGTH, 0.0], [theta_tip, 0.0, 0.0, 0.0], rtol=1e-12, atol=1e-12)
        return sol.y[:, -1]

    theta_tip = brentq(lambda a: from_tip(a)[0], 0.0, np.pi / 2, xtol=1e-14)
    end = from_tip(theta_tip)
    return np.array([-end[2], -end[3]])


@pytest.fixture(scope="module")
def magnet_model():
    return sj.build_model(magnetic_scene(16))


def test_magnetic_elastica_converges_to_the_shooting_solution(magnet_model):
    exact = elastica_tip()
    assert exact[1] > 0.4                       # a large deflection towards the field
    errors = []
    for model in (magnet_model, sj.build_model(magnetic_scene(32))):
        eq = sj.solve_static(model, SETTINGS)
        assert bool(eq.converged)
        errors.append(np.linalg.norm(np.asarray(eq.p[-1, :2]) - exact))
        assert abs(float(eq.p[-1, 2])) < 1e-12   # stays in the plane of m and B
    assert errors[1] < 2e-4
    assert 3.0 < errors[0] / errors[1] < 5.0     # second order in the element length


def test_magnetic_static_solves_agree_on_both_tangent_paths(magnet_model):
    """The elastica's model: its closed-form solve is the program the test above compiled
    already, only the autodiff path compiles here."""
    eqs = [sj.solve_static(magnet_model, SETTINGS.replace(tangent=t))
           for t in ("closed_form", "autodiff")]
    np.testing.assert_allclose(eqs[0].p, eqs[1].p, rtol=0, atol=1e-11)


def test_gradients_in_the_field_and_the_moment_match_finite_differences(magnet_model):
    part = magnet_model.magnetic

    def tip_y(field, moment):
        model = magnet_model.replace(
            magnetic=dataclasses.replace(part, field=field, moment=moment))
        return sj.solve_static(model, SETTINGS).p[-1, 1]

    grads = jax.jit(jax.grad(tip_y, argnums=(0, 1)))(part.field, part.moment)
    value = jax.jit(tip_y)
    eps = 1e-6
    d_field = jnp.array([0.3, 1.0, -0.2])
    d_moment = jnp.asarray(np.random.default_rng(0).standard_normal(part.moment.shape))
    for grad, direction, args in ((grads[0], d_field, lambda e: (part.field + e * d_field,
                                                                 part.moment)),
                                  (grads[1], d_moment, lambda e: (part.field,
                                                                  part.moment + e * d_moment))):
        fd = (value(*args(eps)) - value(*args(-eps))) / (2 * eps)
        assert abs(float(jnp.vdot(grad, direction)) - float(fd)) < 1e-6 * max(1.0, abs(fd))


# ----------------------------------------------------------------------------- fluid

RHO_F, CN, DIAMETER = 1000.0, 1.2, 0.01


def current_scene(speed, elements=20):
    """A clamped, stiff rod along x in a current along y (no gravity)."""
    return sj.Scene.from_dict({
        "solver": {"kind": "static"},
        "fluid": {"density": RHO_F, "drag_normal": CN, "velocity": [0.0, speed, 0.0]},
        "rods": [{"name": "rod", "elements": elements,
                  "geometry": {"kind": "straight", "length": 0.5},
                  "stiffness": dict(EA=1e6, GAy=1e6, GAz=1e6, GJ=50.0, EIy=50.0, EIz=50.0),
                  "inertia": dict(rhoA=0.1, rhoJ=1e-6, rhoIy=1e-6, rhoIz=1e-6),
                  "hydraulic_diameter": DIAMETER}],
        "constraints": [{"kind": "clamp", "rod": "rod", "node": 0}]})


def test_cantilever_in_a_current_bends_as_under_its_uniform_drag():
    speed = 2.0
    model = sj.build_model(current_scene(speed))
    eq = sj.solve_static(model, SETTINGS)
    assert bool(eq.converged)
    q = 0.5 * RHO_F * CN * DIAMETER * speed ** 2            # N/m along +y
    expected = q * 0.5 ** 4 / (8 * 50.0)
    assert abs(float(eq.p[-1, 1]) - expected) < 5e-4 * expected
    # drag grows with the square of the current: twice the speed, four times the drag
    # (the model's current is a traced leaf: no new model, no recompilation)
    faster = model.replace(fluid=dataclasses.replace(model.fluid,
                                                     current=2 * model.fluid.current))
    tip = float(sj.solve_static(faster, SETTINGS).p[-1, 1])
    assert abs(tip - 4 * expected) < 2e-3 * 4 * expected

    def tip_y(cn):
        return sj.solve_static(model.replace(fluid=dataclasses.replace(
            model.fluid, drag_normal=cn)), SETTINGS).p[-1, 1]

    grad = float(jax.jit(jax.grad(tip_y))(model.fluid.drag_normal))
    eps = 1e-4
    fd = float(tip_y(CN + eps) - tip_y(CN - eps)) / (2 * eps)
    assert abs(grad - fd) < 1e-6 * abs(fd)
    assert abs(grad - expected / CN) < 2e-2 * expected / CN


def sinking_scene(t_end=0.6, dt=0.005, added_mass=1.0):
    return sj.Scene.from_dict({
        "solver": {"kind": "dynamic", "t_end": t_end, "dt": dt},
        "gravity": {"vector": [0.0, 0.0, -9.81]},
        "fluid": {"density": RHO_F, "drag_normal": CN, "added_mass": added_mass},
        "materials": [{"name": "m", "E": 1e7, "nu": 0.3, "density": 2000.0}],
        "rods": [{"name": "rod", "elements": 4, "geometry": {"kind": "straight", "length": 0.2},
                  "material": "m", "section": {"shape": "circle", "diameter": DIAMETER}}]})


def test_rod_sinking_broadside_reaches_its_terminal_speed_with_added_mass():
    result = sj.run(sinking_scene())
    assert result.converged
    area = np.pi * DIAMETER ** 2 / 4
    k = 0.5 * RHO_F * CN * DIAMETER
    v_terminal = np.sqrt((2000.0 - RHO_F) * area * 9.81 / k)
    m_eff = (2000.0 + RHO_F * 1.0) * area                     # rod + added mass, kg/m
    t = np.asarray(result.time)
    exact = -v_terminal * np.tanh(k * v_terminal * t / m_eff)
    v = np.asarray(result.velocities("rod"))                  # (T, nodes, 6), body frame
    np.testing.assert_allclose(v[:, :, 2], np.repeat(exact[:, None], v.shape[1], 1),
                               rtol=0, atol=2e-3 * v_terminal)
    assert abs(v[-1, 0, 2] + v_terminal) < 1e-3 * v_terminal
    np.testing.assert_allclose(v[:, :, [0, 1, 3, 4, 5]], 0.0, atol=1e-9)


@pytest.mark.parametrize("change, key", [
    ({"fluid": {"density": -1.0}}, "fluid.density"),
    ({"fluid": {"density": 1.0, "drag_normal": -0.1}}, "fluid.drag_normal"),
    ({"fluid": {"density": 1.0, "buoyancy": "yes"}}, "fluid.buoyancy"),
    ({"fluid": {"density": 1.0, "colour": 1}}, "fluid"),
    ({"magnetic_field": {}}, "magnetic_field.vector"),
    ({"magnetic_field": {"vector": [0, 1]}}, "magnetic_field.vector"),
    ({"magnetic_field": {"vector": [0, 1, 0], "profile": {"kind": "sine"}}},
     "magnetic_field.profile.kind"),
])
def test_bad_field_sections_are_refused_naming_the_key(change, key):
    scene = magnetic_scene(2).to_dict()
    scene.update(change)
    with pytest.raises(ValueError, match="^" + key.replace(".", r"\.")):
        sj.Scene.from_dict(scene)


def test_bad_rod_keys_are_refused_naming_the_key():
    scene = magnetic_scene(2).to_dict()
    rod = {k: v for k, v in scene["rods"][0].items() if k != "magnetic_moment"}
    with pytest.raises(ValueError, match=r"^rods\[0\]\.magnetization: needs a section"):
        sj.Scene.from_dict(dict(scene, rods=[dict(rod, magnetization=[1.0, 0, 0])]))
    with pytest.raises(ValueError, match=r"^rods\[0\]\.magnetic_moment: give magnetization"):
        sj.Scene.from_dict(dict(scene, rods=[dict(rod, magnetization=[1.0, 0, 0],
                                                 magnetic_moment=[1.0, 0, 0],
                                                 section={"shape": "circle", "diameter": 0.01},
                                                 material="silicone")]))
    with pytest.raises(ValueError, match=r"^rods\[0\]\.hydraulic_diameter: required under"):
        sj.Scene.from_dict(dict(scene, rods=[rod], fluid={"density": 1000.0}))


def fields_scene(kind):
    """The all-loads rod of tests/test_one_model.py in a ramped field and a current, with
    buoyancy, both drags and added mass."""
    from test_one_model import dynamic_scene, static_scene
    scene = dynamic_scene() if kind == "dynamic" else static_scene()
    scene["magnetic_field"] = {"vector": [0.01, 0.03, -0.02],
                               "profile": {"kind": "ramp", "t0": 0.003, "t1": 0.305}}
    scene["rods"][0]["magnetization"] = [2e4, -5e3, 1e4]
    scene["fluid"] = {"density": 800.0, "drag_normal": 1.1, "drag_tangent": 0.05,
                      "velocity": [0.2, -0.1, 0.05], "added_mass": 0.9}
    return scene


def test_tangent_paths_agree_with_fields_in_statics_and_dynamics():
    """Closed-form and autodiff paths: the static tangent and the dynamic iteration matrix
    with both registered terms agree to round-off; the static tangent matches central
    differences of the residual along the chart."""
    from test_tangent_paths import check_dynamic_paths, check_static_paths
    from simsoft_jax.model import loads

    check_static_paths(sj.build_model(sj.Scene.from_dict(fields_scene("static"))))
    check_dynamic_paths(loads.loads_at(
        sj.build_model(sj.Scene.from_dict(fields_scene("dynamic"))), 0.2))
