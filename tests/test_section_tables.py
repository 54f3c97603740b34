"""Stiffness and mass tables of beam data sets read into the section frame
(simsoft_jax.scene.section_tables): a permuted, sign-flipped table comes back exactly in the
section frame, the shipped Pazy tables agree with the hand mapping of the 4x4 data, and a
cantilever built from a uniform table bends as P L^3 / 3EI."""
import numpy as np
import pytest

import simsoft_jax as sj
from simsoft_jax.scene import sections
from simsoft_jax.data_files import data_path
from simsoft_jax.scene.section_tables import (BEAM4_COLUMNS, frame_matrix, read_mass_table,
                                        read_stiffness_table)

# section-frame values: [EA, GAy, GAz, GJ, EIy, EIz] and one coupling EA-EIz (eps_x, kappa_z)
EA, GAY, GAZ, GJ, EIY, EIZ, C = 2e6, 8e5, 7e5, 3.0, 5.0, 40.0, 150.0
# table axes: 1 = section z, 2 = section -x (the tangent reversed), 3 = section y
FRAME = ("z", "-x", "y")
SIX = {f"K{i + 1}{j + 1}": (i, j) for i in range(6) for j in range(i, 6)}


def write_six(path, rows):
    """A 6x6 table (upper triangle K11..K66 over the table's [G1, G2, G3, k1, k2, k3])."""
    path.write_text("element," + ",".join(SIX) + "\n" + "".join(
        f"{e}," + ",".join(repr(float(v)) for v in row) + "\n" for e, row in enumerate(rows)))


def table_entries():
    """The table's entries written by hand from FRAME: G1 = G_z, G2 = -eps_x, G3 = G_y,
    k1 = k_z, k2 = -k_x, k3 = k_y, so the eps_x-k_z coupling C sits at (2, 4) as -C."""
    K = np.zeros((6, 6))
    K[0, 0], K[1, 1], K[2, 2] = GAZ, EA, GAY
    K[3, 3], K[4, 4], K[5, 5] = EIZ, GJ, EIY
    K[1, 3] = K[3, 1] = -C
    return [K[i, j] for i, j in SIX.values()]


def test_frame_map_is_a_signed_permutation_and_errors_name_the_entry():
    Q = frame_matrix(("-y", "x", "z"))
    np.testing.assert_array_equal(Q @ [1.0, 2.0, 3.0], [2.0, -1.0, 3.0])
    for bad, match in ((("x", "y"), "one section axis per table axis"),
                       (("x", "x", "z"), "each section axis x, y, z once"),
                       (("x", "w", "z"), "entry 1")):
        with pytest.raises(ValueError, match=match):
            frame_matrix(bad)


def test_permuted_table_comes_back_exactly_in_the_section_frame(tmp_path):
    write_six(tmp_path / "k.csv", [table_entries()] * 2)
    K = read_stiffness_table(tmp_path / "k.csv", SIX, FRAME)
    expected = np.diag([EA, GAY, GAZ, GJ, EIY, EIZ])
    expected[0, 5] = expected[5, 0] = C
    assert K.shape == (2, 6, 6)
    np.testing.assert_array_equal(K[1], expected)
    (tmp_path / "m.csv").write_text("node,mass,cgx,cgy,cgz\n0,0.5,0.1,0.2,0.3\n1,0.25,-1,0,2\n")
    masses = read_mass_table(tmp_path / "m.csv", frame=FRAME)
    np.testing.assert_array_equal(masses.mass, [0.5, 0.25])
    # offset_s = (x, y, z) = (-c2, c3, c1)
    np.testing.assert_array_equal(masses.offset, [[-0.2, 0.3, 0.1], [0.0, 2.0, -1.0]])
    assert masses.scene_masses("arm", 1)[1] == {"rod": "arm", "node": 2, "mass": 0.25,
                                                "offset": [0.0, 2.0, -1.0]}


