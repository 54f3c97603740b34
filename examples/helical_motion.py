"""Helical motion of the synthetic soft arm (the paper's Figs. 4-6).

    python examples/helical_motion.py [--out out/helical_motion] [--fast]

Scene: examples/scenes/helical_synthetic.json. Cantilever, L = 1 m, EA = GA = 1e3 N,
EI = GJ = 1 N m^2, rhoA = 0.1 kg/m, rhoJ = 2 kg m, rhoI = 1 kg m (the paper); a tip force
rising to 2 N and a tip torque rising to 7 N m along S-shaped ramps over 3 s.

Choices where the paper is silent (see tests/test_dynamics_scenes.py):
the S-ramp is the smoothstep 3x^2 - 2x^3 of x = t/3 s; both loads are dead (world frame);
the torque is about world z (coils the arm in the x-y plane) and the force along world z
(lifts the coil into a helix); no gravity; 10 helical elements (4 with --fast, whose
elements bend by < 2 rad), consistent inertia, dt = 0.01 s (the paper's), rho_inf = 0.9.

Writes snapshot_t3.png (Fig. 5: the arm at t = 3 s with section ribbons and frames),
snapshots.png (the motion, coloured by time), tip_displacements.png (Fig. 6),
helical_motion.gif (animation) and summary.json. Printed checks: convergence, the tip at
3 s, the arm length (EA = 1e3 N: stretch < 0.5 %) and the work-energy balance
(work of the tip loads = kinetic + strain energy, up to the small numerical dissipation
of rho_inf = 0.9 and the trapezoid rule).
"""
from _common import helical_example

if __name__ == "__main__":
    raise SystemExit(helical_example("helical_motion", "helical_synthetic", __doc__,
                                     snapshot=True, animation=True))
