"""A data set's own table read as observations through a table map
(simsoft_jax.studies.measurements.read_table, ``simsoft-jax calibrate --table-map``): synthetic
tables in mm and degrees written from known stiffness factors (one wide, one long and not
zeroed) are fitted back to 1e-6 from the command line, row filters and errors name what is
wrong, every shipped map reads its shipped table as the table's own rows say (read here
with csv), and the shipped Pazy sweep runs through its map on a wing built from the
shipped section tables."""
import csv
import json
from pathlib import Path

import jax.numpy as jnp
import numpy as np
import pytest

import simsoft_jax as sj
from simsoft_jax.math import lie
from simsoft_jax.studies.calibration_groups import apply_group_scales, element_masks, parse_groups
from simsoft_jax.cli import main
from simsoft_jax.data_files import data_path
from simsoft_jax.studies.measurements import QuantityColumn, TableMap, load_table_map, read_table
from simsoft_jax.scene.section_tables import read_mass_table, read_stiffness_table

from test_calibration_groups import strip

REPO = Path(__file__).resolve().parents[1]
BEHIND = 0.05
MASSES = (0.0, 0.3, 0.6)
MAP = """scene = "{series}{tip_mass_kg:.1f}"
reference = "{series}0.0"
rod = "wing"
node = -1
[[quantities]]
column = "defl_mm"
quantity = "uz"
scale = 0.001
std = 0.0005
[[quantities]]
column = "twist_deg"
quantity = "twist"
scale = 0.017453292519943295
std = 0.0017453292519943296
"""


def tip(scene, true):
    """Tip position and rotation of ``scene`` with the flap and torsion stiffness
    multiplied by ``true`` (EIy, GJ)."""
    model = sj.build_model(scene)
    masks = jnp.asarray(element_masks(parse_groups("EIy,GJ"), model.structure))
    eq = sj.solve_static(apply_group_scales(model, masks, jnp.log(jnp.asarray(true))))
    return np.asarray(eq.p[-1]), np.asarray(eq.R[-1])


def test_cli_fits_a_native_table_in_mm_and_degrees(tmp_path, capsys):
    true = (1.3, 0.8)
    scenes = [strip(f"a{m:.1f}", m, BEHIND) for m in MASSES]
    paths = []
    for scene in scenes:
        paths.append(str(tmp_path / f"{scene.name}.json"))
        sj.save_scene(scene, paths[-1])
    p0, R0 = tip(scenes[0], true)
    lines = ["series,tip_mass_kg,defl_mm,twist_deg,note"]
    for scene, m in zip(scenes, MASSES):
        p, R = tip(scene, true)
        twist = float(np.degrees(lie.log_so3(jnp.asarray(R0.T @ R))[0]))
        lines.append(f"a,{m},{float(1e3 * (p[2] - p0[2]))!r},{twist!r},measured")
    lines.append("b,0.3,-12.0,,other rig")             # a series without scenes
    (tmp_path / "table.csv").write_text("\n".join(lines) + "\n")
    (tmp_path / "map.toml").write_text(MAP)
    out = tmp_path / "fitted.json"
    args = ["calibrate", "--scenes", *paths, "--measurements", str(tmp_path / "table.csv"),
            "--table-map", str(tmp_path / "map.toml"), "--params", "EIy,GJ", "-o", str(out)]
    assert main(args) == 2
    assert "unknown scene 'b0.3'" in capsys.readouterr().err
    assert main(args + ["--where", "series=a"]) == 0
    fitted = json.loads(out.read_text())
    np.testing.assert_allclose(fitted["scale"], true, rtol=1e-6)
    # 2 loaded masses x 2 quantities (the 0 kg rows are their own reference)
    assert len(fitted["residuals_normalized"]) == 4
    assert main(args + ["--where", "series"]) == 2
    assert "where: expected COLUMN=VALUE" in capsys.readouterr().err


LONG_MAP = """scene = "{series}{tip_mass_kg:.1f}"
reference = "{series}0.0"
zero_within = "{series}"
rod = "wing"
node = -1
[[quantities]]
column = "reading"
quantity = "uz"
scale = -0.001
std = 0.0005
where = { component = ["down_mm"] }
[[quantities]]
column = "reading"
quantity = "twist"
scale = 0.017453292519943295
std = 0.0017453292519943296
where = { component = ["twist_deg"] }
"""


