"""Tests for simsoft_jax.scene.sections against independently computed closed forms and quadratures."""

import math

import numpy as np
import pytest
import scipy.sparse as sparse
import scipy.sparse.linalg as sparse_linalg
from scipy.integrate import dblquad

from simsoft_jax.scene.materials import Material, get_material
from simsoft_jax.scene.sections import (circle, custom_inertia, custom_stiffness, inertia_diagonal,
                                  rectangle, semicircle, stiffness_diagonal, tube,
                                  viscosity_diagonal)


def sig4(x):
    """Round to 4 significant digits."""
    return float(f"{x:.3e}")


def polar_quad(f, r0, r1, t0, t1, epsabs=0.0):
    """∫∫ f(y, z) dA over the annular sector r0 <= r <= r1, t0 <= theta <= t1 (y = r cos, z = r sin)."""
    value, _ = dblquad(lambda r, t: f(r * math.cos(t), r * math.sin(t)) * r, t0, t1, r0, r1,
                       epsabs=epsabs, epsrel=1e-12)
    return value


# ---------------------------------------------------------------- geometry vs quadrature

def test_rectangle_against_grid_integration():
    w, h, n = 3.0e-3, 7.0e-3, 1500
    y = (np.arange(n) + 0.5) / n * w - w / 2          # midpoints of a fine grid
    z = (np.arange(n) + 0.5) / n * h - h / 2
    Y, Z = np.meshgrid(y, z, indexing="ij")
    dA = (w / n) * (h / n)
    s = rectangle(w, h)
    assert s.area == pytest.approx(Y.size * dA, rel=1e-12)
    assert s.Iy == pytest.approx(np.sum(Z**2) * dA, rel=1e-6)
    assert s.Iz == pytest.approx(np.sum(Y**2) * dA, rel=1e-6)
    assert s.polar == pytest.approx(s.Iy + s.Iz)
    assert s.centroid_offset == 0.0 and s.shape == "rectangle"
    assert s.dimensions == {"width": w, "height": h}


def saint_venant_rectangle(a, b, terms=200):
    """Exact series torsion constant of an a x b rectangle, a >= b (Timoshenko & Goodier)."""
    n = np.arange(1, 2 * terms, 2)
    return a * b**3 / 3 * (1 - 192 / np.pi**5 * (b / a) * np.sum(np.tanh(n * np.pi * a / (2 * b)) / n**5))


@pytest.mark.parametrize("ratio", [1.0, 1.2, 1.5, 2.0, 3.0, 3.865, 5.0, 10.0, 100.0])
def test_rectangle_torsion_close_to_saint_venant(ratio):
    b = 2e-3
    for w, h in ((ratio * b, b), (b, ratio * b)):
        assert rectangle(w, h).torsion_constant == pytest.approx(
            saint_venant_rectangle(ratio * b, b), rel=2e-3)


def test_rectangle_torsion_roark_formula_princeton():
    # Roark formula evaluated by hand for the Princeton beam (spec §7.1: 1.13416e-10 m^4).
    a, b = 12.377e-3, 3.2024e-3
    expected = a * b**3 * (1 / 3 - 0.21 * (b / a) * (1 - b**4 / (12 * a**4)))
    jt = rectangle(b, a).torsion_constant
    assert jt == pytest.approx(expected, rel=1e-14)
    assert jt == pytest.approx(1.13416e-10, rel=1e-5)


def test_circle_against_polar_quadrature():
    d = 2e-3
    R = d / 2
    s = circle(d)
    assert s.area == pytest.approx(polar_quad(lambda y, z: 1.0, 0, R, 0, 2 * math.pi), rel=1e-10)
    assert s.Iy == pytest.approx(polar_quad(lambda y, z: z**2, 0, R, 0, 2 * math.pi), rel=1e-10)
    assert s.Iz == pytest.approx(polar_quad(lambda y, z: y**2, 0, R, 0, 2 * math.pi), rel=1e-10)
    # Saint-Venant: for a circle, J_t equals the polar moment (no warping).
    polar = polar_quad(lambda y, z: y**2 + z**2, 0, R, 0, 2 * math.pi)
    assert s.torsion_constant == pytest.approx(polar, rel=1e-10)
    assert s.polar == pytest.approx(polar, rel=1e-10)
    assert s.centroid_offset == 0.0


