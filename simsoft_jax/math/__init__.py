"""Pure mathematics: SO(3)/SE(3) kernels (lie), block linear algebra (linalg), the
NumPy reference-frame geometry of rod centrelines (geometry), and the jit and
XLA helpers every layer compiles with (xla).

No imports here: importing a module of this layer loads only what that module needs.
"""
