"""Per-element stiffness and per-node mass tables of beam data sets, mapped to the
section frame.

Data sets give beam properties in their own axes (e.g. the Pazy wing: a 4x4 stiffness
per element in the frame of a strain-based beam code, lumped masses per node in the
Nastran frame, X aft along the chord, Y spanwise, Z up). A *frame map* says where each
table axis points in the section frame of simsoft_jax (x along the rod, y and z the
section axes): ``frame = ("-y", "x", "z")`` reads "table axis 1 is the section's -y,
table axis 2 its x (the rod tangent), table axis 3 its z". It is the signed permutation
``Q`` with ``v_section = Q v_table`` (:func:`frame_matrix`).

A stiffness table relates the generalized forces to the strains ``e_t = [G_1, G_2, G_3,
k_1, k_2, k_3]`` in the table's axes (translational strain, then curvature/twist
components), so that in the section frame ``e_s = T e_t`` with ``T = diag(Q, Q)`` and the
energy ``e_t^T K_t e_t / 2`` gives ``K_s = T K_t T^T`` (the order of
:data:`simsoft_jax.scene.sections.STRAIN_NAMES`). Which column holds which entry is the
``columns`` map (:data:`BEAM4_COLUMNS` for the 4x4 layout K11..K44 of UM/NAST-type data:
strains ``[extension, twist, flap bending, edgewise bending]`` about the table axes 1, 1,
2, 3). A mass table gives a mass per node and its centre of gravity in the table's axes,
``offset_s = Q c_t``.
"""
from __future__ import annotations

import csv
from pathlib import Path
from typing import NamedTuple, Sequence

import numpy as np

from .sections import RIGID_SHEAR_FACTOR, stiffness_matrix

# 4x4 layout (K11 extension, K22 twist, K33 flap, K44 edgewise, couplings K12..K34) as
# entries (i, j) of the 6x6 table matrix over [G_1, G_2, G_3, k_1, k_2, k_3]
BEAM4_COLUMNS = {"K11": (0, 0), "K22": (3, 3), "K33": (4, 4), "K44": (5, 5),
                 "K12": (0, 3), "K13": (0, 4), "K14": (0, 5), "K23": (3, 4),
                 "K24": (3, 5), "K34": (4, 5)}


def frame_matrix(frame: Sequence[str]) -> np.ndarray:
    """(3,3) signed permutation ``Q`` (``v_section = Q v_table``) from a frame map: three
    of ``"x"``, ``"y"``, ``"z"`` with an optional sign, one per table axis, each section
    axis once (e.g. ``("-y", "x", "z")``)."""
    frame = tuple(frame)
    if len(frame) != 3:
        raise ValueError(f"frame: give one section axis per table axis (3), got {list(frame)}")
    Q = np.zeros((3, 3))
    for k, name in enumerate(frame):
        text = str(name).strip()
        sign = -1.0 if text.startswith("-") else 1.0
        axis = text.lstrip("+-")
        if axis not in ("x", "y", "z"):
            raise ValueError(f"frame: entry {k} must be x, y or z with an optional sign, "
                             f"got {name!r}")
        Q["xyz".index(axis), k] = sign
    if not np.allclose(np.abs(Q).sum(axis=1), 1.0):
        raise ValueError(f"frame: must name each section axis x, y, z once (one per table "
                         f"axis), got {list(frame)}")
    return Q


def _rows(path: Path, needed: Sequence[str]) -> list:
    """``(line, {column: float})`` of the CSV ``path`` for the ``needed`` columns; errors
    name the file, the line and the column."""
    if not path.is_file():
        raise ValueError(f"section table: no such file {str(path)!r}")
    with path.open(newline="") as handle:
        reader = csv.DictReader(handle)
        missing = [c for c in needed if c not in (reader.fieldnames or [])]
        if missing:
            raise ValueError(f"section table: {path.name} lacks column(s) {missing} "
                             f"(columns: {reader.fieldnames})")
        out = []
        for line, row in enumerate(reader, start=2):
            values = {}
            for column in needed:
                text = (row[column] or "").strip()
                try:
                    values[column] = float(text)
                except ValueError:
                    raise ValueError(f"section table: {path.name} line {line}, column "
                                     f"{column}: not a number: {text!r}") from None
                if not np.isfinite(values[column]):
                    raise ValueError(f"section table: {path.name} line {line}, column "
                                     f"{column}: not finite")
            out.append((line, values))
    if not out:
        raise ValueError(f"section table: {path.name} has no data rows")
    return out


