"""Displacement-controlled tendons in dynamics (issue 13, item 1): the tendon's length
change follows its time law at every step, and its tension is solved with the step
(the multiplier of the length constraint) and reported at every saved time.

References: the straight tendon at offset r in a clamped straight rod pulls the
stress-free rod into an arc with curvature ``kappa = T r / EI`` and axial strain
``eps = -T / EA``; the tendon's length per unit arc length is ``1 + eps - kappa r``, so
a length change ``delta`` needs the tension ``T = -delta / (L (1/EA + r^2/EI))``, which
a slow pull reaches once its vibration has settled (rod and tendon are in the closed form
of tests/test_tendons.py); and tension control given the solved tension history as its
time law moves the rod the same way (the issue's "displacement control gives the tension
that tension control needs for the same shape", in dynamics)."""
import numpy as np
import pytest

import simsoft_jax as sj
from conftest import tendon_length_changes

EA, GA, GJ, EI = 2e3, 1e3, 0.4, 0.5
STIFFNESS = {"EA": EA, "GAy": GA, "GAz": GA, "GJ": GJ, "EIy": EI, "EIz": EI}
INERTIA = {"rhoA": 0.1, "rhoJ": 1e-4, "rhoIy": 5e-5, "rhoIz": 5e-5}
L, R_OFF, DELTA, RAMP = 0.5, 0.01, -0.002, 1.0


def scene(tendon):
    """A clamped rod (6 elements) with a straight tendon to its tip, 1.4 s at dt 10 ms."""
    return {"solver": {"kind": "dynamic", "dt": 0.01, "t_end": 1.4, "rho_inf": 0.9},
            "rods": [{"name": "arm", "elements": 6,
                      "geometry": {"kind": "straight", "length": L},
                      "stiffness": STIFFNESS, "inertia": INERTIA}],
            "constraints": [{"kind": "clamp", "rod": "arm", "node": 0}],
            "tendons": [dict({"name": "t", "rod": "arm", "offset": [0.0, R_OFF]}, **tendon)]}


@pytest.fixture(scope="module")
def pulled():
    """The tendon shortened by |DELTA| along a smoothstep over RAMP s (about five periods
    of the rod's first bending mode), then held."""
    result = sj.run(scene({"displacement": DELTA,
                           "profile": {"kind": "smoothstep", "t0": 0.0, "t1": RAMP}}))
    assert result.converged
    return result


def test_length_follows_its_law_and_the_tension_settles_at_the_closed_form(pulled):
    t = np.asarray(pulled.time)
    x = np.clip(t / RAMP, 0.0, 1.0)
    target = DELTA * (3 * x**2 - 2 * x**3)
    change = tendon_length_changes(pulled)[:, 0]
    assert np.abs(np.asarray(change) - target).max() < 1e-10 * L
    tension = pulled.tendon_tension("t")
    assert tension.shape == t.shape and not pulled.slack_tendons
    exact = -DELTA / (L * (1.0 / EA + R_OFF**2 / EI))
    held = t >= RAMP + 0.2 - 1e-9          # one period after the pull ends
    assert abs(tension[held].mean() / exact - 1.0) < 1e-3, (tension[held].mean(), exact)
    assert pulled.to_dict()["tendons"]["t"]["tension"] == pytest.approx(tension.tolist())


@pytest.mark.slow
def test_tension_control_with_the_solved_tensions_moves_the_rod_the_same_way(pulled):
    t = np.asarray(pulled.time)
    tension = pulled.tendon_tension("t")
    replay = sj.run(scene({"tension": 1.0,
                           "profile": {"kind": "table", "t": t.tolist(),
                                       "scale": tension.tolist()}}))
    assert replay.converged
    moved = np.abs(pulled.positions("arm") - pulled.positions("arm")[0]).max()
    assert moved > 1e-3
    assert np.abs(replay.positions("arm") - pulled.positions("arm")).max() < 2e-8 * L
