"""simsoft_jax: differentiable geometrically exact Cosserat rods on SE(3) in JAX.

Importing the package turns on JAX's float64 mode (``jax_enable_x64``): the solvers
need double precision, and every array the package creates is float64.
"""
import jax as _jax

_jax.config.update("jax_enable_x64", True)

from . import lie  # noqa: E402,F401
