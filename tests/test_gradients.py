"""Gradients of static equilibria (spec: shared/spec/algorithm.md section 5, IFT).

References are independent of the IFT code path: central finite differences of full
re-solves (relative step 1e-5, solver tolerance 1e-13), and the
derivative of a Newton iteration unrolled here (30 fixed iterations with a dense tangent,
differentiated through by forward mode).

Model: a 1 m cantilever, 4 elements, K = diag(EA, GAy, GAz, GJ, EIy, EIz) =
(1e4, 5e3, 5e3, 0.8, 2, 1), rhoA = 0.2, gravity 9.81 along -z and a general 3-D dead tip
force (~ 1.8 N; tip rotations of order 1 rad), so bending about both axes, torsion, the
load and gravity all matter. Every function of a parameter vector
``theta = (scale of GJ, scale of EIy, scale of EIz, load scale, g)`` uses one compiled
structure; compilation dominates the run time, so the tests share as much as they can.
"""
import numpy as np
import pytest

import simsoft_jax as sj  # enables float64
import jax
import jax.numpy as jnp
from simsoft_jax.physics import assembly
from simsoft_jax.math import lie, linalg

K0 = {"EA": 1e4, "GAy": 5e3, "GAz": 5e3, "GJ": 0.8, "EIy": 2.0, "EIz": 1.0}
F0 = [0.3, 1.0, -1.5]
G0 = 9.81
TIGHT = sj.StaticSettings(tolerance=1e-13)
FD_REL = 1e-5
NAMES = ("GJ", "EIy", "EIz", "load", "gravity")
COLUMNS = {"GJ": 3, "EIy": 4, "EIz": 5}
THETA0 = np.array([1.0, 1.0, 1.0, 1.0, G0])


def cantilever(elements):
    d = {"name": "grad_cantilever", "solver": {"kind": "static", "tolerance": 1e-13},
         "gravity": {"vector": [0.0, 0.0, -G0]},
         "rods": [{"name": "rod", "stiffness": K0,
                   "inertia": {"rhoA": 0.2, "rhoJ": 1e-3, "rhoIy": 1e-3, "rhoIz": 1e-3},
                   "elements": elements, "geometry": {"kind": "straight", "length": 1.0}}],
         "constraints": [{"kind": "clamp", "rod": "rod", "node": 0}],
         "loads": [{"kind": "force", "rod": "rod", "node": -1, "vector": F0,
                    "frame": "world"}]}
    return sj.build_model(sj.Scene.from_dict(d))


def apply(m, theta):
    """The model with GJ, EIy, EIz scaled by theta[0:3] (uniformly over the elements),
    the tip force scaled by theta[3] and gravity of magnitude theta[4] along -z."""
    scale = jnp.concatenate([jnp.ones(3), theta[:3]])
    return m.replace(stiffness=m.stiffness * scale, nodal_dead=theta[3] * m.nodal_dead,
                     gravity=theta[4] * jnp.array([0.0, 0.0, -1.0]))


def tip(m):
    return sj.solve_static(m, TIGHT).p[-1]


def rel_err(a, b):
    a, b = np.asarray(a), np.asarray(b)
    return np.max(np.abs(a - b)) / np.max(np.abs(b))


@pytest.fixture(scope="module")
def model():
    return cantilever(4)


@pytest.fixture(scope="module")
def fd_jacobian(model):
    """d tip / d theta by central differences of full re-solves (same compiled solver)."""
    J = np.zeros((3, len(THETA0)))
    for k in range(len(THETA0)):
        h = FD_REL * THETA0[k]
        out = []
        for sign in (1.0, -1.0):
            theta = THETA0.copy()
            theta[k] += sign * h
            eq = sj.solve_static(apply(model, jnp.asarray(theta)), TIGHT)
            assert bool(eq.converged)
            out.append(np.asarray(eq.p[-1]))
        J[:, k] = (out[0] - out[1]) / (2 * h)
    return J


@pytest.fixture(scope="module")
def vmapped_grads(model):
    """One reverse-mode program, vmapped over two load scales (0.6 and 1.0): the gradient
    of tip_y w.r.t. the entries of model.stiffness (E, 6), the load scale and g."""
    dead = model.nodal_dead
    down = jnp.array([0.0, 0.0, -1.0])

    def tip_y(K, s, g):
        return tip(model.replace(stiffness=K, nodal_dead=s * dead, gravity=g * down))[1]

    grad = jax.vmap(jax.grad(tip_y, argnums=(0, 1, 2)), in_axes=(None, 0, None))
    gK, gs, gg = grad(model.stiffness, jnp.array([0.6, 1.0]), jnp.asarray(G0))
    return {"K": np.asarray(gK), "load": np.asarray(gs), "gravity": np.asarray(gg)}


@pytest.fixture(scope="module")
def jacfwd_theta(model):
    """Forward mode: the full Jacobian (3 x 5) of the tip w.r.t. theta."""
    return np.asarray(jax.jacfwd(lambda th: tip(apply(model, th)))(jnp.asarray(THETA0)))


def test_equilibrium_is_large_deflection(model):
    eq = sj.solve_static(model, TIGHT)
    assert bool(eq.converged)
    u = np.asarray(eq.p[-1]) - [1.0, 0.0, 0.0]
    assert np.all(np.abs(u) > 0.05), u            # all three components well away from 0


