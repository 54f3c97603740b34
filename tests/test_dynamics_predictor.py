"""The Newton predictor of the generalized-alpha step (dynamics.memory.predicted_increment):
it must return the increment of spec S66 for the acceleration guess it selects, and
select the guess that would have predicted the last accelerations best. The references
are the scheme's formulas written out here (S52, S53, S66)."""
import jax.numpy as jnp
import numpy as np

from simsoft_jax.solvers.dynamics import memory as nm  # importing the package enables float64

RHO = 0.8
ALPHA_M = (2 * RHO - 1) / (RHO + 1)
ALPHA_F = RHO / (RHO + 1)
GAMMA = 0.5 + ALPHA_F - ALPHA_M
BETA = 0.25 * (GAMMA + 0.5) ** 2
SHAPE = (4, 6)
RNG = np.random.default_rng(3)
V, A = RNG.normal(size=SHAPE), RNG.normal(size=SHAPE)


def increment_for(vd, h, vd_next):
    """S66 increment w for a given vdot_{n+1}: a_{n+1} from S52, then w."""
    a_next = ((1 - ALPHA_F) * vd_next + ALPHA_F * vd - ALPHA_M * A) / (1 - ALPHA_M)
    return h * V + h * h * ((0.5 - BETA) * A + BETA * a_next)


def memory_with(history):
    """A NewtonMemory holding the accelerations of the steps before the last entry."""
    vd_hist, h_hist = np.zeros((2,) + SHAPE), np.zeros(2)
    for k, past in enumerate(reversed(history[:-1][-2:])):
        vd_hist[k], h_hist[k] = past, 0.01
    empty = nm.empty_newton_memory(SHAPE[0])
    return empty._replace(vd_history=jnp.asarray(vd_hist), h_history=jnp.asarray(h_hist))


def predict(history, h):
    return nm.predicted_increment(jnp.asarray(V), jnp.asarray(history[-1]), jnp.asarray(A), h,
                                  memory_with(history), ALPHA_M, ALPHA_F, BETA)


def test_linear_accelerations_are_extrapolated():
    base, slope = np.full(SHAPE, 0.3), np.linspace(-1.0, 1.0, 24).reshape(SHAPE)
    history = [base + k * slope for k in range(3)]       # vdot linear in time
    np.testing.assert_allclose(predict(history, 0.01),
                               increment_for(history[-1], 0.01, base + 3 * slope), rtol=1e-13)
    # half the step: the extrapolation follows the step ratio
    np.testing.assert_allclose(predict(history, 0.005),
                               increment_for(history[-1], 0.005, base + 2.5 * slope),
                               rtol=1e-13)


def test_oscillating_accelerations_take_the_zero_guess():
    c = np.linspace(0.5, 2.0, 24).reshape(SHAPE)
    history = [c, -c, c]                                  # period-2 oscillation
    np.testing.assert_allclose(predict(history, 0.01),
                               increment_for(c, 0.01, np.zeros(SHAPE)), rtol=1e-13)


def test_constant_guess_before_there_is_a_history():
    vd = np.linspace(-2.0, 1.0, 24).reshape(SHAPE)
    np.testing.assert_allclose(predict([vd], 0.01), increment_for(vd, 0.01, vd), rtol=1e-13)
    # one step of history: constant (linear needs two), chosen over zero when it did better
    np.testing.assert_allclose(predict([0.9 * vd, vd], 0.01), increment_for(vd, 0.01, vd),
                               rtol=1e-13)


def test_remember_step_pushes_only_accepted_steps():
    memory = memory_with([np.ones(SHAPE), 2 * np.ones(SHAPE)])
    new = nm.remember_step(memory, 3 * jnp.ones(SHAPE), 0.004, jnp.asarray(True))
    np.testing.assert_allclose(new.vd_history[0], 3.0)
    np.testing.assert_allclose(new.vd_history[1], memory.vd_history[0])
    np.testing.assert_allclose(new.h_history, [0.004, memory.h_history[0]])
    same = nm.remember_step(memory, 3 * jnp.ones(SHAPE), 0.004, jnp.asarray(False))
    np.testing.assert_allclose(same.vd_history, memory.vd_history)
    np.testing.assert_allclose(same.h_history, memory.h_history)