def test_tube_against_polar_quadrature():
    D, d = 3.48e-3, 2.54e-3
    s = tube(D, d)
    args = (d / 2, D / 2, 0, 2 * math.pi)
    assert s.area == pytest.approx(polar_quad(lambda y, z: 1.0, *args), rel=1e-10)
    assert s.Iy == pytest.approx(polar_quad(lambda y, z: z**2, *args), rel=1e-10)
    assert s.Iz == pytest.approx(polar_quad(lambda y, z: y**2, *args), rel=1e-10)
    assert s.torsion_constant == pytest.approx(polar_quad(lambda y, z: y**2 + z**2, *args), rel=1e-10)


def test_tube_without_hole_equals_circle():
    t, c = tube(5e-2, 0.0), circle(5e-2)
    for attr in ("area", "Iy", "Iz", "torsion_constant", "centroid_offset", "polar"):
        assert getattr(t, attr) == pytest.approx(getattr(c, attr), rel=1e-15)
    assert t.default_shear_coefficients(0.3) == pytest.approx(c.default_shear_coefficients(0.3))


def test_semicircle_against_polar_quadrature():
    r = 1e-2
    s = semicircle(r)
    args = (0, r, 0, math.pi)                         # z = r sin(theta) >= 0: flat side on z = 0
    area = polar_quad(lambda y, z: 1.0, *args)
    c = polar_quad(lambda y, z: z, *args) / area
    assert s.area == pytest.approx(area, rel=1e-10)
    assert s.centroid_offset == pytest.approx(c, rel=1e-10)
    assert s.Iy == pytest.approx(polar_quad(lambda y, z: (z - c) ** 2, *args), rel=1e-9)
    assert s.Iz == pytest.approx(polar_quad(lambda y, z: y**2, *args), rel=1e-10)
    product = polar_quad(lambda y, z: y * (z - c), *args, epsabs=1e-22)
    assert product == pytest.approx(0.0, abs=1e-20)     # y, z are principal axes


def prandtl_torsion_semicircle(n):
    """J_t of the unit half disc by finite differences: ∇²φ = -2 in Ω, φ = 0 on ∂Ω, J = 2∫φ dA."""
    h = 1.0 / n
    Y, Z = np.meshgrid(np.arange(-n, n + 1) * h, np.arange(n + 1) * h, indexing="ij")
    inside = (Y**2 + Z**2 < 1 - 1e-12) & (Z > 1e-12)
    index = -np.ones(Y.shape, dtype=int)
    index[inside] = np.arange(inside.sum())
    i, j = np.nonzero(inside)
    k = index[i, j]
    rows, cols, vals = [k], [k], [np.full(k.size, 4.0)]
    for di, dj in ((1, 0), (-1, 0), (0, 1), (0, -1)):
        nb = index[i + di, j + dj]
        keep = nb >= 0
        rows.append(k[keep]), cols.append(nb[keep]), vals.append(-np.ones(keep.sum()))
    A = sparse.csc_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))))
    phi = sparse_linalg.spsolve(A, np.full(k.size, 2.0 * h * h))
    return 2.0 * phi.sum() * h * h


def test_semicircle_torsion_approximation_against_finite_differences():
    # Richardson extrapolation of the O(h) staircase-boundary error.
    j_fd = 2 * prandtl_torsion_semicircle(200) - prandtl_torsion_semicircle(100)
    r = 1e-2
    assert semicircle(r).torsion_constant == pytest.approx(j_fd * r**4, rel=2e-3)


# ---------------------------------------------------------------- seed and spec numbers

PRINCETON = dict(width=3.2024e-3, height=12.377e-3)


