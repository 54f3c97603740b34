"""Mass-proportional (Rayleigh-type) damping: a force against the nodal velocities weighted
by the element mass matrix.

With the element mass matrix ``M_e`` (12,12) of :mod:`simsoft_jax.physics.inertia` (the one whose
quadratic form ``1/2 v_e^T M_e v_e`` is the element's kinetic energy) and the damping
constant ``c`` (1/s), the residual gains ``c M_e v_e``: the discrete equations become
``M vdot + c M v + f_int(q) = f_ext``. Linearised about an equilibrium, every vibration
mode ``q_k'' + c q_k' + omega_k^2 q_k = 0`` then decays as ``exp(-c t / 2)`` whatever its
frequency (the mass-proportional half of Rayleigh damping; Kelvin-Voigt viscosity,
:mod:`.viscous`, is the stiffness-like half, damping fast modes more). It also resists
rigid motion, like a surrounding medium: the power it dissipates is ``c v^T M v``, twice
``c`` times the kinetic energy.
"""


def force(el, data):
    """``c M_e v_e`` (12,): ``data.mass_damping`` c (1/s) times the element mass matrix
    ``data.mass`` (12,12, kg and kg m^2) times the nodal body velocities ``el.ve`` (12,)."""
    return data.mass_damping * (data.mass @ el.ve)
