"""One traced model (core redesign): every array a solve reads lives in the Model, so
replacing any of them changes the solve and its gradient; float settings are traced.

References are independent of the code's earlier output: a model rebuilt from a scene
with the changed numbers, central finite differences, and a compile counter read from
JAX's own compile log.
"""
import logging

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import simsoft_jax as sj
from conftest import primal
from simsoft_jax.math import lie

ROD = {"name": "arm", "elements": 4, "geometry": {"kind": "arc", "radius": 1.5, "angle_deg": 30},
       "stiffness": {"EA": 2e3, "GAy": 1e3, "GAz": 1.5e3, "GJ": 0.8, "EIy": 1.0, "EIz": 1.7},
       "inertia": {"rhoA": 0.2, "rhoJ": 2e-3, "rhoIy": 1e-3, "rhoIz": 1.5e-3}}


def dynamic_scene(**changes):
    """A curved rod with every kind of load and time law, viscosity and mass-proportional
    damping, an attached mass at an offset, a helical tendon over part of the rod and a
    pressure chamber, an initial velocity and a driven base (a rotation table). No time-law sample falls on a step time (the
    laws are piecewise linear: a kink on a step would make finite differences in the
    sample times one-sided)."""
    rod = dict(ROD, **changes.pop("rod", {}))
    scene = {
        "solver": {"kind": "dynamic", "t_end": 0.5, "dt": 0.01, "rho_inf": 0.8},
        "gravity": {"vector": [0.0, 0.0, -9.81]},
        "materials": [{"name": "m", "E": 1e6, "nu": 0.3, "density": 1e3, "viscosity": 50.0,
                       "mass_damping": 0.5}],
        "rods": [dict(rod, material="m", section={"shape": "circle", "diameter": 0.05})],
        "constraints": [{"kind": "drive", "rod": "arm", "node": 0, "times": [0.002, 0.505],
                         "displacement": [[0, 0, 0], [0.0, 0.01, 0.0]],
                         "rotation": [[0, 0, 0], [0.05, 0.0, 0.1]]}],
        "loads": [
            {"kind": "force", "rod": "arm", "node": -1, "vector": [0.0, 0.2, -0.3]},
            {"kind": "moment", "rod": "arm", "node": 2, "vector": [0.02, 0.0, 0.01],
             "frame": "local"},
            {"kind": "force", "rod": "arm", "node": -1, "vector": [0.1, 0.0, 0.05],
             "profile": {"kind": "ramp", "t0": 0.003, "t1": 0.305}},
            {"kind": "distributed_force", "rod": "arm", "vector": [0.0, 0.05, 0.0]},
            {"kind": "distributed_force", "rod": "arm", "vector": [0.0, 0.0, 0.04],
             "frame": "local", "profile": {"kind": "table", "t": [0.002, 0.205, 0.505],
                                           "scale": [0.0, 1.0, 0.5]}}],
        "initial_velocity": [{"rod": "arm", "linear": [0, 0, 0], "angular": [0.0, 0.3, 0.2]}],
        "masses": [{"rod": "arm", "node": -1, "mass": 0.05, "offset": [0.0, 0.02, 0.01],
                    "inertia": [[2e-5, 0, 0], [0, 1e-5, 0], [0, 0, 1.5e-5]]}],
        "tendons": [{"name": "t1", "rod": "arm", "from_node": 0, "to_node": 3,
                     "offset": {"kind": "helix", "radius": 0.01, "pitch": 0.8,
                                "phase_deg": 30.0}, "tension": 0.5,
                     "profile": {"kind": "ramp", "t0": 0.003, "t1": 0.305}}],
        "chambers": [{"name": "c1", "rod": "arm", "area": 1e-4, "offset": [0.01, -0.005],
                      "pressure": 2e3, "profile": {"kind": "table", "t": [0.002, 0.505],
                                                   "scale": [0.2, 1.0]}}],
    }
    scene.update(changes)
    return scene


def static_scene():
    scene = dynamic_scene()
    scene["solver"] = {"kind": "static", "tolerance": 1e-13}
    scene["constraints"] = [{"kind": "clamp", "rod": "arm", "node": 0}]
    del scene["initial_velocity"]
    return scene


SETTINGS = sj.DynamicSettings(dt=0.01, steps=50, rho_inf=0.8, tolerance=1e-13)
COUNTS_COMPILATIONS = True   # conftest: start this module with no program in memory


