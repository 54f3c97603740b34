"""The Newton predictor of the generalized-alpha step (dynamics.predicted_increment): it
must return the increment of spec S66 for the acceleration guess it selects, and select
the guess that would have predicted the last accelerations best. The references are the
scheme's formulas written out here (S52, S53, S66)."""
import jax.numpy as jnp
import numpy as np

import simsoft_jax  # noqa: F401  (enables float64)
from simsoft_jax import dynamics as dy

RHO = 0.8
SETTINGS = dy.DynamicSettings(dt=0.01, steps=1, rho_inf=RHO)


def increment_for(state, h, vd_next):
    """S66 increment w for a given vdot_{n+1}: a_{n+1} from S52, then w."""
    am = (2 * RHO - 1) / (RHO + 1)
    af = RHO / (RHO + 1)
    gamma = 0.5 + af - am
    beta = 0.25 * (gamma + 0.5) ** 2
    a_next = ((1 - af) * vd_next + af * state.vd - am * state.a) / (1 - am)
    return h * state.v + h * h * ((0.5 - beta) * state.a + beta * a_next)


def setup(history):
    """A State with vd = history[-1] and a NewtonMemory holding the earlier entries."""
    rng = np.random.default_rng(3)
    n = 4
    shape = (n, 6)
    state = dy.State(jnp.tile(jnp.eye(3), (n, 1, 1)), jnp.zeros((n, 3)),
                     jnp.asarray(rng.normal(size=shape)), jnp.asarray(history[-1]),
                     jnp.asarray(rng.normal(size=shape)), jnp.asarray(0.0))
    vd_hist = np.zeros((2,) + shape)
    h_hist = np.zeros(2)
    for k, past in enumerate(reversed(history[:-1][-2:])):
        vd_hist[k], h_hist[k] = past, 0.01
    memory = dy.NewtonMemory((jnp.zeros((24, 24)), jnp.zeros(24, int)), jnp.asarray(0.01),
                             jnp.asarray(False), jnp.asarray(vd_hist), jnp.asarray(h_hist))
    return state, memory


def test_linear_accelerations_are_extrapolated():
    base, slope = np.full((4, 6), 0.3), np.linspace(-1.0, 1.0, 24).reshape(4, 6)
    history = [base + k * slope for k in range(3)]       # vdot linear in time
    state, memory = setup(history)
    w = dy.predicted_increment(SETTINGS, state, 0.01, memory)
    np.testing.assert_allclose(w, increment_for(state, 0.01, base + 3 * slope), rtol=1e-13)
    # half the step: the extrapolation follows the step ratio
    w = dy.predicted_increment(SETTINGS, state, 0.005, memory)
    np.testing.assert_allclose(w, increment_for(state, 0.005, base + 2.5 * slope),
                               rtol=1e-13)


def test_oscillating_accelerations_take_the_zero_guess():
    c = np.linspace(0.5, 2.0, 24).reshape(4, 6)
    history = [c, -c, c]                                  # period-2 oscillation
    state, memory = setup(history)
    w = dy.predicted_increment(SETTINGS, state, 0.01, memory)
    np.testing.assert_allclose(w, increment_for(state, 0.01, np.zeros((4, 6))), rtol=1e-13)


def test_constant_guess_before_there_is_a_history():
    vd = np.linspace(-2.0, 1.0, 24).reshape(4, 6)
    state, memory = setup([vd])
    w = dy.predicted_increment(SETTINGS, state, 0.01, memory)
    np.testing.assert_allclose(w, increment_for(state, 0.01, vd), rtol=1e-13)
    # one step of history: constant (linear needs two), chosen over zero when it did better
    state, memory = setup([0.9 * vd, vd])
    w = dy.predicted_increment(SETTINGS, state, 0.01, memory)
    np.testing.assert_allclose(w, increment_for(state, 0.01, vd), rtol=1e-13)


def test_remember_step_pushes_only_accepted_steps():
    state, memory = setup([np.ones((4, 6)), 2 * np.ones((4, 6))])
    new = dy.remember_step(memory, 3 * jnp.ones((4, 6)), 0.004, jnp.asarray(True))
    np.testing.assert_allclose(new.vd_history[0], 3.0)
    np.testing.assert_allclose(new.vd_history[1], memory.vd_history[0])
    np.testing.assert_allclose(new.h_history, [0.004, memory.h_history[0]])
    same = dy.remember_step(memory, 3 * jnp.ones((4, 6)), 0.004, jnp.asarray(False))
    np.testing.assert_allclose(same.vd_history, memory.vd_history)
    np.testing.assert_allclose(same.h_history, memory.h_history)
