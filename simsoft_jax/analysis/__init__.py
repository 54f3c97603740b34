"""Reports on solved states: kinematics, contact forces and the
discretization advisor.

No imports here: importing a module of this layer loads only what that module needs.
"""
