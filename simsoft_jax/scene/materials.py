"""Isotropic linear-elastic materials for Cosserat rods (SI units throughout).

A :class:`Material` carries Young's modulus ``E`` (Pa), shear modulus ``G`` (Pa), Poisson's ratio
``nu`` (-), mass density (kg/m^3) and the shear viscosity ``mu`` (Pa s) of the Kelvin-Voigt law
(spec (S28)). For an isotropic material ``G = E / (2 (1 + nu))`` (the paper, Grazioso et al. 2019,
text after eq. (9)); exactly one of ``G`` and ``nu`` is given and the other is derived.

The built-in library holds the paper's three materials (spec §7.1-7.3, ``scene-format.md``):

* ``aluminum_7075``: E 71.7 GPa, G 27.37 GPa, rho 2679 kg/m^3 (Princeton beam, paper eqs. (109)-(110));
* ``spring_steel``: E 210 GPa, nu 0.3, rho 7850 kg/m^3 (helical scene, Magellan catheter);
* ``silicone``: E 110 kPa, nu 0.5, rho 1080 kg/m^3 (soft body, rehabilitation actuator).

Every invalid argument raises ``ValueError`` whose message starts with the argument's name.
"""

from __future__ import annotations

import copy
import math
import numbers
from dataclasses import dataclass
from typing import Callable

# Round-off allowed when a derived Poisson ratio lands just above the incompressible limit 0.5
# (e.g. G = E / 3 given for silicone).
_NU_ROUNDING = 1e-12


def check_number(name: str, value, requirement: str = "> 0",
                 test: Callable[[float], bool] = lambda x: x > 0) -> float:
    """Return ``float(value)`` if it is a finite real number passing ``test``.

    Otherwise raise ``ValueError("<name>: must be a finite number <requirement>, got <value>")``.
    Booleans and strings are rejected even though Python could convert them.
    """
    if isinstance(value, numbers.Real) and not isinstance(value, bool):
        x = float(value)
        if math.isfinite(x) and test(x):
            return x
    raise ValueError(f"{name}: must be a finite number {requirement}, got {value!r}")


def _valid_nu(x: float) -> bool:
    return -1.0 < x <= 0.5


@dataclass(frozen=True)
class Material:
    """Isotropic material; after construction both ``G`` and ``nu`` are floats.

    Attributes:
        E: Young's modulus, Pa, > 0.
        density: mass density rho, kg/m^3, > 0.
        G: shear modulus, Pa, > 0 (give exactly one of ``G`` and ``nu``).
        nu: Poisson's ratio, dimensionless, in (-1, 0.5].
        viscosity: shear viscosity mu, Pa s, >= 0; enters the Kelvin-Voigt damping matrix
            ``Upsilon = mu diag(3A, A, A, J_t, 3 I_y, 3 I_z)`` (spec (S28), paper eq. (9) corrected).
        mass_damping: mass-proportional (Rayleigh) damping constant c, 1/s, >= 0: a force
            ``-c M v`` against the nodal velocities, weighted by the element mass matrix
            (:mod:`simsoft_jax.physics.terms.mass_damping`); each vibration mode decays as
            ``exp(-c t / 2)``.
        name: label used in error messages and scene files.
    """

    E: float
    density: float
    G: float | None = None
    nu: float | None = None
    viscosity: float = 0.0
    name: str = "custom"
    mass_damping: float = 0.0

    def __post_init__(self) -> None:
        E = check_number("E", self.E)
        density = check_number("density", self.density)
        viscosity = check_number("viscosity", self.viscosity, ">= 0", lambda x: x >= 0)
        mass_damping = check_number("mass_damping", self.mass_damping, ">= 0",
                                    lambda x: x >= 0)
        if not isinstance(self.name, str) or not self.name:
            raise ValueError(f"name: must be a non-empty string, got {self.name!r}")
        if (self.G is None) == (self.nu is None):
            given = "both" if self.G is not None else "neither"
            raise ValueError(f"G, nu: give exactly one of G and nu ({given} given)")
        if self.nu is not None:
            # G = E / (2 (1 + nu)), the paper's text after eq. (9).
            nu = check_number("nu", self.nu, "in (-1, 0.5]", _valid_nu)
            G = E / (2.0 * (1.0 + nu))
        else:
            G = check_number("G", self.G)
            nu = E / (2.0 * G) - 1.0
            if 0.5 < nu <= 0.5 + _NU_ROUNDING:
                nu = 0.5
            if not _valid_nu(nu):
                raise ValueError(
                    f"G: implies nu = E/(2G) - 1 = {nu:.6g}, outside (-1, 0.5] (E = {E:.6g}, G = {G:.6g})")
        for field_name, value in (("E", E), ("density", density), ("G", G), ("nu", nu),
                                  ("viscosity", viscosity), ("mass_damping", mass_damping)):
            object.__setattr__(self, field_name, value)

    def with_viscosity(self, mu: float) -> Material:
        """Return a copy with shear viscosity ``mu`` (Pa s, >= 0); E, G, nu, density unchanged."""
        mu = check_number("mu", mu, ">= 0", lambda x: x >= 0)
        new = copy.copy(self)
        object.__setattr__(new, "viscosity", mu)
        return new


BUILTIN_MATERIALS: dict[str, Material] = {
    "aluminum_7075": Material(E=71.7e9, G=27.37e9, density=2679.0, name="aluminum_7075"),
    "spring_steel": Material(E=210e9, nu=0.3, density=7850.0, name="spring_steel"),
    "silicone": Material(E=110e3, nu=0.5, density=1080.0, name="silicone"),
}


def get_material(name: str) -> Material:
    """Return the built-in material called ``name`` (see :data:`BUILTIN_MATERIALS`)."""
    try:
        return BUILTIN_MATERIALS[name]
    except (KeyError, TypeError):
        known = ", ".join(sorted(BUILTIN_MATERIALS))
        raise ValueError(f"name: unknown material {name!r}; known: {known}") from None