def read_stiffness_table(path, columns: dict = BEAM4_COLUMNS, frame=("x", "y", "z"),
                         shear=None) -> np.ndarray:
    """(E, 6, 6) section stiffness matrices, one per row of ``path`` (the elements in the
    file's order, e.g. root to tip), in the section frame (module docstring: ``K_s = T
    K_t T^T``).

    columns: ``{column: (i, j)}``, the entry of the symmetric table matrix over ``[G_1,
    G_2, G_3, k_1, k_2, k_3]`` (table axes) that the column holds (N, N m or N m^2).
    frame: the frame map (:func:`frame_matrix`). shear: ``(GAy, GAz)`` (N, section frame)
    for tables that give no shear stiffness (both section shear diagonals zero after the
    mapping); None takes ``GA = 100 EA`` as :func:`simsoft_jax.scene.sections.beam4_stiffness`
    does (shear-rigid data). Each matrix is checked symmetric positive definite
    (:func:`simsoft_jax.scene.sections.stiffness_matrix`), the error naming the line.
    """
    path = Path(path)
    for column, (i, j) in columns.items():
        if not (0 <= i < 6 and 0 <= j < 6):
            raise ValueError(f"columns: {column!r} maps to ({i}, {j}), outside the 6x6 matrix")
    Q = frame_matrix(frame)
    T = np.zeros((6, 6))
    T[:3, :3], T[3:, 3:] = Q, Q
    out = []
    for line, values in _rows(path, list(columns)):
        Kt = np.zeros((6, 6))
        for column, (i, j) in columns.items():
            Kt[i, j] = Kt[j, i] = values[column]
        K = T @ Kt @ T.T
        if K[1, 1] == 0.0 and K[2, 2] == 0.0:
            K[1, 1], K[2, 2] = ((RIGID_SHEAR_FACTOR * K[0, 0],) * 2 if shear is None
                                else (float(shear[0]), float(shear[1])))
        try:
            out.append(stiffness_matrix(K))
        except ValueError as err:
            raise ValueError(f"section table: {path.name} line {line}: {err}") from None
    return np.array(out)


class MassTable(NamedTuple):
    """Lumped masses of a table: mass (N,) kg, one per row (node); offset (N, 3) m, the
    centre of gravity in the section frame."""
    mass: np.ndarray
    offset: np.ndarray

    def scene_masses(self, rod: str, first_node: int = 0) -> list[dict]:
        """The scene's ``[[masses]]`` entries: row k on node ``first_node + k`` of ``rod``."""
        return [{"rod": rod, "node": first_node + k, "mass": float(m),
                 "offset": [float(v) for v in c]}
                for k, (m, c) in enumerate(zip(self.mass, self.offset))]


def read_mass_table(path, mass: str = "mass", centre=("cgx", "cgy", "cgz"),
                    frame=("x", "y", "z")) -> MassTable:
    """:class:`MassTable` of ``path``: column ``mass`` (kg, >= 0) and the centre of
    gravity columns ``centre`` (m, table axes 1, 2, 3) mapped by ``frame`` to the section
    frame (``offset = Q c``, :func:`frame_matrix`); e.g. the Pazy wing's Nastran-frame
    table (X aft, Y spanwise, Z up) on a rod along +Y whose section y points to the
    leading edge: ``frame=("-y", "x", "z")``."""
    path = Path(path)
    Q = frame_matrix(frame)
    rows = _rows(path, [mass, *centre])
    for line, values in rows:
        if values[mass] < 0.0:
            raise ValueError(f"section table: {path.name} line {line}, column {mass}: "
                             f"must be >= 0, got {values[mass]}")
    masses = np.array([v[mass] for _, v in rows])
    centres = np.array([[v[c] for c in centre] for _, v in rows])
    return MassTable(masses, centres @ Q.T)
