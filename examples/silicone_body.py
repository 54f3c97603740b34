"""Helical motion of a silicone body (the paper's Fig. 8).

    python examples/silicone_body.py [--out out/silicone_body] [--fast]

Scene: examples/scenes/helical_silicone.json. Cantilever, circular d = 5 cm, L = 0.5 m,
silicone (rho 1080 kg/m^3, E 110 kPa, nu 0.5, G = E/3); tip force f(t) = 0.1035 t N and
tip torque tau(t) = 0.01225 t N m for 0 <= t <= 3 s (the paper).

Choices where the paper is silent (see tests/test_dynamics_scenes.py):
**no gravity** (the body weighs 10.4 N, a hundred times the tip loads: with gravity it
would just hang); both loads dead (world frame), the torque about world z, the force
along world z; no material damping; Cowper shear coefficient 0.9; 10 helical elements
(4 with --fast), consistent inertia, dt = 0.01 s, rho_inf = 0.9.

Unlike the steel rod, this heavy and soft body has a first bending period of about 3.5 s,
as long as the loading: its motion is truly dynamic (it lags behind the loads).

Writes tip_displacements.png (Fig. 8), snapshots.png and summary.json (converged, tip at
3 s, arm length change, work-energy balance).
"""
from _common import helical_example

if __name__ == "__main__":
    raise SystemExit(helical_example("silicone_body", "helical_silicone", __doc__))
