"""Helical motion of a spring-steel rod (the paper's Fig. 7).

    python examples/spring_steel_rod.py [--out out/spring_steel_rod] [--fast]

Scene: examples/scenes/helical_spring_steel.json. Cantilever, circular d = 2 mm,
L = 0.5 m, spring steel (rho 7850 kg/m^3, E 210 GPa, nu 0.3, G = E/2(1 + nu)); tip force
f(t) = 0.14 t N and tip torque tau(t) = 0.49 t N m for 0 <= t <= 3 s (the paper).

Choices where the paper is silent (see tests/test_dynamics_scenes.py):
both loads dead (world frame), the torque about world z (coils the rod in the x-y plane),
the force along world z; no gravity; Cowper shear coefficient 0.886; 10 helical
elements (4 with --fast), consistent inertia, dt = 0.01 s, rho_inf = 0.9 (damps the axial
modes, whose frequency is 1000 / dt). At t = 3 s, tau L / EI = 4.46 rad.

The first bending period (0.17 s) is short against the 3 s of loading, so the rod
follows its quasi-static path: the test suite compares the tip at 3 s with a continuum
Cosserat-rod shooting solution under the t = 3 s loads.

Writes tip_displacements.png (Fig. 7), snapshots.png and summary.json (converged, tip at
3 s, arm length change, work-energy balance).
"""
from _common import helical_example

if __name__ == "__main__":
    raise SystemExit(helical_example("spring_steel_rod", "helical_spring_steel", __doc__))