def test_cli_fits_a_long_table_that_is_not_zeroed(tmp_path):
    """A long table (one reading column, ``component`` naming it: downward deflection in
    mm, twist in degrees) of absolute readings, each series offset by a zero error: the
    map subtracts each series' 0 kg reading and the fit recovers the factors to 1e-6."""
    true = (1.3, 0.8)
    scenes = [strip(f"a{m:.1f}", m, BEHIND) for m in MASSES]
    paths = []
    for scene in scenes:
        paths.append(str(tmp_path / f"{scene.name}.json"))
        sj.save_scene(scene, paths[-1])
    p0, R0 = tip(scenes[0], true)
    lines = ["series,tip_mass_kg,component,reading"]
    for scene, m in zip(scenes, MASSES):
        p, R = tip(scene, true)
        twist = float(np.degrees(lie.log_so3(jnp.asarray(R0.T @ R))[0]))
        lines.append(f"a,{m},down_mm,{7.0 - float(1e3 * (p[2] - p0[2]))!r}")
        lines.append(f"a,{m},twist_deg,{twist - 0.4!r}")
    (tmp_path / "long.csv").write_text("\n".join(lines) + "\n")
    (tmp_path / "map.toml").write_text(LONG_MAP)
    out = tmp_path / "fitted.json"
    assert main(["calibrate", "--scenes", *paths, "--measurements", str(tmp_path / "long.csv"),
                 "--table-map", str(tmp_path / "map.toml"), "--params", "EIy,GJ",
                 "-o", str(out)]) == 0
    fitted = json.loads(out.read_text())
    np.testing.assert_allclose(fitted["scale"], true, rtol=1e-6)
    assert len(fitted["residuals_normalized"]) == 4      # 2 loaded masses x 2 components


def read_csv(*path):
    with data_path("real", *path).open(newline="") as handle:
        return list(csv.DictReader(handle))


def test_shipped_tdcr_map_reads_the_tip_heights_into_the_example_scenes(monkeypatch):
    """Seven tip heights (world z, m) into the scenes examples/real_tdcr_tendon.py writes."""
    monkeypatch.syspath_prepend(str(REPO / "examples"))
    from real_tdcr_tendon import scene_name
    table = read_csv("tdcr_isir_nouredeen", "tip_z_vs_tendon_pull_measured.csv")
    rows = read_table(data_path("real", "tdcr_isir_nouredeen",
                                "tip_z_vs_tendon_pull_measured.csv"),
                      load_table_map("tdcr-tip-height"))
    assert len(rows) == len(table) == 7
    for row, r in zip(rows, table):
        pulls = [float(r[f"pull_t{k}_m"]) for k in (1, 2, 3)]
        assert (row.scene, row.rod, row.node, row.quantity, row.reference) == (
            scene_name(pulls), "backbone", -1, "z", None)
        assert row.value == float(r["z_tip_measured_m"])
        assert row.value == pytest.approx(float(r["z_tip_measured_mm"]) * 1e-3, rel=1e-15)


def test_shipped_minguet_map_reads_the_long_table_with_its_signs():
    """The long table (one displacement per row, ``component`` naming it; the table holds
    -u1, u2, -u3): 101 rows less the 10 placeholder zeros of u2 (beams 1 and 3 at 0 deg),
    each as the world displacement of node 20 (x1 = 0.5 m of 22 elements over 0.55 m)."""
    name = ("minguet_dugundji_composite_cantilever", "displacements_at_x500mm_measured.csv")
    table = read_csv(*name)
    kept = [(line, r) for line, r in enumerate(table, start=2)
            if not (r["beam"] in ("1", "3") and r["root_rotation_deg"] == "0"
                    and r["component"] == "u2")]
    table_map = load_table_map("minguet-strips")
    rows = read_table(data_path("real", *name), table_map)
    assert len(table) == 101 and len(rows) == len(kept) == 91
    assert {round(float(r["station_x1_m"]) / 0.55 * 22) for r in table} == {table_map.node}
    sign = {"u1": ("ux", -1.0), "u2": ("uy", 1.0), "u3": ("uz", -1.0)}
    for row, (line, r) in zip(rows, kept):
        quantity, factor = sign[r["component"]]
        assert row.line == line and row.rod == "strip" and row.reference is None
        assert row.scene == f"beam{r['beam']}_theta{r['root_rotation_deg']}_{r['tip_load_g']}g"
        assert (row.quantity, row.value, row.std) == (quantity, factor * float(
            r["displacement_m"]), 0.0015)
    # beam 2, 45 deg, 400 g: the three components of one scene
    case = {r.quantity: r.value for r in rows if r.scene == "beam2_theta45_400g"}
    assert sorted(case) == ["ux", "uy", "uz"] and case["uz"] < -0.1 < 0 < -case["ux"]


