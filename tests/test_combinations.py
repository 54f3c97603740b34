"""Every pair of scene features in one scene, in statics and in dynamics, with a physical
check: a rod built as two rods welded end to end gives exactly the answer of the same rod
built as one, whatever else is in the scene (the weld is rigid, and each feature acts on
the welded pair as it acts on the one rod). The features: a body welded at the tip
(joints and bodies), rod-rod contact with a clamped crossing rod, a sphere with Coulomb
friction under the tip (obstacle contact with friction), a displacement-controlled
tendon, a tension tendon, a pressure chamber and a point mass at the tip. The root is
clamped in statics; in dynamics it is on a drive sliding along the rod (a static solve
has no force to hold a slide), in every pair. The rollouts' gradients (tip position in
the stiffness and the tip force) equal central finite differences.

All features are in one scene structure per kind (static, dynamic), so that its
programs compile once; a pair switches the other features off through the model's
arrays (:func:`only`): zero tension, pressure and masses (the body a massless
connector), the sphere and the crossing rod moved 1 m away. The displacement-controlled
tendon and the sliding drive cannot be switched off: off the pair the tendon runs along
the centreline with its length held (the rods' axial stiffness is 1e4 N, so it changes
little) -- the equivalence holds whatever else the scene holds."""
from __future__ import annotations

import functools
import itertools

import jax
import numpy as np
import pytest

import simsoft_jax as sj
from conftest import primal

FEATURES = ("body", "rod_contact", "friction", "displaced_tendon", "tendon", "chamber",
            "mass")
L, ELEMENTS, R = 0.4, 4, 0.01        # main rod: length (m), elements, contact radius (m)
SPHERE = 0.05                        # radius (m) of the sphere under the tip
TIP_FORCE = [0.3, 0.2, -1.0]         # N, world
STIFFNESS = {"EA": 1e4, "GAy": 1e4, "GAz": 1e4, "GJ": 0.5, "EIy": 1.0, "EIz": 1.0}
INERTIA = {"rhoA": 0.5, "rhoJ": 2e-4, "rhoIy": 1e-4, "rhoIz": 1e-4}


def _rod(name, x0, length, elements, along_y=False, z=0.0):
    return {"name": name, "elements": elements, "stiffness": STIFFNESS, "inertia": INERTIA,
            "geometry": {"kind": "straight", "length": length}, "contact_radius": R,
            "base": {"position": [0.0, x0, z] if along_y else [x0, 0.0, z],
                     "rotation": [0.0, 0.0, np.pi / 2 if along_y else 0.0]}}


