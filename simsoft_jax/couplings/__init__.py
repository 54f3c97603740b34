"""What couples nodes beyond the rod chains, behind one door for the solvers
(coupling): rods, bodies and joints (mechanisms), rod-rod contact
(broad_phase, rod_pairs), and driven or sliding nodes (drives).

No imports here: importing a module of this layer loads only what that module needs.
"""