def test_princeton_stiffness_seed_eq_110():
    K = stiffness_diagonal(rectangle(**PRINCETON), get_material("aluminum_7075"), (0.590, 0.833))
    EA, GAy, GAz, GJ, EIy, EIz = K
    assert [sig4(v) for v in (EA, GAy, GJ, EIy, EIz)] == [2.842e6, 0.6401e6, 3.104, 36.28, 2.429]
    # The seed prints 0.9039e6; G kz A = 0.903672e6 (spec §7.1), i.e. the printed 4th digit is off.
    assert GAz == pytest.approx(0.9039e6, rel=5e-4)
    assert GAz == pytest.approx(27.37e9 * 0.833 * 3.2024e-3 * 12.377e-3, rel=1e-14)


def test_princeton_inertia_seed_eq_109():
    M = inertia_diagonal(rectangle(**PRINCETON), get_material("aluminum_7075"))
    assert sig4(M[0]) == 0.1062 and M[0] == M[1] == M[2]
    assert sig4(M[4]) == 1.356e-6
    # Seed prints 0.09078e-6; rho h b^3/12 = 0.0907473e-6 (spec §7.1, "rounding").
    assert M[5] == pytest.approx(0.09078e-6, rel=5e-4)
    # rhoJ: polar value 1.446e-6 (not the seed's inconsistent 3.034e-6; spec §9 item 14).
    assert sig4(M[3]) == 1.446e-6


def test_helical_scene_sections_spec_7_2():
    K = stiffness_diagonal(circle(2e-3), get_material("spring_steel"))
    assert (sig4(K[4]), sig4(K[5]), sig4(K[3])) == (sig4(0.16493), sig4(0.16493), sig4(0.12687))
    K = stiffness_diagonal(circle(5e-2), get_material("silicone"))
    assert (sig4(K[0]), sig4(K[4])) == (216.0, sig4(0.033748))


def test_magellan_tubes_spec_7_3():
    steel = get_material("spring_steel")
    guide = stiffness_diagonal(tube(3.48e-3, 2.54e-3), steel)
    assert (sig4(guide[4]), sig4(guide[3])) == (sig4(1.0828), 0.8329)
    leader = stiffness_diagonal(tube(2.13e-3, 1.00e-3), steel)
    assert (sig4(leader[4]), sig4(leader[3])) == (sig4(0.20187), sig4(0.15529))


def test_semicircle_spec_7_3():
    s = semicircle(1e-2)
    assert (sig4(s.Iy), sig4(s.Iz)) == (sig4(1.0976e-9), 3.927e-9)
    assert sig4(s.area) == 1.571e-4 and sig4(s.centroid_offset) == 4.244e-3


# ---------------------------------------------------------------- shear coefficients

def test_cowper_circle():
    assert round(circle(1.0).default_shear_coefficients(0.3)[0], 3) == 0.886
    assert circle(1.0).default_shear_coefficients(0.5) == pytest.approx((0.9, 0.9), rel=1e-15)
    assert semicircle(1.0).default_shear_coefficients(0.3) == circle(1.0).default_shear_coefficients(0.3)


def test_cowper_rectangle_and_thin_tube():
    assert rectangle(1.0, 2.0).default_shear_coefficients(0.3) == pytest.approx((13 / 15.3,) * 2)
    # Cowper's thin-walled tube limit: 2 (1 + nu) / (4 + 3 nu).
    k = tube(1.0, 1.0 - 1e-9).default_shear_coefficients(0.3)
    assert k == pytest.approx((2.6 / 4.9,) * 2, rel=1e-8)


def test_default_shear_used_and_override():
    steel = get_material("spring_steel")
    s = circle(2e-3)
    K = stiffness_diagonal(s, steel)
    A, G = math.pi * 1e-6, 210e9 / 2.6
    assert K[1] == pytest.approx(G * A * 7.8 / 8.8) and K[2] == pytest.approx(K[1])
    K = stiffness_diagonal(s, steel, shear_coefficients=(0.5, 0.25))
    assert K[1] == pytest.approx(0.5 * G * A) and K[2] == pytest.approx(0.25 * G * A)


# ---------------------------------------------------------------- diagonal ordering