def scene(features, welded: bool, kind: str) -> dict:
    """The main rod along x from the origin (one rod "a", or rods "a" and "b" welded at
    mid-span), held at its root (static: clamped; dynamic: on a drive sliding along x),
    under gravity and a tip force, with ``features``."""
    from simsoft_jax.physics.terms.contact import SMOOTHING
    if welded:
        rods = [_rod("a", 0.0, L / 2, ELEMENTS // 2), _rod("b", L / 2, L / 2, ELEMENTS // 2)]
        joints = [{"kind": "weld", "a": {"rod": "a", "node": -1}, "b": {"rod": "b", "node": 0}}]
    else:
        rods, joints = [_rod("a", 0.0, L, ELEMENTS)], []
    tip = "b" if welded else "a"
    if kind == "dynamic":
        root = {"kind": "drive", "rod": "a", "node": 0, "times": [0.0],
                "displacement": [[0.0, 0.0, 0.0]], "slides_along": [1.0, 0.0, 0.0]}
    else:
        root = {"kind": "clamp", "rod": "a", "node": 0}
    d = {"name": "pair", "rods": rods, "constraints": [root], "joints": joints,
         "gravity": {"vector": [0.0, 0.0, -9.81]},
         "loads": [{"kind": "force", "rod": tip, "node": -1, "vector": TIP_FORCE}],
         "solver": ({"kind": "static", "load_steps": 4} if kind == "static" else
                    {"kind": "dynamic", "dt": 0.005, "t_end": 0.02, "rho_inf": 0.8})}
    touching = -2 * R + SMOOTHING * 2 * R        # centre distance a smoothing width in
    if "body" in features:
        d["bodies"] = [{"name": "tool", "mass": 0.05, "position": [L, 0.0, 0.0],
                        "inertia": [[2e-5, 0, 0], [0, 1e-5, 0], [0, 0, 1e-5]]}]
        d["joints"] = joints + [{"kind": "weld", "a": {"rod": tip, "node": -1},
                                 "b": {"body": "tool"}}]
    if "rod_contact" in features:
        d["rods"] = rods + [_rod("under", -0.1, 0.2, 2, along_y=True, z=touching)]
        d["rods"][-1]["base"]["position"][0] = 0.75 * L
        d["constraints"] = d["constraints"] + [
            {"kind": "clamp", "rod": "under", "node": n} for n in (0, -1)]
        d.setdefault("contact", {}).update({"self": True, "max_pairs": 4,
                                            "quadrature_points": 2})
    if "friction" in features:
        d["obstacles"] = [{"name": "ball", "kind": "sphere", "radius": SPHERE,
                           "center": [L, 0.0, touching / 2 - SPHERE], "friction": 0.3}]
        d.setdefault("contact", {}).update({"stiffness": 2e4, "slip_velocity": 0.05,
                                            "slip_displacement": 1e-4})
    if "mass" in features:
        d["masses"] = [{"rod": tip, "node": -1, "mass": 0.03, "offset": [0.0, 0.01, 0.0]}]
    tendons = []
    if "tendon" in features:
        tendons.append({"name": "t", "rod": "a", "to_rod": tip, "offset": [0.004, -0.005],
                        "tension": 8.0})
    if "displaced_tendon" in features:
        tendons.append({"name": "d", "rod": "a", "to_rod": tip, "offset": [-0.004, -0.005],
                        "displacement": -4e-4})
    if tendons:
        d["tendons"] = tendons
    if "chamber" in features:
        d["chambers"] = [{"name": f"c{rod['name']}", "rod": rod["name"], "area": 1e-4,
                          "offset": [0.005, 0.0], "pressure": 3e4} for rod in rods]
    return d


def _main_rod(positions, structure):
    """The main rod's node positions ((T,) N, 3) from the model's nodes (..., nodes, 3),
    the welded pair joined at its weld."""
    rods = {rod.name: rod for rod in structure.rods}
    parts = [positions[..., rods["a"].first_node:rods["a"].first_node + rods["a"].nodes, :]]
    if "b" in rods:
        b = rods["b"]
        parts.append(positions[..., b.first_node + 1:b.first_node + b.nodes, :])
    return np.concatenate(parts, axis=-2)


@functools.lru_cache(maxsize=None)
def model(welded: bool, kind: str):
    """The model of the scene with every feature."""
    return sj.build_model(sj.Scene.from_dict(scene(set(FEATURES), welded, kind)))


def only(m, pair):
    """``m`` with the features outside ``pair`` switched off (module docstring)."""
    s = m.structure
    body_node = dict(s.bodies)["tool"]
    is_body = np.array(s.mass_nodes) == body_node
    keep_mass = np.where(is_body, "body" in pair, "mass" in pair)
    rods = {rod.name: rod for rod in s.rods}
    under = rods["under"]
    shift = np.zeros(np.shape(m.p0))
    if "rod_contact" not in pair:
        shift[under.first_node:under.first_node + under.nodes, 2] = -1.0
    names = list(s.tendon_names)
    tension = np.array(m.tendon_tension)
    tension[names.index("t")] *= "tendon" in pair
    offset, slope = np.array(m.tendon_offset), np.array(m.tendon_slope)
    displacement = np.array(m.tendon_displacement)
    if "displaced_tendon" not in pair and "d" in names:
        k = names.index("d")
        offset[k], slope[k], displacement[k] = 0.0, 0.0, 0.0
    obstacles = np.array(m.obstacles)
    if "friction" not in pair:
        obstacles[0, :3] += [0.0, 0.0, -1.0]
    return m.replace(
        mass=np.asarray(m.mass) * keep_mass,
        mass_inertia=np.asarray(m.mass_inertia) * keep_mass[:, None, None],
        p0=np.asarray(m.p0) + shift, tendon_tension=tension, tendon_offset=offset,
        tendon_slope=slope, tendon_displacement=displacement,
        chamber_pressure=np.asarray(m.chamber_pressure) * ("chamber" in pair),
        obstacles=obstacles)


PAIRS = list(itertools.combinations(FEATURES, 2))
STATIC = sj.StaticSettings(load_steps=4)
DYNAMIC = sj.DynamicSettings(dt=0.005, steps=4, rho_inf=0.8)
# The gradients' rollouts over the same 0.02 s in steps of a quarter: at 5 ms the friction
# pairs sub-step every step (in four), which needs a rollout program that records the
# sub-steps and a backward program of its own; at 1.25 ms no pair sub-steps, so every
# pair's gradient takes the backward program over whole steps (one for all pairs).
GRADIENT = sj.DynamicSettings(dt=0.00125, steps=16, rho_inf=0.8)


def _assert_equal_main_rods(welded, one, structures):
    ref = _main_rod(one, structures[1])
    rest = np.linspace(0.0, L, ELEMENTS + 1)[:, None] * np.array([1.0, 0.0, 0.0])
    moved = np.abs(ref - rest).max()
    assert moved > 1e-4                           # the loads move the rod
    np.testing.assert_allclose(_main_rod(welded, structures[0]), ref,
                               atol=1e-7 * moved + 1e-12)


@pytest.mark.parametrize("pair", PAIRS, ids="+".join)
def test_static_pair_welded_equals_one_rod(pair):
    models = [only(model(w, "static"), pair) for w in (True, False)]
    eqs = [sj.solve_static(m, STATIC) for m in models]
    for eq in eqs:
        assert bool(eq.converged), eq.message()
    _assert_equal_main_rods(eqs[0].p, eqs[1].p, [m.structure for m in models])


@pytest.mark.parametrize("pair", PAIRS, ids="+".join)
def test_dynamic_pair_welded_equals_one_rod(pair):
    models = [only(model(w, "dynamic"), pair) for w in (True, False)]
    runs = [sj.simulate(m, DYNAMIC) for m in models]
    for run in runs:
        assert bool(np.all(run.converged)), run
    _assert_equal_main_rods(runs[0].p, runs[1].p, [m.structure for m in models])


def _tip():
    """The welded model's tip node and the measure ``tip . weights`` of its rollout in
    ``theta = (stiffness scale, tip force scale)``. Not jitted: the rollout is the
    program the pair tests compiled already, and ``jax.grad`` adds only the adjoint's
    backward program, one for all pairs (:data:`GRADIENT`); the finite differences take
    its values by :func:`conftest.primal`, with the same program (called plainly, the
    differentiable rollout compiles one of its own)."""
    b = next(rod for rod in model(True, "dynamic").structure.rods if rod.name == "b")
    tip = b.first_node + b.nodes - 1
    weights = np.array([1.0, 2.0, -1.0])

    def tip_position(theta, m):
        m = m.replace(stiffness=m.stiffness * theta[0], nodal_dead=m.nodal_dead * theta[1])
        return sj.simulate(m, GRADIENT, differentiable=True).p[-1, tip] @ weights

    return tip_position


@pytest.mark.parametrize("pair", PAIRS, ids="+".join)
def test_dynamic_pair_gradient_equals_finite_differences(pair):
    """d(tip . c)/d(stiffness scale, tip force scale) of the welded pair's rollout."""
    m = only(model(True, "dynamic"), pair)
    value = _tip()
    gradient = jax.grad(value)
    theta, h = np.array([1.0, 1.0]), 1e-5
    fd = np.array([(primal(lambda x: value(x, m), theta + h * e)
                    - primal(lambda x: value(x, m), theta - h * e)) / (2 * h)
                   for e in np.eye(2)])
    assert np.abs(fd).max() > 1e-6
    np.testing.assert_allclose(gradient(theta, m), fd, rtol=1e-5,
                               atol=1e-7 * np.abs(fd).max())