def test_changed_loads_and_inertia_reach_the_rollout():
    """Regression (defect 1 of the redesign issue): scaling the Model's constant loads by 10
    moved the tip by exactly 0.0, and doubling ``model.inertia`` changed only the gravity
    and gyroscopic terms. Now both runs equal runs of models rebuilt from scenes with the
    same numbers (to round-off)."""
    model = sj.build_model(sj.Scene.from_dict(dynamic_scene()))
    base = sj.simulate(model, SETTINGS)
    louder = sj.simulate(model.replace(nodal_dead=10 * model.nodal_dead), SETTINGS)
    scene = dynamic_scene()
    scene["loads"][0]["vector"] = [0.0, 2.0, -3.0]
    rebuilt = sj.simulate(sj.build_model(sj.Scene.from_dict(scene)), SETTINGS)
    assert float(jnp.abs(louder.p[-1, -1] - base.p[-1, -1]).max()) > 1e-3
    np.testing.assert_allclose(louder.p, rebuilt.p, rtol=0, atol=1e-12)

    heavier = sj.simulate(model.replace(inertia=2 * model.inertia), SETTINGS)
    doubled = {key: 2 * value for key, value in ROD["inertia"].items()}
    rebuilt = sj.simulate(sj.build_model(sj.Scene.from_dict(
        dynamic_scene(rod={"inertia": doubled}))), SETTINGS)
    assert float(jnp.abs(heavier.p[-1, -1] - base.p[-1, -1]).max()) > 1e-3
    np.testing.assert_allclose(heavier.p, rebuilt.p, rtol=0, atol=1e-12)


def _direction(leaf, rng):
    """A random direction for one float leaf, each entry scaled like that entry (so a
    finite-difference step is the same relative change everywhere), zeros like a
    thousandth of the leaf's mean size."""
    size = np.abs(np.asarray(leaf))
    return rng.standard_normal(np.shape(leaf)) * (size + 1e-3 * (size.mean() + 1e-3))


def _perturb(model, name, direction, eps):
    """The model with leaf ``name`` moved by ``eps`` along ``direction``; rotations move
    as ``R exp(eps w)`` so that finite differences stay on SO(3)."""
    if name == "R0":
        R = model.R0 @ jax.vmap(lie.exp_so3)(eps * direction)
        return model.replace(R0=R)
    leaves = dict(_named_leaves(model))
    new = leaves[name] + eps * direction
    return _replace_leaf(model, name, new)


def _named_leaves(model):
    out = []
    for path, leaf in jax.tree_util.tree_flatten_with_path(model)[0]:
        name = ".".join(str(getattr(k, "name", k)) for k in path)
        out.append((name, leaf))
    return out


def _replace_leaf(model, name, value):
    paths = [n for n, _ in _named_leaves(model)]
    leaves = [value if n == name else leaf for n, leaf in _named_leaves(model)]
    assert name in paths
    return jax.tree_util.tree_unflatten(jax.tree_util.tree_structure(model), leaves)


def _check_every_leaf(model, scalar, skip=(), rtol=1e-5):
    """Reverse-mode gradient of ``scalar(model)`` along a random direction of every float
    leaf against central finite differences (1e-5 relative, above the differences' noise
    floor). Returns the leaves whose derivative is non-zero (so the test knows which ones
    were really exercised). The differences take the values by :func:`conftest.primal`
    (the programs of the gradient's forward pass, none compiled for them alone)."""
    rng = np.random.default_rng(7)
    grad = jax.grad(scalar)(model)
    grads = dict(_named_leaves(grad))
    value = float(primal(scalar, model))
    moved = []
    for name, leaf in _named_leaves(model):
        if name in skip or not jnp.issubdtype(jnp.asarray(leaf).dtype, jnp.floating) or leaf.size == 0:
            continue
        if name == "R0":
            direction = rng.standard_normal((leaf.shape[0], 3))
            # d/de f(R exp(e skew(w))) = <grad_R, R skew(w)>
            tangent = jnp.asarray(leaf) @ jax.vmap(lie.skew)(jnp.asarray(direction))
            analytic = float(jnp.sum(grads[name] * tangent))
        else:
            direction = _direction(leaf, rng)
            analytic = float(jnp.sum(grads[name] * direction))
        eps = 1e-6
        fd = (float(primal(scalar, _perturb(model, name, jnp.asarray(direction), eps)))
              - float(primal(scalar, _perturb(model, name, jnp.asarray(direction), -eps)))
              ) / (2 * eps)
        # 1e-5 relative; the floor is the noise of a central difference of solves
        # converged to ~1e-13 (relative) with a step of 1e-6: ~1e-7 of the scalar
        assert abs(analytic - fd) <= rtol * abs(fd) + 1e-6 * abs(value), (name, analytic, fd)
        if abs(fd) > 1e-6 * abs(value):
            moved.append(name)
    return moved