def test_diagonal_ordering():
    w, h, E, rho, mu = 2.0, 5.0, 7.0, 3.0, 0.5
    mat = Material(E=E, nu=0.25, density=rho, viscosity=mu)
    s = rectangle(w, h)
    A, Iy, Iz, Jt = w * h, w * h**3 / 12, h * w**3 / 12, s.torsion_constant
    assert viscosity_diagonal(s, mat) == pytest.approx(mu * np.array([3 * A, A, A, Jt, 3 * Iy, 3 * Iz]))
    assert inertia_diagonal(s, mat) == pytest.approx(rho * np.array([A, A, A, Iy + Iz, Iy, Iz]))
    G = E / 2.5
    assert stiffness_diagonal(s, mat, (0.7, 0.6)) == pytest.approx(
        [E * A, G * 0.7 * A, G * 0.6 * A, G * Jt, E * Iy, E * Iz])
    assert np.all(viscosity_diagonal(s, get_material("silicone")) == 0.0)


def test_custom_diagonals():
    assert custom_stiffness(1, 2, 3, 4, 5, 6).tolist() == [1.0, 2.0, 3.0, 4.0, 5.0, 6.0]
    assert custom_inertia(0.1, 2.0, 1.0, 0.0).tolist() == [0.1, 0.1, 0.1, 2.0, 1.0, 0.0]


# ---------------------------------------------------------------- validation

BAD = [0, 0.0, -1.0, math.nan, math.inf, -math.inf, "1", None, True]
CONSTRUCTORS = [
    (circle, {"diameter": 1.0}),
    (tube, {"outer_diameter": 2.0, "inner_diameter": 1.0}),
    (rectangle, {"width": 1.0, "height": 2.0}),
    (semicircle, {"radius": 1.0}),
    (custom_stiffness, dict(EA=1.0, GAy=1.0, GAz=1.0, GJ=1.0, EIy=1.0, EIz=1.0)),
    (custom_inertia, dict(rhoA=1.0, rhoJ=1.0, rhoIy=1.0, rhoIz=1.0)),
]
CASES = [(f, good, arg, bad) for f, good in CONSTRUCTORS for arg in good for bad in BAD
         if not (arg in ("inner_diameter", "rhoJ", "rhoIy", "rhoIz") and bad in (0, 0.0))]


@pytest.mark.parametrize("func, good, arg, bad", CASES,
                         ids=[f"{f.__name__}-{a}-{b!r}" for f, _, a, b in CASES])
def test_bad_arguments_named(func, good, arg, bad):
    with pytest.raises(ValueError, match=rf"^{arg}: must be a finite number"):
        func(**dict(good, **{arg: bad}))


def test_message_format():
    with pytest.raises(ValueError, match=r"^width: must be a finite number > 0, got 0$"):
        rectangle(0, 1.0)


def test_zero_allowed_where_documented():
    assert tube(1.0, 0).area == pytest.approx(math.pi / 4)
    assert custom_inertia(1.0, 0, 0, 0)[3:].tolist() == [0.0, 0.0, 0.0]


@pytest.mark.parametrize("inner", [1.0, 1.5])
def test_tube_inner_not_smaller_than_outer(inner):
    with pytest.raises(ValueError, match=r"^inner_diameter: "):
        tube(1.0, inner)


@pytest.mark.parametrize("coefficients, name", [
    ((0.0, 1.0), r"shear_coefficients\[0\]"), ((1.0, -1.0), r"shear_coefficients\[1\]"),
    ((1.0, math.nan), r"shear_coefficients\[1\]"), ((1.0,), "shear_coefficients"),
    ("ab", "shear_coefficients"),
])
def test_bad_shear_coefficients(coefficients, name):
    with pytest.raises(ValueError, match=rf"^{name}: "):
        stiffness_diagonal(circle(1.0), get_material("spring_steel"), coefficients)


@pytest.mark.parametrize("nu", [0.6, -1.0, math.nan, "0.3"])
def test_bad_nu_for_shear_coefficients(nu):
    with pytest.raises(ValueError, match=r"^nu: "):
        circle(1.0).default_shear_coefficients(nu)