def test_fd_jacobian_is_nondegenerate(fd_jacobian):
    """Every parameter moves the tip: relative sensitivities theta_k |d tip / d theta_k|
    are at least 1e-3 m."""
    sens = np.abs(fd_jacobian * THETA0).max(axis=0)
    assert np.all(sens > 1e-3), dict(zip(NAMES, sens))


@pytest.mark.parametrize("name", ["GJ", "EIy", "EIz"])
def test_stiffness_entry_gradient_matches_fd(vmapped_grads, fd_jacobian, name):
    """jax.grad w.r.t. the entries of model.stiffness, summed over the elements (the
    derivative w.r.t. a uniform GJ, EIy or EIz), against central differences."""
    ift = vmapped_grads["K"][1][:, COLUMNS[name]].sum()   # load scale 1.0
    fd = fd_jacobian[1, NAMES.index(name)] / K0[name]      # theta scales the value
    assert abs(ift - fd) <= 1e-6 * abs(fd), (name, ift, fd, abs(ift - fd) / abs(fd))


@pytest.mark.parametrize("name", ["load", "gravity"])
def test_load_and_gravity_magnitude_gradient_matches_fd(vmapped_grads, fd_jacobian, name):
    ift = vmapped_grads[name][1]
    fd = fd_jacobian[1, NAMES.index(name)]
    assert abs(ift - fd) <= 1e-6 * abs(fd), (name, ift, fd)


def test_jacfwd_matches_fd_and_grad(vmapped_grads, fd_jacobian, jacfwd_theta):
    """Forward mode over all five parameters vs finite differences (all three tip
    components), and vs the reverse pass (chain rule: scale derivative = sum_e g_e K0)."""
    assert rel_err(jacfwd_theta, fd_jacobian) < 1e-6
    rev = [vmapped_grads["K"][1][:, COLUMNS[n]].sum() * K0[n] for n in ("GJ", "EIy", "EIz")]
    rev += [vmapped_grads["load"][1], vmapped_grads["gravity"][1]]
    np.testing.assert_allclose(rev, jacfwd_theta[1], rtol=1e-10)


def test_vmap_of_grad_over_load_values(model, vmapped_grads):
    """The load-0.6 lane of the vmapped gradient against its own central difference."""
    dead = model.nodal_dead
    vals = []
    for sign in (1.0, -1.0):
        s = 0.6 * (1.0 + sign * FD_REL)
        vals.append(float(tip(model.replace(nodal_dead=s * dead))[1]))
    fd = (vals[0] - vals[1]) / (2 * 0.6 * FD_REL)
    g = vmapped_grads["load"]
    assert abs(g[0] - fd) <= 1e-6 * abs(fd), (g[0], fd)
    assert abs(g[0] - g[1]) > 1e-2 * abs(g[1])            # nonlinear: the two differ
    # the stiffness gradients differ between the lanes as well
    assert rel_err(vmapped_grads["K"][0], vmapped_grads["K"][1]) > 1e-2


# ----------------------------------------------------- unrolled Newton on a tiny model
def unrolled_tip(m, iterations=30, levels=5):
    """Plain Newton written here: dense tangent from the package's assembly, full steps,
    ``levels`` equal load increments, ``iterations`` steps in all (a fixed-length scan
    that JAX differentiates through). Returns the tip and the last residual norm."""
    per_level = iterations // levels
    lams = jnp.minimum(1.0, (jnp.arange(iterations) // per_level + 1) / levels)

    def step(state, lam):
        R, p = state
        r, blocks = assembly.residual_and_tangent(m, R, p, lam)
        dx = -jnp.linalg.solve(linalg.dense(blocks), r.reshape(-1)).reshape(-1, 6)
        R, p = jax.vmap(lie.compose_exp)(R, p, dx)
        return (R, p), jnp.linalg.norm(r)

    (R, p), norms = jax.lax.scan(step, (m.R0, m.p0), lams)
    return p[-1], norms[-1]


def test_ift_matches_unrolled_newton_derivative(model, jacfwd_theta):
    """The Jacobian (3 x 5) of the tip w.r.t. theta by the IFT equals the derivative of
    the unrolled Newton iteration. (The 4-element model of the other tests, not a 1-2
    element one: the dense 30 x 30 tangent is still tiny, and the IFT Jacobian is then the
    one already compiled; compilation dominates the run time.)"""
    theta = jnp.asarray(THETA0)

    def unrolled(th):
        p, last = unrolled_tip(apply(model, th))
        return p, (p, last)

    # forward mode through the 30 unrolled iterations: reverse mode (jax.grad) gives the
    # same numbers but its compilation takes ~55 s here (second derivatives of the
    # element kernels inside a transposed scan), forward mode ~15 s
    J_unrolled, (p_unrolled, last) = jax.jit(jax.jacfwd(unrolled, has_aux=True))(theta)
    assert float(last) < 1e-9                       # the unrolled iteration converged
    np.testing.assert_allclose(p_unrolled, tip(model), atol=1e-11)
    J_unrolled = np.asarray(J_unrolled)
    assert np.all(np.isfinite(J_unrolled))
    assert rel_err(jacfwd_theta, J_unrolled) < 1e-8, (jacfwd_theta, J_unrolled)
