"""A step too long for the contact time stands where the damped penalty releases a rod it
held deeper than its loads press it (:mod:`simsoft_jax.solvers.dynamics.contact_time`,
(T1)), and is still refused where a stiff impact would throw the rod back (the drops of
tests/test_contact_damping.py and tests/test_dynamics_limits.py).

Reference: a rod lying flat on a critically damped penalty (``[contact] damping_ratio =
1``: spring ``k`` and dashpot ``2 sqrt(k rhoA)`` per unit length) is a critically damped
oscillator about its equilibrium sink ``delta_eq = rhoA g / k + eps / 2``. Released at
rest from a deeper sink it creeps back, ``x(t) = x0 (1 + omega t) exp(-omega t)``, and
never passes the equilibrium (no rebound); at rest the floor carries the rod's weight.
"""
import numpy as np

import simsoft_jax as sj
from simsoft_jax.physics.terms.contact import SMOOTHING

RHO_A, G, R_C, L_ROD = 0.5, 9.81, 0.02, 0.5
T_CONTACT = 0.04                                  # s: pi sqrt(rhoA / k)
K = RHO_A * (np.pi / T_CONTACT) ** 2              # N/m^2
# the end caps (a length r of line penalty at each free end, contact.py) carry part of
# the weight: the penalty's length is L + 2r
DELTA_EQ = RHO_A * G * L_ROD / (K * (L_ROD + 2 * R_C)) + 0.5 * SMOOTHING * R_C   # m
DELTA_0 = DELTA_EQ + 5e-4                         # m: released 0.5 mm deeper
DT = 0.02                                         # s: half the contact time


def released_rod():
    """The rod lying flat, sunk DELTA_0 into a critically damped floor, at rest."""
    return {"solver": {"kind": "dynamic", "t_end": 0.4, "dt": DT},
            "gravity": {"vector": [0.0, 0.0, -G]},
            "rods": [{"name": "rod", "elements": 10,
                      "geometry": {"kind": "straight", "length": L_ROD},
                      "stiffness": {"EA": 1e5, "GAy": 1e5, "GAz": 1e5, "GJ": 1.0,
                                    "EIy": 1.0, "EIz": 1.0},
                      "inertia": {"rhoA": RHO_A, "rhoJ": 1e-4, "rhoIy": 5e-5,
                                  "rhoIz": 5e-5}}],
            "obstacles": [{"name": "floor", "kind": "plane",
                           "point": [0.0, 0.0, DELTA_0 - R_C], "normal": [0.0, 0.0, 1.0]}],
            "contact": {"radius": R_C, "stiffness": K, "damping_ratio": 1.0}}


def test_release_from_a_deep_sink_rises_to_equilibrium_without_rebound():
    """Released 0.5 mm below its equilibrium sink (steps half the contact time: the check
    looks at every step), the rod rises back to equilibrium and rests there with the
    floor carrying its weight. Only the first step, where the implicit step over the
    unresolved release gains energy (T1), is sub-stepped, once: its halves stand (a
    check refusing every station that leaves faster than it came split it in four). Its
    mean height (the end caps' penalty, which carries no mass, bends it slightly) never
    rises above equilibrium (the critically damped oscillator does not overshoot; 2 % of
    the release allowed for the step)."""
    res = sj.run(released_rod())
    assert res.converged
    substeps = np.asarray(res.raw.substeps)
    assert np.all(substeps[1:] == 1) and substeps[0] <= 2
    z = res.positions("rod")[..., 2].mean(axis=1)  # the rod's mean height (it bends a little)
    release = DELTA_0 - DELTA_EQ
    z_eq = release                                 # centreline height at equilibrium
    assert z.max() <= z_eq + 0.02 * release
    assert abs(z[-1] - z_eq) < 0.02 * release
    weight = RHO_A * G * L_ROD
    assert abs(float(res.contacts["floor"]["normal_force"][-1]) - weight) < 0.01 * weight
