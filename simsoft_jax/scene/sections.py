"""Cross-section properties and the sectional stiffness / inertia / viscosity diagonals (SI units),
and full 6x6 sections with couplings (stiffness) or an offset centre of mass (inertia).

Conventions (spec §0, ``scene-format.md``): local x is the rod axis, local y and z are the
principal axes of the section and the rod's reference line is the section's centroid.
``Iy = ∫ z² dA`` is the second moment about local y (it resists bending about y, the tip then moves
along z), ``Iz = ∫ y² dA``. Diagonals are ordered like the strains ``[γ; κ]``:

* stiffness ``K = diag(EA, G k_y A, G k_z A, G J_t, E I_y, E I_z)``        (spec (S28), the paper's eq. (9));
* inertia   ``M = rho diag(A, A, A, I_y + I_z, I_y, I_z)``                  (spec (S29), the paper's eq. (19));
* viscosity ``Upsilon = mu diag(3A, A, A, J_t, 3 I_y, 3 I_z)``              (spec (S28), §9 item 6).

``J_t`` is the Saint-Venant torsion constant (torsional stiffness ``G J_t``); the rotary inertia
about the axis uses the polar moment ``J_p = I_y + I_z``. They coincide only for circles and tubes.

Note on the Princeton beam (spec §7.1 and §9 item 14): the paper prints ``rho J = 3.034e-6 kg m``
(eq. (109)), but ``rho J_t = 3.04e-7`` and ``rho (I_y + I_z) = 1.446e-6 kg m``; neither matches.
We use the polar value. Rotary inertia about the axis plays no role in statics, so the paper's
Princeton results are unaffected.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .materials import Material, check_number

def _circle_shear(nu: float) -> float:
    """Cowper (1966) shear coefficient of a solid circle: ``k = 6 (1 + nu) / (7 + 6 nu)``."""
    return 6.0 * (1.0 + nu) / (7.0 + 6.0 * nu)


@dataclass(frozen=True)
class Section:
    """Geometric properties of a cross-section (normally built by the shape functions below).

    Attributes:
        shape: ``"circle"``, ``"tube"``, ``"rectangle"`` or ``"semicircle"``.
        area: A, m².
        Iy: centroidal principal second moment ``∫ z² dA``, m⁴.
        Iz: centroidal principal second moment ``∫ y² dA``, m⁴.
        torsion_constant: Saint-Venant torsion constant J_t, m⁴ (stiffness G J_t).
        centroid_offset: distance of the centroid from the shape's geometric reference, m
            (semicircle: from the flat side along +z; 0 for doubly symmetric shapes).
        dimensions: the constructor arguments, m.
    """

    shape: str
    area: float
    Iy: float
    Iz: float
    torsion_constant: float
    centroid_offset: float
    dimensions: dict = field(hash=False)

    @property
    def polar(self) -> float:
        """Polar second moment ``J_p = I_y + I_z`` about the centroid, m⁴ (rotary inertia, (S29))."""
        return self.Iy + self.Iz

    def default_shear_coefficients(self, nu: float) -> tuple[float, float]:
        """Timoshenko shear coefficients ``(k_y, k_z)`` (dimensionless) for Poisson ratio ``nu``.

        From G. R. Cowper, "The shear coefficient in Timoshenko's beam theory",
        J. Appl. Mech. 33:335-340 (1966), Table 1:

        * circle: ``6 (1 + nu) / (7 + 6 nu)`` (0.886 for nu = 0.3, 0.9 for nu = 0.5);
        * tube, ``m = d_i / d_o``: ``6 (1 + nu)(1 + m²)² / ((7 + 6 nu)(1 + m²)² + (20 + 12 nu) m²)``;
        * rectangle: ``10 (1 + nu) / (12 + 11 nu)`` in both directions;
        * semicircle: the solid-circle value, an approximation (Cowper gives no semicircle entry).
        """
        nu = check_number("nu", nu, "in (-1, 0.5]", lambda x: -1.0 < x <= 0.5)
        if self.shape == "tube":
            m2 = (self.dimensions["inner_diameter"] / self.dimensions["outer_diameter"]) ** 2
            k = 6.0 * (1.0 + nu) * (1.0 + m2) ** 2 / (
                (7.0 + 6.0 * nu) * (1.0 + m2) ** 2 + (20.0 + 12.0 * nu) * m2)
        elif self.shape == "rectangle":
            k = 10.0 * (1.0 + nu) / (12.0 + 11.0 * nu)
        else:
            k = _circle_shear(nu)
        return (k, k)


def circle(diameter: float) -> Section:
    """Solid circle of diameter d (m): ``A = π d²/4``, ``I_y = I_z = π d⁴/64``, ``J_t = π d⁴/32``."""
    d = check_number("diameter", diameter)
    return Section("circle", math.pi * d**2 / 4.0, math.pi * d**4 / 64.0, math.pi * d**4 / 64.0,
                   math.pi * d**4 / 32.0, 0.0, {"diameter": d})


def tube(outer_diameter: float, inner_diameter: float) -> Section:
    """Circular tube (annulus), diameters in m; ``inner_diameter = 0`` gives the solid circle.

    ``A = π (D² − d²)/4``, ``I_y = I_z = π (D⁴ − d⁴)/64``, ``J_t = π (D⁴ − d⁴)/32`` (exact).
    """
    D = check_number("outer_diameter", outer_diameter)
    d = check_number("inner_diameter", inner_diameter, f"in [0, outer_diameter = {D:g})",
                     lambda x: 0.0 <= x < D)
    second = math.pi * (D**4 - d**4) / 64.0
    return Section("tube", math.pi * (D**2 - d**2) / 4.0, second, second, 2.0 * second, 0.0,
                   {"outer_diameter": D, "inner_diameter": d})


def rectangle(width: float, height: float) -> Section:
    """Solid rectangle, ``width`` w along local y and ``height`` h along local z (m).

    ``A = w h``, ``I_y = w h³/12``, ``I_z = h w³/12``. Torsion constant (approximation used by the
    the paper, text after eq. (109), citing Roark's Formulas for Stress and Strain), with
    ``a = max(w, h)``, ``b = min(w, h)``: ``J_t = a b³ [1/3 − 0.21 (b/a)(1 − b⁴/(12 a⁴))]``;
    within 0.2 % of Saint-Venant's series solution for every aspect ratio.
    """
    w = check_number("width", width)
    h = check_number("height", height)
    a, b = max(w, h), min(w, h)
    jt = a * b**3 * (1.0 / 3.0 - 0.21 * (b / a) * (1.0 - b**4 / (12.0 * a**4)))
    return Section("rectangle", w * h, w * h**3 / 12.0, h * w**3 / 12.0, jt, 0.0,
                   {"width": w, "height": h})


def semicircle(radius: float) -> Section:
    """Solid half disc of radius r (m), diameter along local y, flat side normal to local z.

    ``A = π r²/2``; centroid ``4 r/(3π)`` from the flat side (``centroid_offset``, along +z);
    ``I_y = (π/8 − 8/(9π)) r⁴`` about the centroidal axis parallel to the diameter;
    ``I_z = π r⁴/8`` about the symmetry axis (spec §7.3).
    ``J_t ≈ (π/2 − 4/π) r⁴ ≈ 0.2976 r⁴`` is an approximation (spec §7.3); a Richardson-extrapolated
    finite-difference solution of Prandtl's stress-function problem gives 0.2976 r⁴ as well
    (checked to 0.2 % in the tests).
    """
    r = check_number("radius", radius)
    return Section("semicircle", math.pi * r**2 / 2.0, (math.pi / 8.0 - 8.0 / (9.0 * math.pi)) * r**4,
                   math.pi * r**4 / 8.0, (math.pi / 2.0 - 4.0 / math.pi) * r**4,
                   4.0 * r / (3.0 * math.pi), {"radius": r})


def stiffness_diagonal(section: Section, material: Material,
                       shear_coefficients: tuple[float, float] | None = None) -> np.ndarray:
    """Sectional stiffness diagonal ``[EA, G k_y A, G k_z A, G J_t, E I_y, E I_z]``.

    Units ``[N, N, N, N m², N m², N m²]`` (spec (S28), the paper's eq. (9)). ``shear_coefficients =
    (k_y, k_z)`` overrides :meth:`Section.default_shear_coefficients` (e.g. the paper's
    (0.590, 0.833) for the Princeton beam, eq. (110)).
    """
    if shear_coefficients is None:
        ky, kz = section.default_shear_coefficients(material.nu)
    else:
        if isinstance(shear_coefficients, (str, bytes)) or len(shear_coefficients) != 2:
            raise ValueError(f"shear_coefficients: must be a pair (ky, kz), got {shear_coefficients!r}")
        ky = check_number("shear_coefficients[0]", shear_coefficients[0])
        kz = check_number("shear_coefficients[1]", shear_coefficients[1])
    E, G, A = material.E, material.G, section.area
    return np.array([E * A, G * ky * A, G * kz * A, G * section.torsion_constant,
                     E * section.Iy, E * section.Iz])


def inertia_diagonal(section: Section, material: Material) -> np.ndarray:
    """Sectional inertia diagonal ``rho [A, A, A, I_y + I_z, I_y, I_z]``.

    Units ``[kg/m, kg/m, kg/m, kg m, kg m, kg m]`` (spec (S29), the paper's eq. (19)); the rotary inertia
    about the axis uses the polar moment, not the torsion constant (see the module note).
    """
    rho, A = material.density, section.area
    return rho * np.array([A, A, A, section.polar, section.Iy, section.Iz])


def viscosity_diagonal(section: Section, material: Material) -> np.ndarray:
    """Kelvin-Voigt damping diagonal ``mu [3A, A, A, J_t, 3 I_y, 3 I_z]``.

    Units ``[N s, N s, N s, N m² s, N m² s, N m² s]`` (spec (S28); the paper's eq. (9) corrected per spec
    §9 item 6: an incompressible material has extensional viscosity 3 mu).
    """
    mu, A = material.viscosity, section.area
    return mu * np.array([3.0 * A, A, A, section.torsion_constant, 3.0 * section.Iy, 3.0 * section.Iz])


def custom_stiffness(EA: float, GAy: float, GAz: float, GJ: float, EIy: float, EIz: float) -> np.ndarray:
    """Validated stiffness diagonal ``[EA, GAy, GAz, GJ, EIy, EIz]`` given directly (N, N m²); each > 0."""
    values = {"EA": EA, "GAy": GAy, "GAz": GAz, "GJ": GJ, "EIy": EIy, "EIz": EIz}
    return np.array([check_number(key, value) for key, value in values.items()])


def custom_inertia(rhoA: float, rhoJ: float, rhoIy: float, rhoIz: float) -> np.ndarray:
    """Validated inertia diagonal ``[rhoA, rhoA, rhoA, rhoJ, rhoIy, rhoIz]`` (kg/m, kg m).

    ``rhoA > 0``; the rotary terms may be 0 (no rotary inertia).
    """
    rho_a = check_number("rhoA", rhoA)
    rotary = [check_number(key, value, ">= 0", lambda x: x >= 0)
              for key, value in (("rhoJ", rhoJ), ("rhoIy", rhoIy), ("rhoIz", rhoIz))]
    return np.array([rho_a, rho_a, rho_a, *rotary])


def inertia_matrix(matrix, rtol: float = 1e-9) -> np.ndarray:
    """Validated full section inertia (6,6) per unit length with an offset centre of mass.

    Rows and columns follow the section velocity ``[v; w]`` (linear, angular; section
    frame), about the rod's reference axis: ``M = [[rhoA I, -rhoA C], [rhoA C, J_c -
    rhoA C C]]`` (:func:`simsoft_jax.math.lie.spatial_inertia`), ``C = skew(c)``, units kg/m
    (linear block), kg (couplings) and kg m (rotary block); kinetic energy per length
    ``u^T M u / 2``. Checked, each failure one ``ValueError`` naming ``matrix`` (entries
    compared to ``rtol`` times the largest entry): 6x6 and finite; symmetric (the mean of
    ``M`` and ``M^T`` is kept); the translational block ``rhoA I`` with ``rhoA > 0``
    (equal diagonal, zero off-diagonal: every part of a section moves with it); the
    coupling block ``M[3:6, 0:3] = rhoA skew(c)`` skew-symmetric with the centre of mass
    ``c = (0, cy, cz)`` in the section plane; the rotary inertia about the centre of mass
    ``J_c = M[3:6, 3:6] + rhoA C C`` positive semi-definite (a rotary inertia may be 0, as
    in the diagonal form; ``M`` is then positive semi-definite, its Schur complement on the
    translational block being ``J_c``). The result has exactly that form (the checked
    blocks are set to it), so a diagonal input stays exactly diagonal.
    """
    M = np.array(matrix, dtype=float)
    if M.shape != (6, 6):
        raise ValueError(f"matrix: must be 6x6, got shape {M.shape}")
    if not np.all(np.isfinite(M)):
        raise ValueError("matrix: entries must be finite")
    tol = rtol * np.abs(M).max()
    if np.abs(M - M.T).max() > tol:
        i, j = np.unravel_index(np.argmax(np.abs(M - M.T)), M.shape)
        raise ValueError(f"matrix: must be symmetric; entry [{i}][{j}] = {M[i, j]:g} but "
                         f"[{j}][{i}] = {M[j, i]:g}")
    M = 0.5 * (M + M.T)
    rho_a = M[0, 0]
    if not rho_a > 0.0:
        raise ValueError(f"matrix: the line density [0][0] = rhoA must be > 0, got {rho_a:g}")
    linear = np.abs(M[:3, :3] - rho_a * np.eye(3))
    if linear.max() > tol:
        i, j = np.unravel_index(np.argmax(linear), (3, 3))
        raise ValueError(f"matrix: the translational block [0:3][0:3] must be rhoA I (equal "
                         f"diagonal, zero off-diagonal); entry [{i}][{j}] = {M[i, j]:g}, "
                         f"rhoA = [0][0] = {rho_a:g}")
    B = M[3:, :3]
    skew_part = 0.5 * (B - B.T)
    skew_part[1, 2] = skew_part[2, 1] = 0.0          # no centre-of-mass offset along x
    off = np.abs(B - skew_part)
    if off.max() > tol:
        i, j = np.unravel_index(np.argmax(off), (3, 3))
        raise ValueError(f"matrix: the coupling block [3:6][0:3] must be rhoA skew(c) with "
                         f"the centre of mass c = (0, cy, cz) in the section plane; entry "
                         f"[{i + 3}][{j}] = {B[i, j]:g}")
    M[:3, :3] = rho_a * np.eye(3)
    M[3:, :3], M[:3, 3:] = skew_part, skew_part.T
    rotary = M[3:, 3:] + skew_part @ skew_part / rho_a
    low = float(np.linalg.eigvalsh(rotary).min())
    if low < -tol:
        raise ValueError(f"matrix: the rotary inertia about the centre of mass, "
                         f"M[3:6][3:6] + rhoA C C, must be positive semi-definite; smallest "
                         f"eigenvalue {low:.4g}")
    return M


def offset_inertia(rhoA: float, centre=(0.0, 0.0), rotary=(0.0, 0.0, 0.0)) -> np.ndarray:
    """(6,6) section inertia about the reference axis (:func:`inertia_matrix`) from the
    line density ``rhoA`` (kg/m), the centre of mass ``centre = (cy, cz)`` (m, section
    frame) and the rotary inertia per length about the centre of mass ``rotary`` (kg m):
    its diagonal ``[J_x, J_y, J_z]`` or the full symmetric (3,3);
    ``M = [[rhoA I, -rhoA C], [rhoA C, J_c - rhoA C C]]``, ``C = skew((0, cy, cz))``
    (:func:`simsoft_jax.math.lie.spatial_inertia`)."""
    from ..math import lie    # JAX, imported here: scene validation (this module) stays NumPy

    rho_a = check_number("rhoA", rhoA)
    centre = np.asarray(centre, dtype=float)
    if centre.shape != (2,):
        raise ValueError(f"centre: must be (cy, cz), got shape {centre.shape}")
    J = np.asarray(rotary, dtype=float)
    J = np.diag(J) if J.shape == (3,) else J
    if J.shape != (3, 3):
        raise ValueError(f"rotary: must be 3 numbers or 3x3, got shape {J.shape}")
    c = np.concatenate([[0.0], centre])
    return inertia_matrix(np.asarray(lie.spatial_inertia(rho_a, c, J)))


STRAIN_NAMES = ("eps_x", "gamma_y", "gamma_z", "kappa_x", "kappa_y", "kappa_z")


def stiffness_matrix(matrix, rtol: float = 1e-9) -> np.ndarray:
    """Validated full section stiffness (6,6) with couplings.

    Rows and columns follow the strains ``[eps_x, gamma_y, gamma_z, kappa_x, kappa_y,
    kappa_z]`` (extension, the two shears, twist, bending about local y, bending about
    local z), so ``[N; M] = K eps`` with units N (linear block), N m (couplings between
    forces and curvatures) and N m^2 (angular block). ``K`` must be symmetric (to
    ``rtol`` relative to its largest entry; the mean of ``K`` and ``K^T`` is kept) and
    positive definite (a Cholesky factorization exists), else one ``ValueError`` naming
    ``matrix``; the diagonal is the uncoupled ``[EA, GAy, GAz, GJ, EIy, EIz]``.
    """
    K = np.array(matrix, dtype=float)
    if K.shape != (6, 6):
        raise ValueError(f"matrix: must be 6x6, got shape {K.shape}")
    if not np.all(np.isfinite(K)):
        raise ValueError("matrix: entries must be finite")
    scale = np.abs(K).max()
    asym = np.abs(K - K.T).max()
    if asym > rtol * scale:
        i, j = np.unravel_index(np.argmax(np.abs(K - K.T)), K.shape)
        raise ValueError(f"matrix: must be symmetric; entry [{i}][{j}] = {K[i, j]:g} but "
                         f"[{j}][{i}] = {K[j, i]:g}")
    K = 0.5 * (K + K.T)
    try:
        np.linalg.cholesky(K)
    except np.linalg.LinAlgError:
        low = float(np.linalg.eigvalsh(K).min())
        raise ValueError(f"matrix: must be positive definite (a stored energy "
                         f"1/2 eps^T K eps > 0 for every strain); smallest eigenvalue "
                         f"{low:.4g}") from None
    return K


def coupled_stiffness(diagonal, couplings=None) -> np.ndarray:
    """(6,6) stiffness from the diagonal ``[EA, GAy, GAz, GJ, EIy, EIz]`` and couplings
    ``{(i, j): value}`` (strain indices 0..5 in :data:`STRAIN_NAMES` order, or their
    names, e.g. ``{("kappa_x", "kappa_y"): -0.102}`` for bending-twist coupling, N m^2);
    each coupling is written at ``[i][j]`` and ``[j][i]``. Validated by
    :func:`stiffness_matrix`."""
    K = np.diag(np.asarray(diagonal, dtype=float))
    for (i, j), value in (couplings or {}).items():
        i = STRAIN_NAMES.index(i) if isinstance(i, str) else int(i)
        j = STRAIN_NAMES.index(j) if isinstance(j, str) else int(j)
        if i == j:
            raise ValueError(f"couplings: ({i}, {j}) is a diagonal entry, not a coupling")
        K[i, j] = K[j, i] = float(value)
    return stiffness_matrix(K)


RIGID_SHEAR_FACTOR = 100.0   # GA / EA that beam4_stiffness takes for shear-rigid data


def beam4_stiffness(K4, shear=None, signs=(1.0, 1.0, 1.0, 1.0)) -> np.ndarray:
    """(6,6) stiffness from the 4x4 beam stiffness of strain-based aeroelastic beam codes.

    ``K4`` (4,4) symmetric, strains ``[extension, twist, out-of-plane (flap) bending,
    in-plane (edgewise) bending]`` (e.g. UM/NAST of Su & Cesnik, Pazy wing data:
    K11 N, K22 GJ, K33 flap EI, K44 edge EI, N m^2, couplings K12..K34). Axis convention
    used here: the rod's local x along the beam reference axis, local y along the chord
    (in-plane), local z normal to the wing plane; flap bending turns the section about
    local y (``kappa_y``, the tip moves along z) and edgewise bending about local z
    (``kappa_z``). The 4 strains go to ``[eps_x, kappa_x, kappa_y, kappa_z]`` with the
    optional ``signs`` (+-1 per source strain) when the source's axes point the other way
    (a coupling ``K_ij`` changes sign with ``signs[i] signs[j]``).

    Shear-rigid sources give no shear stiffness. ``shear = (GAy, GAz)`` (N) sets it;
    ``None`` takes ``GA = 100 K11`` (:data:`RIGID_SHEAR_FACTOR` times the extension
    stiffness) for both, so that the shear part of a cantilever's tip deflection,
    ``P L / GA`` (Timoshenko), is ``3 EI / (GA L^2) = 0.03 EI / (K11 L^2)`` of the bending
    part ``P L^3 / (3 EI)``: for a slender beam (``EI / K11`` the squared radius of
    gyration) far below any measurement, while the Newton residual's round-off floor
    (about eps GA) stays far below the solver tolerance. Checked positive definite.
    """
    K4 = np.asarray(K4, dtype=float)
    if K4.shape != (4, 4):
        raise ValueError(f"K4: must be 4x4, got shape {K4.shape}")
    s = np.asarray(signs, dtype=float)
    K = np.zeros((6, 6))
    rows = np.array([0, 3, 4, 5])
    K[np.ix_(rows, rows)] = K4 * np.outer(s, s)
    if shear is None:
        rigid = RIGID_SHEAR_FACTOR * check_number("K4[0][0]", K4[0, 0])
        shear = (rigid, rigid)
    K[1, 1], K[2, 2] = (check_number("shear[0]", shear[0]), check_number("shear[1]", shear[1]))
    return stiffness_matrix(K)
