"""Scene files and their checks, plain Python + NumPy (never JAX): the validated
specs, key checks, one module per scene section, materials and sections,
supports and start frames, and the cross checks. Every input error is raised here.

No imports here: importing a module of this layer loads only what that module needs.
"""