def test_static_gradient_over_every_model_leaf():
    """d(scalar of the equilibrium)/d(every float array of the Model) by the implicit
    function theorem agrees with central differences to 1e-5 relative."""
    model = sj.build_model(sj.Scene.from_dict(static_scene()))
    weights = jnp.asarray(np.random.default_rng(1).standard_normal(model.p0.shape))
    settings = sj.StaticSettings(tolerance=1e-13)

    def scalar(m):
        eq = sj.solve_static(m, settings)
        return jnp.sum(weights * eq.p) + jnp.sum(eq.R[-1] * jnp.eye(3)[::-1])

    # time laws play no role in statics; P and A enter as their product (pressure checked)
    moved = _check_every_leaf(model, scalar, skip=(
        "tendon_displacement", "chamber_area", "tendon_law.params", "tendon_law.table_t",
        "tendon_law.table_scale", "chamber_law.params", "chamber_law.table_t",
        "chamber_law.table_scale"))
    assert {"stiffness", "d0", "length", "inertia", "gravity", "nodal_dead", "nodal_follower",
            "distributed_world", "channels.nodal_dead", "channels.distributed_local",
            "tendon_tension", "tendon_offset", "tendon_slope", "chamber_pressure",
            "chamber_offset"} <= set(moved), moved


@pytest.mark.slow
def test_rollout_gradient_over_every_model_leaf():
    """The same through a 50-step differentiable rollout (implicit derivative of each step):
    initial frames and velocities, inertia, viscosity, loads and their time-law tables,
    drive tables, gravity, stiffness and reference geometry."""
    model = sj.build_model(sj.Scene.from_dict(dynamic_scene()))
    weights = jnp.asarray(np.random.default_rng(2).standard_normal(model.p0.shape))

    def scalar(m):
        traj = sj.simulate(m, SETTINGS, differentiable=True)
        return jnp.sum(weights * traj.p[-1]) + jnp.sum(traj.v[-1, -1])

    # actuator leaves the static test checks already, or that this scene's laws do not
    # read (a ramp has no table, a table no ramp times), are skipped (each costs 2 rollouts)
    moved = _check_every_leaf(model, scalar, skip=(
        "tendon_displacement", "tendon_slope", "chamber_area", "chamber_offset",
        "tendon_law.table_t", "tendon_law.table_scale", "chamber_law.params",
        "chamber_law.table_t"))
    assert {"R0", "p0", "v0", "stiffness", "d0", "length", "inertia", "viscosity", "gravity",
            "nodal_dead", "nodal_follower", "distributed_world", "channels.params",
            "channels.table_scale", "channels.nodal_dead", "channels.distributed_local",
            "drive_rotation", "drive_displacement", "mass_damping", "mass", "mass_offset",
            "mass_inertia", "tendon_tension", "tendon_offset", "tendon_law.params",
            "chamber_pressure", "chamber_law.table_scale"} <= set(moved), moved


class _CompileCounter(logging.Handler):
    """Counts JAX's "Compiling jit(<name>)" log records, for any of ``names``."""

    def __init__(self, *names):
        super().__init__(logging.DEBUG)
        self.names, self.count = names, 0

    def emit(self, record):
        if any(record.getMessage().startswith(f"Compiling jit({name})")
               for name in self.names):
            self.count += 1


