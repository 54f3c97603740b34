"""The residual: one helical element (element), element inertia, obstacle
distances, one module per term (terms/, with its registry) and the assembler.

No imports here: importing a module of this layer loads only what that module needs.
"""