def test_bad_tables_name_file_line_and_column(tmp_path):
    write_six(tmp_path / "k.csv", [table_entries()])
    text = (tmp_path / "k.csv").read_text().replace("2000000.0", "two", 1)
    (tmp_path / "bad.csv").write_text(text)
    with pytest.raises(ValueError, match="bad.csv line 2, column K22: not a number"):
        read_stiffness_table(tmp_path / "bad.csv", SIX, FRAME)
    (tmp_path / "short.csv").write_text("element,K11,K22\n0,1,2\n")
    with pytest.raises(ValueError, match=r"lacks column\(s\) \['K33'"):
        read_stiffness_table(tmp_path / "short.csv", BEAM4_COLUMNS)
    negative = [-v if v == EA else v for v in table_entries()]
    write_six(tmp_path / "neg.csv", [negative])
    with pytest.raises(ValueError, match="neg.csv line 2"):
        read_stiffness_table(tmp_path / "neg.csv", SIX, FRAME)
    (tmp_path / "m.csv").write_text("mass,cgx,cgy,cgz\n-1,0,0,0\n")
    with pytest.raises(ValueError, match="line 2, column mass: must be >= 0"):
        read_mass_table(tmp_path / "m.csv")


def test_shipped_pazy_tables_match_the_4x4_mapping():
    """The Pazy 4x4 table read with BEAM4_COLUMNS (identity frame) equals
    sections.beam4_stiffness of each row's K11..K44; the Nastran-frame masses (X aft,
    Y spanwise, Z up) on a rod along +Y with y to the leading edge: offset (cgy, -cgx, cgz)."""
    import csv
    folder = data_path("real", "pazy_wing_technion")
    K = read_stiffness_table(folder / "beam_stiffness_skin0.csv")
    with open(folder / "beam_stiffness_skin0.csv", newline="") as handle:
        rows = list(csv.DictReader(handle))
    assert K.shape == (15, 6, 6)
    for Ke, row in zip(K, rows):
        k = lambda i, j: float(row[f"K{min(i, j)}{max(i, j)}"])  # noqa: E731
        K4 = np.array([[k(i, j) for j in range(1, 5)] for i in range(1, 5)])
        np.testing.assert_array_equal(Ke, sections.beam4_stiffness(K4))
    masses = read_mass_table(folder / "beam_inertia_skin0.csv", frame=("-y", "x", "z"))
    with open(folder / "beam_inertia_skin0.csv", newline="") as handle:
        first = next(csv.DictReader(handle))
    assert len(masses.mass) == 16 and masses.mass[0] == float(first["mass"])
    np.testing.assert_array_equal(masses.offset[0], [float(first["cgy"]), -float(first["cgx"]),
                                                     float(first["cgz"])])


def test_cantilever_from_a_uniform_table_bends_as_p_l3_over_3ei(tmp_path):
    """Uniform table (flap EI about section y = table axis 3), 64 elements, P L^2 / EI =
    1e-4: w = P L^3 / (3 EI) (1 - 1/(4 n^2)) + P L / GA (the one-point-strain element's
    known defect; geometric nonlinearity O(1e-8))."""
    n, L = 64, 0.5
    write_six(tmp_path / "k.csv", [table_entries()] * n)
    K = read_stiffness_table(tmp_path / "k.csv", SIX, FRAME)
    P = 1e-4 * EIY / L**2
    scene = sj.Scene.from_dict({
        "name": "table", "solver": {"kind": "static", "tolerance": 1e-12},
        "rods": [{"name": "arm", "geometry": {"kind": "straight", "length": L},
                  "segments": [{"elements": 1, "length": L / n,
                                "stiffness": {"matrix": Ke.tolist()},
                                "inertia": {"rhoA": 1.0, "rhoJ": 0.0, "rhoIy": 0.0,
                                            "rhoIz": 0.0}} for Ke in K]}],
        "constraints": [{"kind": "clamp", "rod": "arm", "node": 0}],
        "loads": [{"kind": "force", "rod": "arm", "node": -1, "vector": [0.0, 0.0, P]}]})
    eq = sj.solve_static(sj.build_model(scene))
    w = float(eq.p[-1][2])
    expected = P * L**3 / (3 * EIY) * (1 - 1 / (4 * n**2)) + P * L / GAZ
    assert w == pytest.approx(expected, rel=1e-6)
