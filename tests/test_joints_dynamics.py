"""Rigid bodies and joints in dynamics (issue 13, items 3-4), against independent
references: a body on a ball joint swings with the exact (elliptic-integral) period of a
physical pendulum; a body welded to a rod moves exactly like the same mass attached to
the node as a ``[[masses]]`` entry (offset and inertia included, large 3-D motion); a rod
cut in two and welded moves like the whole rod; a closed loop (two rods welded to a
platform) keeps its energy in free vibration, with an error that falls at second order in
the time step; gradients through a rollout of the loop against central differences; the
CLI writes the bodies' poses of a dynamic run."""
import dataclasses
import json
import subprocess
import sys

import numpy as np
import pytest
from scipy.special import ellipk

import jax
import jax.numpy as jnp
import simsoft_jax as sj
from simsoft_jax.solvers.dynamics import DynamicSettings, energy, simulate
from simsoft_jax.model.model import build_model
from conftest import REPO_ROOT


def rod(name, length, elements, E=5.0e6, position=(0.0, 0.0, 0.0), rotation=None,
        diameter=0.02, density=1100.0):
    base = {"position": list(position)}
    if rotation is not None:
        base["rotation"] = rotation
    return {"name": name, "material": {"name": "m_" + name, "E": E, "nu": 0.5,
                                        "density": density},
            "section": {"shape": "circle", "diameter": diameter}, "elements": elements,
            "geometry": {"kind": "straight", "length": length}, "base": base}


def clamp(name):
    return {"kind": "clamp", "rod": name, "node": 0}


M_BOB, D_BOB, J_BOB, G, THETA0 = 2.0, 0.25, 0.01, 9.81, np.deg2rad(40.0)


def pendulum_scene():
    """A body (mass M_BOB, inertia J_BOB about its centre) hanging D_BOB below a ball joint
    at a clamped rod node (the origin), at rest at THETA0; 2 s at dt = 5 ms, rho_inf 1."""
    return {"solver": {"kind": "dynamic", "t_end": 2.0, "dt": 0.005, "rho_inf": 1.0},
            "gravity": {"vector": [0.0, -G, 0.0]},
            "rods": [rod("post", 0.1, 2, E=2e11, diameter=0.01, density=7800.0,
                         rotation={"axis": [0, 0, 1], "angle_deg": 90.0})],
            "constraints": [clamp("post")],
            "bodies": [{"name": "bob", "mass": M_BOB, "inertia": (J_BOB * np.eye(3)).tolist(),
                        "position": [D_BOB * np.sin(THETA0), -D_BOB * np.cos(THETA0), 0.0],
                        "rotation": {"axis": [0, 0, 1], "angle_deg": np.rad2deg(THETA0)}}],
            "joints": [{"kind": "ball", "a": {"rod": "post", "node": 0},
                        "b": {"body": "bob", "offset": [0.0, D_BOB, 0.0]}}]}


def test_ball_jointed_body_swings_with_the_exact_pendulum_period():
    """The physical pendulum's period ``4 sqrt(I_p / (m g d)) K(sin^2(theta0/2))`` with
    ``I_p = Jc + m d^2`` (elliptic integral K); dt = T/215 at rho_inf = 1: the scheme's
    period error is O(dt^2), about 1e-4 here. The joint holds to the solver tolerance."""
    result = sj.run(pendulum_scene())
    assert result.converged
    p, R = result.body_pose("bob")
    t = np.asarray(result.time)
    x = p[:, 0]
    i = np.nonzero(np.sign(x[:-1]) != np.sign(x[1:]))[0]
    crossings = t[i] - x[i] * (t[i + 1] - t[i]) / (x[i + 1] - x[i])
    assert len(crossings) >= 3
    period = 2.0 * np.mean(np.diff(crossings))
    I_p = J_BOB + M_BOB * D_BOB**2
    exact = 4.0 * np.sqrt(I_p / (M_BOB * G * D_BOB)) * ellipk(np.sin(THETA0 / 2) ** 2)
    assert abs(period / exact - 1.0) < 3e-4, (period, exact)
    gap = p + np.einsum("tij,j->ti", R, [0.0, D_BOB, 0.0])      # the pivot is the origin
    assert np.abs(gap).max() < 1e-10 * D_BOB


