"""Optional parts of a :class:`~simsoft_jax.model.model.Model` (and of its load channels): a
part the scene lacks is None, not an array of zeros. None is part of the pytree
structure, so it is static under ``jit``: ``model.gravity is not None`` is a trace-time
test, and nothing of an absent term is traced. :func:`refuse_absent` is the one check
that a replaced value does not give an absent part a value.
"""
from __future__ import annotations

# What each optional part is, in the words of the error messages.
WHAT = {
    "nodal_dead": "world-frame nodal loads",
    "nodal_follower": "section-frame (follower) nodal loads",
    "distributed_world": "world-frame distributed forces",
    "distributed_local": "section-frame distributed forces",
    "element_point_dead": "world-frame point loads inside elements",
    "element_point_follower": "section-frame point loads inside elements",
    "gravity": "gravity",
    "viscosity": "viscous terms",
    "mass_damping": "mass damping",
    "obstacle_friction": "friction",
    "obstacle_shift": "moving obstacles",
    "magnetic": "magnetic couples",
    "fluid": "fluid loads",
}


def refuse_absent(current, changes: dict) -> None:
    """Raise a ValueError naming the field when ``changes`` gives a value to a part that
    ``current`` (a Model or LoadChannels) was built without (None there): the solvers
    compiled for it do not read that part, and the part's presence comes from the scene."""
    for key, value in changes.items():
        if value is not None and getattr(current, key, 0) is None:
            what = WHAT.get(key, key)
            raise ValueError(f"{key}: this model was built without {what}, so it has no "
                             f"{key} to replace; build it from a scene that has {what}")
