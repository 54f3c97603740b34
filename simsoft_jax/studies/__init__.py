"""Many solves at once: sweeps and sharding, calibration and measurements,
inverse statics and dynamics, least squares, actuation maps and control.

No imports here: importing a module of this layer loads only what that module needs.
"""
