"""Tests for simsoft_jax.scene.materials: library values, G/nu relation, input validation."""

import dataclasses
import math

import pytest

from simsoft_jax.scene.materials import BUILTIN_MATERIALS, Material, get_material


@pytest.mark.parametrize("name, E, G, nu, density", [
    ("aluminum_7075", 71.7e9, 27.37e9, 71.7e9 / (2 * 27.37e9) - 1, 2679.0),
    ("spring_steel", 210e9, 210e9 / 2.6, 0.3, 7850.0),
    ("silicone", 110e3, 110e3 / 3.0, 0.5, 1080.0),
])
def test_builtin_library(name, E, G, nu, density):
    m = get_material(name)
    assert m is BUILTIN_MATERIALS[name]
    assert m.name == name
    assert m.E == E and m.density == density and m.viscosity == 0.0
    assert m.G == pytest.approx(G, rel=1e-14)
    assert m.nu == pytest.approx(nu, rel=1e-14)


def test_builtin_names():
    assert set(BUILTIN_MATERIALS) == {"aluminum_7075", "spring_steel", "silicone"}


def test_aluminum_nu_close_to_seed():
    # The seed quotes nu = 0.31 alongside G = 27.37 GPa (text before eq. (109)).
    assert get_material("aluminum_7075").nu == pytest.approx(0.31, abs=5e-4)


def test_G_from_nu():
    m = Material(E=200.0, nu=0.25, density=1.0)
    assert isinstance(m.G, float) and m.G == pytest.approx(80.0, rel=1e-15)
    assert m.nu == 0.25


def test_nu_from_G():
    m = Material(E=260.0, G=100.0, density=1.0)
    assert isinstance(m.nu, float) and m.nu == pytest.approx(0.3, rel=1e-14)
    assert m.G == 100.0


def test_G_equal_E_over_3_is_incompressible():
    m = Material(E=110e3, G=110e3 / 3.0, density=1080.0)
    assert m.nu == pytest.approx(0.5, abs=1e-15) and m.nu <= 0.5


def test_values_are_floats():
    m = Material(E=3, nu=0, density=2, viscosity=1)
    assert all(isinstance(getattr(m, f), float) for f in ("E", "G", "nu", "density", "viscosity"))


def test_with_viscosity_returns_copy():
    base = get_material("silicone")
    damped = base.with_viscosity(2.5)
    assert damped.viscosity == 2.5 and base.viscosity == 0.0
    assert (damped.E, damped.G, damped.nu, damped.density, damped.name) == (
        base.E, base.G, base.nu, base.density, base.name)
    with pytest.raises(ValueError, match=r"^mu: "):
        base.with_viscosity(-1.0)


def test_frozen():
    with pytest.raises(dataclasses.FrozenInstanceError):
        get_material("spring_steel").E = 1.0


GOOD = {"E": 1e9, "density": 1000.0, "nu": 0.3}


@pytest.mark.parametrize("arg, value", [
    ("E", 0.0), ("E", -1.0), ("E", math.nan), ("E", math.inf), ("E", "1e9"), ("E", None),
    ("density", 0.0), ("density", -5.0), ("density", math.nan), ("density", "x"),
    ("nu", 0.6), ("nu", -1.0), ("nu", -2.0), ("nu", math.nan), ("nu", math.inf), ("nu", "0.3"),
    ("viscosity", -0.1), ("viscosity", math.nan), ("viscosity", math.inf), ("viscosity", "a"),
    ("name", ""), ("name", 3),
])
def test_bad_input_names_argument(arg, value):
    kwargs = dict(GOOD, **{arg: value})
    with pytest.raises(ValueError, match=rf"^{arg}: "):
        Material(**kwargs)


def test_message_format():
    with pytest.raises(ValueError, match=r"^E: must be a finite number > 0, got -1$"):
        Material(E=-1, density=1.0, nu=0.3)


@pytest.mark.parametrize("G", [0.0, -1.0, math.nan, math.inf, "1", 1e9 / 3.5])
def test_bad_G(G):
    # 1e9 / 3.5 < E / 3 implies nu = 0.75 > 0.5
    with pytest.raises(ValueError, match=r"^G: "):
        Material(E=1e9, density=1.0, G=G)


def test_both_G_and_nu():
    with pytest.raises(ValueError, match=r"^G, nu: give exactly one of G and nu"):
        Material(E=1e9, density=1.0, G=4e8, nu=0.25)


def test_neither_G_nor_nu():
    with pytest.raises(ValueError, match=r"^G, nu: give exactly one of G and nu"):
        Material(E=1e9, density=1.0)


def test_get_material_unknown():
    with pytest.raises(ValueError, match=r"^name: .*aluminum_7075, silicone, spring_steel"):
        get_material("unobtainium")