def test_shipped_prepazy_map_subtracts_each_runs_unloaded_reading():
    """Raw readings (the 0 kg rows are not zero): every loaded row relative to the 0 kg row
    of its run (test, skin, load_sequence), deflection in m, twist in degrees to rad."""
    name = ("prepazy_wing_technion", "tip_mass_sweep_measured_prepazy.csv")
    table = read_csv(*name)
    zero = {(r["test"], r["skin"], r["load_sequence"]): r for r in table
            if float(r["tip_mass_kg"]) == 0.0}
    loaded = [r for r in table if float(r["tip_mass_kg"]) != 0.0]
    rows = read_table(data_path("real", *name), load_table_map("prepazy-tip-sweep"))
    uz = [r for r in rows if r.quantity == "uz"]
    tilt = [r for r in rows if r.quantity == "tilt_y"]
    assert len(zero) == 5 and len(uz) == len(loaded) == 83
    assert len(tilt) == sum(1 for r in loaded if r["tip_twist_deg"]) == 45
    for row in uz + tilt:
        r = table[row.line - 2]
        z = zero[r["test"], r["skin"], r["load_sequence"]]
        mass = float(r["tip_mass_kg"])
        assert row.scene == f"{r['test']}_skin{r['skin']}_{mass:.2f}kg"
        assert row.reference == f"{r['test']}_skin{r['skin']}_0.00kg"
        if row.quantity == "uz":
            assert row.value == pytest.approx(float(r["tip_uz_m"]) - float(z["tip_uz_m"]),
                                              abs=1e-15)
        else:
            assert row.value == pytest.approx(np.radians(float(r["tip_twist_deg"])
                                                         - float(z["tip_twist_deg"])), rel=1e-14)
    # the second bending run with skin starts again from its own 0 kg reading (6.6 mm)
    second = next(r for r in uz if r.scene == "bending_skin1_0.20kg" and r.line > 9)
    assert second.value == pytest.approx(-0.016080 - 0.006576, abs=1e-12)


def test_table_rows_carry_their_cells_and_errors_name_the_column(tmp_path):
    (tmp_path / "t.csv").write_text("series,tip_mass_kg,defl_mm,twist_deg\n"
                                    "a,0.3,-5,1.5\na,0.6,,3\na,0.9,x,\n")
    table_map = TableMap("{series}{tip_mass_kg:.1f}", "wing", -1,
                         (QuantityColumn("defl_mm", "uz", 1e-3, 5e-4, (0.0, 0.01, 0.0)),
                          QuantityColumn("twist_deg", "twist", np.pi / 180)),
                         "{series}0.0", {"tip_mass_kg": (0.3, 0.6)})
    rows = read_table(tmp_path / "t.csv", table_map)
    assert [(r.scene, r.quantity, r.line) for r in rows] == [
        ("a0.3", "uz", 2), ("a0.3", "twist", 2), ("a0.6", "twist", 3)]
    assert rows[0].value == -5e-3 and rows[0].std == 5e-4 and rows[0].offset == (0.0, 0.01, 0.0)
    assert rows[1].value == pytest.approx(np.radians(1.5), rel=1e-15)
    assert rows[0].reference == "a0.0" and rows[0].columns["tip_mass_kg"] == "0.3"
    with pytest.raises(ValueError, match="t.csv line 4, column defl_mm: not a number"):
        read_table(tmp_path / "t.csv", table_map._replace(where={}))
    with pytest.raises(ValueError, match="line 2, column rig: scene template"):
        read_table(tmp_path / "t.csv", table_map._replace(scene="{rig}"))
    with pytest.raises(ValueError, match="unknown quantity 'w'"):
        read_table(tmp_path / "t.csv", table_map._replace(
            quantities=(QuantityColumn("defl_mm", "w"),)))
    (tmp_path / "bad.toml").write_text('scene = "x"\nrod = "wing"\nnode = -1\n')
    with pytest.raises(ValueError, match=r"bad.toml: give at least one \[\[quantities\]\]"):
        load_table_map(tmp_path / "bad.toml")
    with pytest.raises(ValueError, match="shipped maps: pazy-tip-sweep"):
        load_table_map("pazy-sweep")
    with pytest.raises(ValueError, match="line 2, column defl_mm: run 'a' has no unloaded reading of uz"):
        read_table(tmp_path / "t.csv", table_map._replace(zero_within="{series}"))
    (tmp_path / "z.csv").write_text("series,tip_mass_kg,defl_mm,twist_deg\n"
                                    "a,0.0,1,\na,0.0,2,\na,0.3,-5,\n")
    with pytest.raises(ValueError, match="z.csv line 3, column defl_mm: run 'a' has a second "
                       "unloaded reading for uz"):
        read_table(tmp_path / "z.csv", table_map._replace(where={}, zero_within="{series}"))
    with pytest.raises(ValueError, match="zero_within needs a reference"):
        read_table(tmp_path / "t.csv", table_map._replace(zero_within="{series}",
                                                          reference=None))