def test_cli_run_writes_the_bodies_of_a_dynamic_scene(tmp_path):
    """``simsoft-jax run`` on the pendulum: the result file lists the body's pose at every
    saved time, and in it the joint point stays at the pivot."""
    path, out = tmp_path / "pendulum.json", tmp_path / "out.json"
    scene = pendulum_scene()
    scene["solver"]["t_end"] = 0.2
    path.write_text(json.dumps(scene))
    proc = subprocess.run([sys.executable, "-m", "simsoft_jax.cli", "run", str(path), "-o",
                           str(out)], capture_output=True, text=True, timeout=600,
                          cwd=REPO_ROOT)
    assert proc.returncode == 0, proc.stderr
    d = json.loads(out.read_text())
    position = np.asarray(d["bodies"]["bob"]["position"])
    rotation = np.asarray(d["bodies"]["bob"]["rotation"])
    assert position.shape == (len(d["time"]), 3) and rotation.shape == (len(d["time"]), 3, 3)
    assert np.abs(position[-1] - position[0]).max() > 1e-3
    gap = position + np.einsum("tij,j->ti", rotation, [0.0, D_BOB, 0.0])
    assert np.abs(gap).max() < 1e-10 * D_BOB


def test_welded_body_moves_like_the_same_attached_mass():
    """A body welded to a cantilever's tip, its centre offset from the tip, with a full
    inertia tensor, falls under gravity in a large 3-D motion; the same mass and inertia
    as a ``[[masses]]`` entry at the tip node (its own, independently tested Newton-Euler
    term) gives the same motion to the solver tolerance."""
    L, m = 0.5, 0.05
    c = np.array([0.03, 0.01, -0.02])
    J = np.array([[2e-5, 1e-6, 0.0], [1e-6, 3e-5, 0.0], [0.0, 0.0, 1e-5]])
    common = {"solver": {"kind": "dynamic", "t_end": 0.3, "dt": 0.005, "rho_inf": 0.9},
              "gravity": {"vector": [0.0, 0.0, -9.81]}, "rods": [rod("arm", L, 4)],
              "constraints": [clamp("arm")]}
    body = dict(common, bodies=[{"name": "tip", "mass": m, "inertia": J.tolist(),
                                 "position": [L + c[0], c[1], c[2]]}],
                joints=[{"kind": "weld", "a": {"rod": "arm", "node": -1, "offset": c.tolist()},
                         "b": {"body": "tip"}}])
    attached = dict(common, masses=[{"rod": "arm", "node": -1, "mass": m,
                                     "offset": c.tolist(), "inertia": J.tolist()}])
    a, b = sj.run(body), sj.run(attached)
    assert a.converged and b.converged
    pa, pb = a.positions("arm"), b.positions("arm")
    assert np.abs(pb[:, -1] - pb[0, -1]).max() > 0.2 * L        # a large motion
    assert np.abs(pa - pb).max() < 1e-8 * L
    tip, _ = a.body_pose("tip")
    Rt = a.rotations("arm")[:, -1]
    assert np.abs(tip - pa[:, -1] - np.einsum("tij,j->ti", Rt, c)).max() < 1e-10 * L


@pytest.mark.slow
def test_rod_cut_in_two_and_welded_moves_like_the_whole_rod():
    """Two rods end to end, welded where they meet (a rod-rod weld: one end joins the
    coupling set), swing under gravity and a tendon pulled across the weld (tension ramp)
    like one rod with all their elements and the same tendon."""
    common = {"solver": {"kind": "dynamic", "t_end": 0.2, "dt": 0.005, "rho_inf": 0.9},
              "gravity": {"vector": [0.0, -9.81, 0.3]}}
    tendon = {"name": "t", "rod": "a", "offset": [0.004, 0.003], "tension": 0.5,
              "profile": {"kind": "ramp", "t0": 0.0, "t1": 0.1}}
    cut = dict(common, rods=[rod("a", 0.2, 2), rod("b", 0.2, 2, position=(0.2, 0, 0))],
               constraints=[clamp("a")],
               joints=[{"kind": "weld", "a": {"rod": "a", "node": -1},
                        "b": {"rod": "b", "node": 0}}],
               tendons=[dict(tendon, to_rod="b")])
    whole = dict(common, rods=[rod("a", 0.4, 4)], constraints=[clamp("a")],
                 tendons=[tendon])
    a, b = sj.run(cut), sj.run(whole)
    assert a.converged and b.converged
    joined = np.concatenate([a.positions("a"), a.positions("b")[:, 1:]], axis=1)
    assert np.abs(b.positions("a")[:, -1, 1]).max() > 0.05
    assert np.abs(joined - b.positions("a")).max() < 1e-9


