"""Scene parsing of section stiffness and inertia tables (diagonal or full 6x6 matrix),
point masses (``[[masses]]``) and load offsets: plain Python + NumPy, errors naming the key path
(:mod:`simsoft_jax.scene.scene` calls these; contract in ``docs/scene-format.md``)."""
from __future__ import annotations

from typing import Any

import numpy as np

from .key_checks import (check_keys, fail, index, join, matrix, number, positive, prefixed,
                        readonly, table, vector)
from .sections import custom_inertia, custom_stiffness, inertia_matrix, stiffness_matrix

STIFFNESS_KEYS = ("EA", "GAy", "GAz", "GJ", "EIy", "EIz")
INERTIA_KEYS = ("rhoA", "rhoJ", "rhoIy", "rhoIz")


def _section_constants(value: Any, path: str, keys: tuple, diagonal, full) -> np.ndarray:
    """A section table: its named diagonal ``keys`` -> ``diagonal(**values)``, or
    ``{ matrix = [[..6..] x 6] }`` (the key alone in its table) -> ``full(rows)``; errors
    name ``path.key`` / ``path.matrix``."""
    k = table(value, path)
    if "matrix" not in k:
        check_keys(k, path, keys + ("matrix",), required=keys)
        args = {n: number(k[n], join(path, n)) for n in keys}
        with prefixed(path, keys):
            return diagonal(**args)
    check_keys(k, path, ("matrix",), required=("matrix",))
    mpath = join(path, "matrix")
    rows = matrix(k["matrix"], mpath, 6)
    if len(rows) != 6:
        fail(mpath, f"must have 6 rows of 6 numbers, got {len(rows)} rows")
    with prefixed(path, ("matrix",)):
        return full(rows)


def parse_stiffness(value: Any, path: str) -> np.ndarray:
    """``stiffness = {EA, GAy, GAz, GJ, EIy, EIz}`` -> the diagonal (6,), or
    ``stiffness = { matrix = [[..6..] x 6] }`` -> the full symmetric positive definite
    matrix (6,6) (strains ``eps_x, gamma_y, gamma_z, kappa_x, kappa_y, kappa_z``;
    :func:`~simsoft_jax.scene.sections.stiffness_matrix`)."""
    return _section_constants(value, path, STIFFNESS_KEYS, custom_stiffness, stiffness_matrix)


def parse_section_inertia(value: Any, path: str) -> np.ndarray:
    """``inertia = {rhoA, rhoJ, rhoIy, rhoIz}`` -> the diagonal (6,), or
    ``inertia = { matrix = [[..6..] x 6] }`` -> the full section inertia (6,6) per unit
    length about the reference axis, with an offset centre of mass
    (:func:`~simsoft_jax.scene.sections.inertia_matrix`)."""
    return _section_constants(value, path, INERTIA_KEYS, custom_inertia, inertia_matrix)


MASS_KEYS = ("rod", "node", "s", "mass", "offset", "inertia")


def parse_offset(ld: dict, path: str, kind: str, frame: str, profile_kind: str,
                 inside_element: bool) -> np.ndarray | None:
    """A point load's ``offset`` (3,) (m, section frame): the force acts at
    ``p + R offset``, so it also makes the moment ``offset x R^T F`` about the node, which
    turns with the section. Forces at a node only; a world-frame (dead) force at an offset
    needs a constant profile (a time law there is not supported yet)."""
    if "offset" not in ld:
        return None
    opath = join(path, "offset")
    if kind != "force":
        fail(opath, f"only a force can act at an offset (kind = {kind!r})")
    if inside_element:
        fail(opath, "a load placed by s inside an element cannot have an offset; place it "
             "at a node")
    if frame == "world" and profile_kind != "constant":
        fail(opath, "a world-frame force at an offset needs a constant profile (a time law "
             "with an offset is supported for frame = \"local\" only)")
    return vector(ld["offset"], opath)


def parse_inertia(value: Any, path: str) -> np.ndarray:
    """An inertia tensor (3,3), kg m^2: 3 rows of 3 numbers, symmetric (to 1e-9 of its
    largest entry; symmetrized) and positive semi-definite."""
    inertia = matrix(value, path, 3)
    if inertia.shape != (3, 3):
        fail(path, f"must be 3x3 (3 rows of 3 numbers), got {len(inertia)} rows")
    scale = max(np.abs(inertia).max(), 1e-300)
    if np.abs(inertia - inertia.T).max() > 1e-9 * scale:
        fail(path, "must be symmetric")
    inertia = 0.5 * (inertia + inertia.T)
    if np.linalg.eigvalsh(inertia).min() < -1e-12 * scale:
        fail(path, "must be positive semi-definite (principal moments >= 0)")
    return inertia


def parse_masses(items: list, rods: dict, node_of) -> tuple:
    """``[[masses]]`` -> :class:`~simsoft_jax.scene.scene_specs.MassSpec` tuple: a rigid mass
    (``mass`` > 0, kg) attached to a rod node, centre of mass at ``offset`` (m, section
    frame, default 0), ``inertia`` (3x3, kg m^2, about the centre, section frame;
    symmetric positive semi-definite, default 0: a point mass). ``node_of(item, path,
    rod)`` resolves ``node``/``s``."""
    from .scene_specs import MassSpec

    out = []
    for i, item in enumerate(items):
        path = index("masses", i)
        check_keys(item, path, MASS_KEYS, required=("rod", "mass"))
        name = item["rod"]
        if not isinstance(name, str) or name not in rods:
            fail(join(path, "rod"), f"no rod named {name!r} (known: {', '.join(rods)})")
        rod = rods[name]
        node = node_of(item, path, rod)
        mass = positive(item["mass"], join(path, "mass"))
        offset = vector(item.get("offset", [0.0, 0.0, 0.0]), join(path, "offset"))
        inertia = np.zeros((3, 3))
        if "inertia" in item:
            inertia = parse_inertia(item["inertia"], join(path, "inertia"))
        out.append(MassSpec(rod=name, node=node, mass=mass, offset=readonly(offset),
                            inertia=readonly(inertia)))
    return tuple(out)
