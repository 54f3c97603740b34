"""Joint constraints between two nodes (rod nodes or rigid bodies), spec: scene-format
``[[joints]]``.

The joint point is ``p_a + R_a c_a`` seen from node a and ``p_b + R_b c_b`` from node b
(``c`` in each node's frame). A ``ball`` joint keeps the two points together,
``g = p_a + R_a c_a - p_b - R_b c_b`` (3,) (m, world); a ``weld`` also keeps the
relative rotation ``R_rel = R_a^T R_b`` of the start configuration,
``g_rot = vee(Q - Q^T) / 2`` with ``Q = R_rel^T R_a^T R_b`` (3,): ``sin(angle) axis`` of
the rotation error, zero exactly when Q = I within a quarter turn of it, with the
identity as derivative there (the same first-order behaviour as ``log Q``; polynomial,
so its second derivatives, which the Newton matrix needs, are cheap and smooth). With multipliers ``mu`` the joint adds
``d(mu . g)/dx`` to the residual of both nodes (x: the right perturbations
``H exp(x)``) and ``g = 0`` to the equations (:mod:`simsoft_jax.couplings.mechanisms`).
"""
import jax.numpy as jnp

from ...math import lie

SIZES = {"ball": 3, "weld": 6}


def constraint(kind: str, Ra, pa, Rb, pb, offset_a, offset_b, rotation):
    """``g`` (3,) for a ball joint, (6,) ``[gap; rotation]`` for a weld (see the module
    docstring): Ra, Rb (3,3), pa, pb (3,) the node frames, offset_a, offset_b (3,) m,
    rotation (3,3) the kept ``R_a^T R_b``."""
    gap = pa + Ra @ offset_a - pb - Rb @ offset_b
    if kind == "ball":
        return gap
    Q = rotation.T @ Ra.T @ Rb
    return jnp.concatenate([gap, 0.5 * lie.vee_so3(Q - Q.T)])