def loop_scene(t_end=0.8):
    """Two vertical rods clamped at the floor, welded at the top to a rigid plate; a
    force pulse on the left rod over [0, 0.1] s, no gravity: free vibration after."""
    L = 0.4
    up = {"axis": [0, 1, 0], "angle_deg": -90.0}
    return {"solver": {"kind": "dynamic", "t_end": t_end, "dt": 0.005, "rho_inf": 1.0},
            "rods": [rod("l", L, 5, rotation=up), rod("r", L, 5, position=(0.2, 0, 0),
                                                      rotation=up)],
            "constraints": [clamp("l"), clamp("r")],
            "bodies": [{"name": "plate", "mass": 0.05, "position": [0.1, 0.0, L],
                        "inertia": np.diag([1e-4, 2e-4, 2e-4]).tolist()}],
            "joints": [{"kind": "weld", "a": {"rod": "l", "node": -1},
                        "b": {"body": "plate", "offset": [-0.1, 0.0, 0.0]}},
                       {"kind": "weld", "a": {"rod": "r", "node": -1},
                        "b": {"body": "plate", "offset": [0.1, 0.0, 0.0]}}],
            "loads": [{"kind": "force", "rod": "l", "node": 2, "vector": [0.5, 1.0, 0.2],
                       "frame": "world", "profile": {"kind": "table", "t": [0.0, 0.05, 0.1],
                                                     "scale": [0.0, 1.0, 0.0]}}]}


@pytest.fixture(scope="module")
def loop_model():
    return build_model(sj.Scene.from_dict(loop_scene()))


@pytest.mark.slow
def test_closed_loop_keeps_its_energy_at_second_order(loop_model):
    """Kinetic (rods and plate) plus strain energy after the pulse: rho_inf = 1 keeps it
    to 2e-3 at dt = 5 ms, and halving dt shrinks the spread at least 3-fold (second
    order: 4)."""
    spreads = []
    energies = jax.jit(jax.vmap(energy, in_axes=(None, 0, 0, 0)))
    for dt in (0.005, 0.0025):
        traj = simulate(loop_model, DynamicSettings(dt=dt, steps=120, rho_inf=1.0))
        assert bool(traj.converged)
        E = np.asarray(energies(loop_model, traj.R, traj.p, traj.v))
        late = np.asarray(traj.time) > 0.1 + 1e-9
        spreads.append((E[late].max() - E[late].min()) / E[late].mean())
    assert spreads[0] < 2e-3
    assert spreads[1] < spreads[0] / 3.0, spreads


@pytest.mark.slow
def test_gradients_through_a_rollout_of_the_loop_match_central_differences(loop_model):
    """d(plate position after 30 steps) / d(plate mass, rod stiffness scale, plate inertia
    I_xx), along a direction that moves all three, by the implicit derivative of each step
    against central differences (1e-5). One compiled program serves both (the primal of
    ``jax.jvp``; forward mode: ``differentiable="forward"``)."""
    settings = DynamicSettings(dt=0.005, steps=30, rho_inf=0.9)
    plate = dict(loop_model.structure.bodies)["plate"]
    k = list(loop_model.structure.mass_nodes).index(plate)

    def moved(params):
        mass, stiff, inertia = params
        model = dataclasses.replace(
            loop_model, mass=loop_model.mass.at[k].set(mass),
            stiffness=loop_model.stiffness * stiff,
            mass_inertia=loop_model.mass_inertia.at[k, 0, 0].set(inertia))
        return simulate(model, settings, differentiable="forward").p[-1, plate]

    x0 = jnp.array([0.05, 1.0, 1e-4])
    direction = x0 * jnp.array([1.0, -0.7, 0.5])      # relative changes of each
    derivative = jax.jit(lambda x, dx: jax.jvp(moved, (x,), (dx,)))
    _, exact = derivative(x0, direction)
    h = 1e-4
    fd = (np.asarray(derivative(x0 + h * direction, direction)[0])
          - np.asarray(derivative(x0 - h * direction, direction)[0])) / (2 * h)
    assert np.linalg.norm(fd) > 1e-4
    assert np.linalg.norm(np.asarray(exact) - fd) < 1e-5 * np.linalg.norm(fd), (exact, fd)