def test_dt_study_compiles_once():
    """Five time steps, two rho_inf and two tolerances on one structure: at most one
    compilation of the rollout (dt, rho_inf and tolerance are traced; none when ``sj.run``
    compiled it earlier in this process: ``sj.simulate`` runs its program), and each run
    differs."""
    model = sj.build_model(sj.Scene.from_dict(dynamic_scene()))
    counter = _CompileCounter("rollout_program", "_chunk")
    logger = logging.getLogger("jax")
    logger.addHandler(counter)
    level = logger.level
    logger.setLevel(logging.DEBUG)
    try:
        with jax.log_compiles(True):
            tips = []
            for dt, rho, tol in [(0.002, 0.8, 1e-10), (0.004, 0.8, 1e-10), (0.005, 0.9, 1e-9),
                                 (0.008, 0.9, 1e-10), (0.01, 0.8, 1e-9)]:
                traj = sj.simulate(model, sj.DynamicSettings(dt=dt, steps=20, rho_inf=rho,
                                                             tolerance=tol))
                assert bool(traj.converged)
                assert float(traj.time[-1]) == pytest.approx(20 * dt)
                tips.append(np.asarray(traj.p[-1, -1]))
    finally:
        logger.removeHandler(counter)
        logger.setLevel(level)
    assert counter.count <= 1
    assert min(np.linalg.norm(a - b) for i, a in enumerate(tips) for b in tips[:i]) > 1e-6


def test_viscosity_on_a_model_built_without_it_is_refused():
    scene = dynamic_scene()
    scene["materials"][0]["viscosity"] = 0.0
    model = sj.build_model(sj.Scene.from_dict(scene))
    assert model.viscosity is None
    with pytest.raises(ValueError, match="^viscosity: this model was built without"):
        model.replace(viscosity=np.ones((model.structure.n_elements, 6)))


def test_replace_refuses_parts_the_model_was_built_without_and_changed_shapes():
    """A part the scene lacks is None and gets no value, zeros included, nor inside jit
    (the solvers compiled for the model do not read it), with a ValueError naming the
    field; a present part takes traced values. The reference: a model rebuilt from the
    scene with the load present gives a different equilibrium, so the refused value was
    one that matters."""
    scene = {"solver": {"kind": "static"},
             "rods": [{"name": "r", "elements": 3, "geometry": {"kind": "straight", "length": 1.0},
                       "stiffness": {"EA": 1e4, "GAy": 1e4, "GAz": 1e4, "GJ": 1.0,
                                     "EIy": 1.0, "EIz": 1.0},
                       "inertia": {"rhoA": 0.1, "rhoJ": 1e-3, "rhoIy": 1e-3, "rhoIz": 1e-3}}],
             "constraints": [{"kind": "clamp", "rod": "r", "node": 0}],
             "loads": [{"kind": "moment", "rod": "r", "node": -1, "vector": [0, 0.1, 0],
                        "frame": "local"}]}
    model = sj.build_model(sj.Scene.from_dict(scene))
    tip = np.zeros((4, 6))
    tip[-1, 2] = 0.5
    for key, value in (("nodal_dead", tip), ("nodal_dead", np.zeros((4, 6))),
                       ("gravity", np.array([0.0, 0.0, -9.81])),
                       ("distributed_world", np.ones((3, 3)))):
        assert getattr(model, key) is None
        with pytest.raises(ValueError, match=f"^{key}: this model was built without"):
            model.replace(**{key: value})
    with pytest.raises(ValueError, match="^gravity: this model was built without gravity"):
        jax.jit(lambda g: model.replace(gravity=g).p0)(jnp.array([0.0, 0.0, -1.0]))
    with pytest.raises(ValueError, match="^nodal_dead: this model was built without"):
        model.channels.replace(nodal_dead=np.zeros((0, 4, 6)))
    with pytest.raises(ValueError, match=r"Model.replace: stiffness: shape \(3, 6, 6\)"):
        model.replace(stiffness=np.broadcast_to(np.eye(6), (3, 6, 6)))
    traced = jax.jit(lambda f: model.replace(nodal_follower=f).nodal_follower)(jnp.ones((4, 6)))
    np.testing.assert_array_equal(np.asarray(traced), 1.0)
    scene["loads"].append({"kind": "force", "rod": "r", "node": -1, "vector": [0, 0, 0.5]})
    loaded = sj.build_model(sj.Scene.from_dict(scene))
    assert loaded.nodal_dead is not None
    plain = sj.solve_static(model, sj.StaticSettings())
    pushed = sj.solve_static(loaded, sj.StaticSettings())
    assert float(jnp.abs(pushed.p[-1, 2] - plain.p[-1, 2])) > 1e-3