def pazy_scene(mass):
    """The Pazy wing without skin with ``mass`` kg at the tip mid-chord, from the shipped
    tables: one element per table row between the reference-axis stations (44 % chord),
    the rod along world +Y (Nastran frame: X aft, Y span, Z up) with its section y to the
    leading edge, so the tables' frame map is (-y, x, z) for the masses and the identity
    for the 4x4 stiffness."""
    folder = data_path("real", "pazy_wing_technion")
    K = read_stiffness_table(folder / "beam_stiffness_skin0.csv")
    masses = read_mass_table(folder / "beam_inertia_skin0.csv", frame=("-y", "x", "z"))
    stations = np.loadtxt(folder / "beam_reference_axis_nodes.csv", delimiter=",",
                          skiprows=1, usecols=2)
    return sj.Scene.from_dict({
        "name": f"bending_skin0_{mass:.1f}kg", "solver": {"kind": "static", "tolerance": 1e-10},
        "gravity": {"vector": [0.0, 0.0, -9.80665]},
        "rods": [{"name": "wing", "geometry": {"kind": "straight", "length": stations[-1]},
                  "base": {"rotation": [0.0, 0.0, np.pi / 2]},
                  "segments": [{"elements": 1, "length": float(h),
                                "stiffness": {"matrix": Ke.tolist()},
                                "inertia": {"rhoA": 1e-9, "rhoJ": 0.0, "rhoIy": 0.0,
                                            "rhoIz": 0.0}}
                               for Ke, h in zip(K, np.diff(stations))]}],
        "constraints": [{"kind": "clamp", "rod": "wing", "node": 0}],
        "masses": masses.scene_masses("wing"),
        "loads": [{"kind": "force", "rod": "wing", "node": -1,
                   "vector": [0.0, 0.0, -9.80665 * mass], "offset": [0.0, -0.006, 0.0]}]})


def test_shipped_pazy_sweep_calibrates_through_the_shipped_map(tmp_path, capsys):
    """Skin off, bending test, tip masses 0, 1 and 2 kg: the flap stiffness of the
    shipped (model-derived) tables needs a factor near 1 and the fit leaves millimetres."""
    paths = []
    for mass in (0.0, 1.0, 2.0):
        scene = pazy_scene(mass)
        paths.append(str(tmp_path / f"{scene.name}.json"))
        sj.save_scene(scene, paths[-1])
    out = tmp_path / "fitted.json"
    table = data_path("real", "pazy_wing_technion", "tip_mass_sweep_measured.csv")
    assert main(["calibrate", "--scenes", *paths, "--measurements", str(table),
                 "--table-map", "pazy-tip-sweep", "--where", "skin=0", "--where",
                 "test=bending", "--where", "tip_mass_kg=0,1,2", "--params", "EIy",
                 "-o", str(out)]) == 0
    fitted = json.loads(out.read_text())
    assert len(fitted["residuals_normalized"]) == 2
    assert 0.8 < fitted["scale"][0] < 1.25 and fitted["std_scale"][0] < 0.05
    assert fitted["rms"] < 0.005 and fitted["converged"]
    assert "EIy: scale" in capsys.readouterr().out
