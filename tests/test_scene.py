"""Scene parsing and validation (simsoft_jax.scene.scene): the scene-format.md contract."""

import copy
import json
import math
import re
import subprocess
import sys

import numpy as np
import pytest

from simsoft_jax.scene.scene import Scene, load_scene, save_scene
from conftest import REPO_ROOT, SCENES_DIR

ROOT = REPO_ROOT
EXAMPLES = sorted(SCENES_DIR.glob("*"))
EXAMPLES = [p for p in EXAMPLES if p.suffix in (".toml", ".json")]

BASE = {
    "name": "base",
    "solver": {"kind": "static"},
    "rods": [{
        "name": "arm",
        "material": "aluminum_7075",
        "section": {"shape": "rectangle", "width": 3.2e-3, "height": 12.4e-3},
        "elements": 4,
        "geometry": {"kind": "straight", "length": 0.5},
    }],
    "constraints": [{"kind": "clamp", "rod": "arm", "node": 0}],
    "loads": [{"kind": "force", "rod": "arm", "node": -1, "vector": [0.0, 0.0, -1.0]}],
}

DYNAMIC = {"kind": "dynamic", "t_end": 1.0, "dt": 0.01}
DRIVE = {"kind": "drive", "rod": "arm", "node": -1, "times": [0.0, 1.0],
         "displacement": [[0, 0, 0], [0, 0, 0.1]], "rotation": [[0, 0, 0], [0, 0.5, 0]]}
DEL = object()


def mutate(*changes):
    """A copy of BASE with ``(key path tuple, value)`` changes (value DEL removes the key)."""
    d = copy.deepcopy(BASE)
    for keys, value in changes:
        target = d
        for k in keys[:-1]:
            target = target[k]
        if value is DEL:
            del target[keys[-1]]
        else:
            target[keys[-1]] = copy.deepcopy(value)
    return d


def rename(d_path, old, new):
    d = copy.deepcopy(BASE)
    target = d
    for k in d_path:
        target = target[k]
    target[new] = target.pop(old)
    return d


ROD = ("rods", 0)
LOAD = ("loads", 0)
BAD = [
    ("negative width", mutate((ROD + ("section", "width"), -1)), "rods[0].section.width"),
    ("misspelt key", rename(ROD + ("geometry",), "length", "lenght"), "rods[0].geometry.lenght"),
    ("zero elements", mutate((ROD + ("elements",), 0)), "rods[0].elements"),
    ("bool elements", mutate((ROD + ("elements",), True)), "rods[0].elements"),
    ("float elements", mutate((ROD + ("elements",), 4.0)), "rods[0].elements"),
    ("string length", mutate((ROD + ("geometry", "length"), "0.5")), "rods[0].geometry.length"),
    ("unknown solver kind", mutate((("solver", "kind"), "quasi")), "solver.kind"),
    ("missing solver", mutate((("solver",), DEL)), "solver"),
    ("dynamic without dt", mutate((("solver",), {"kind": "dynamic", "t_end": 1.0})), "solver.dt"),
    ("dt above t_end", mutate((("solver",), {**DYNAMIC, "dt": 2.0})), "solver.dt"),
    ("rho_inf above 1", mutate((("solver",), {**DYNAMIC, "rho_inf": 1.5})), "solver.rho_inf"),
    ("nan tolerance", mutate((("solver", "tolerance"), float("nan"))), "solver.tolerance"),
    ("zero max_iterations", mutate((("solver", "max_iterations"), 0)), "solver.max_iterations"),
    ("level_tolerance of 1", mutate((("solver", "level_tolerance"), 1.0)), "solver.level_tolerance"),
    ("negative level_tolerance", mutate((("solver", "level_tolerance"), -1e-3)),
     "solver.level_tolerance"),
    ("max_load_step above 1", mutate((("solver", "max_load_step"), 1.5)), "solver.max_load_step"),
    ("zero max_load_step", mutate((("solver", "max_load_step"), 0.0)), "solver.max_load_step"),
    ("gravity of length 2", mutate((("gravity",), {"vector": [0.0, -9.81]})), "gravity.vector"),
    ("gravity with a string", mutate((("gravity",), {"vector": [0, 0, "g"]})), "gravity.vector[2]"),
    ("node out of range", mutate((LOAD + ("node",), 5)), "loads[0].node"),
    ("negative node out of range", mutate((LOAD + ("node",), -6)), "loads[0].node"),
    ("unknown rod in load", mutate((LOAD + ("rod",), "nope")), "loads[0].rod"),
    ("node and s", mutate((LOAD + ("s",), 0.1)), "loads[0]"),
    ("s beyond the tip", mutate((LOAD + ("node",), DEL), (LOAD + ("s",), 0.6)), "loads[0].s"),
    ("unknown frame", mutate((LOAD + ("frame",), "body")), "loads[0].frame"),
    ("inf in load vector", mutate((LOAD + ("vector",), [0, 0, float("inf")])), "loads[0].vector[2]"),
    ("bool in load vector", mutate((LOAD + ("vector",), [True, 0, 0])), "loads[0].vector[0]"),
    ("ramp t1 before t0", mutate((LOAD + ("profile",), {"kind": "ramp", "t0": 2.0, "t1": 1.0})),
     "loads[0].profile.t1"),
    ("table t not increasing",
     mutate((LOAD + ("profile",), {"kind": "table", "t": [0, 2, 1], "scale": [0, 1, 2]})),
     "loads[0].profile.t"),
    ("table lengths differ",
     mutate((LOAD + ("profile",), {"kind": "table", "t": [0, 1], "scale": [0, 1, 2]})),
     "loads[0].profile.scale"),
    ("missing table file",
     mutate((LOAD + ("profile",), {"kind": "table", "file": "no_such_file.txt"})),
     "loads[0].profile.file"),
    ("linear without rate", mutate((LOAD + ("profile",), {"kind": "linear"})), "loads[0].profile.rate"),
    ("distributed force with node", mutate((LOAD + ("kind",), "distributed_force")), "loads[0].node"),
    ("two clamps on one node",
     mutate((("constraints",), [BASE["constraints"][0], {"kind": "clamp", "rod": "arm", "node": 0}])),
     "constraints[1].node"),
    ("pin on a drive node",
     mutate((("constraints",), [BASE["constraints"][0], DRIVE, {"kind": "pin", "rod": "arm", "s": 0.5}])),
     "constraints[2].s"),
    ("drive rows mismatch",
     mutate((("constraints",), [BASE["constraints"][0], {**DRIVE, "displacement": [[0, 0, 0]]}])),
     "constraints[1].displacement"),
    ("drive row of two numbers",
     mutate((("constraints",), [BASE["constraints"][0], {**DRIVE, "displacement": [[0, 0, 0], [0, 1]]}])),
     "constraints[1].displacement[1]"),
    ("drive times decreasing",
     mutate((("constraints",), [BASE["constraints"][0], {**DRIVE, "times": [1.0, 0.0]}])),
     "constraints[1].times"),
    ("times on a clamp", mutate((("constraints", 0, "times"), [0.0])), "constraints[0].times"),
    ("custom material shadows built-in",
     mutate((("materials",), [{"name": "aluminum_7075", "E": 1e9, "nu": 0.3, "density": 1.0}])),
     "materials[0].name"),
    ("both G and nu",
     mutate((("materials",), [{"name": "x", "E": 1e9, "G": 1e8, "nu": 0.3, "density": 1.0}])),
     "materials[0]"),
    ("inline material E negative",
     mutate((ROD + ("material",), {"E": -1.0, "nu": 0.3, "density": 1000.0})), "rods[0].material.E"),
    ("unknown material", mutate((ROD + ("material",), "unobtainium")), "rods[0].material"),
    ("tube inner >= outer",
     mutate((ROD + ("section",), {"shape": "tube", "outer_diameter": 2e-3, "inner_diameter": 3e-3})),
     "rods[0].section"),
    ("unknown section shape", mutate((ROD + ("section", "shape"), "hexagon")), "rods[0].section.shape"),
    ("duplicate rod name", mutate((("rods",), [BASE["rods"][0], BASE["rods"][0]])), "rods[1].name"),
    ("empty rod name", mutate((ROD + ("name",), "")), "rods[0].name"),
    ("arc above 360 deg",
     mutate((ROD + ("geometry",), {"kind": "arc", "radius": 1.0, "angle_deg": 400.0})),
     "rods[0].geometry.angle_deg"),
    ("helix negative pitch",
     mutate((ROD + ("geometry",), {"kind": "helix", "radius": 1.0, "pitch": -0.1, "turns": 2})),
     "rods[0].geometry.pitch"),
    ("polyline repeated point",
     mutate((ROD + ("geometry",), {"kind": "polyline", "points": [[0, 0, 0], [0, 0, 0], [1, 0, 0]]})),
     "rods[0].geometry.points[1]"),
    ("zero rotation axis",
     mutate((ROD + ("base",), {"rotation": {"axis": [0, 0, 0], "angle_deg": 10}})),
     "rods[0].base.rotation.axis"),
    ("initial with one point", mutate((ROD + ("initial",), {"points": [[0, 0, 0]]})),
     "rods[0].initial.points"),
    ("shear coefficients of length 3", mutate((ROD + ("shear_coefficients",), [0.5, 0.8, 0.9])),
     "rods[0].shear_coefficients"),
    ("no section and no overrides", mutate((ROD + ("section",), DEL)), "rods[0].section"),
    ("stiffness missing EIz",
     mutate((ROD + ("stiffness",), {"EA": 1, "GAy": 1, "GAz": 1, "GJ": 1, "EIy": 1})),
     "rods[0].stiffness.EIz"),
    ("unknown top-level key", mutate((("lods",), [])), "lods"),
    ("rods not a list", mutate((("rods",), {"name": "arm"})), "rods"),
    ("initial velocity of unknown rod",
     mutate((("initial_velocity",), [{"rod": "nope", "linear": [0, 0, 0]}])),
     "initial_velocity[0].rod"),
]


@pytest.mark.parametrize("scene, path", [(s, p) for _, s, p in BAD], ids=[i for i, _, _ in BAD])
def test_malformed_scene_names_the_key_path(scene, path):
    with pytest.raises(ValueError, match=re.escape(path)) as info:
        Scene.from_dict(scene)
    assert str(info.value).startswith(path)  # the path leads the message


def test_there_are_enough_distinct_malformed_cases():
    assert len(BAD) >= 25
    assert len({i for i, _, _ in BAD}) == len(BAD)


def test_the_message_carries_the_reason():
    with pytest.raises(ValueError, match=r"^rods\[0\]\.section\.width: must be > 0"):
        Scene.from_dict(mutate((ROD + ("section", "width"), -1)))
    with pytest.raises(ValueError, match=r"rods\[0\]\.geometry\.lenght: unknown key \(allowed: kind, length\)"):
        Scene.from_dict(rename(ROD + ("geometry",), "length", "lenght"))


def test_validation_never_imports_jax():
    """scene.py (and the materials/sections it needs) are plain NumPy: load them under a
    stub package so that simsoft_jax/__init__ (which imports jax) does not run."""
    code = f"""
import sys, types
pkg = types.ModuleType("simsoft_jax")
pkg.__path__ = [{str(ROOT / "simsoft_jax")!r}]
sys.modules["simsoft_jax"] = pkg
import simsoft_jax.scene.scene as sc
from pathlib import Path
for p in sorted(Path({str(ROOT / "examples" / "scenes")!r}).glob("*")):
    if p.suffix in (".toml", ".json"):
        sc.load_scene(p)
try:
    sc.Scene.from_dict({{"solver": {{"kind": "static"}}, "rods": []}})
except ValueError:
    pass
print("jax" in sys.modules)
"""
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False", out.stdout + out.stderr


def test_valid_base_scene():
    scene = Scene.from_dict(BASE)
    rod = scene.rod("arm")
    assert rod.elements == 4 and rod.nodes == 5
    assert rod.material.name == "aluminum_7075"
    assert rod.geometry.arc_length == 0.5
    np.testing.assert_array_equal(rod.base_rotation, np.eye(3))
    np.testing.assert_array_equal(rod.base_position, np.zeros(3))
    assert scene.solver.kind == "static" and scene.solver.tolerance == 1e-10
    assert scene.gravity is None and scene.initial_velocity == ()
    (load,) = scene.loads
    assert load.node == 4 and load.frame == "world" and load.profile.kind == "constant"
    with pytest.raises(ValueError, match="nope"):
        scene.rod("nope")


def test_continuation_keys_reach_the_static_settings():
    """``solver.level_tolerance`` / ``max_load_step`` reach StaticSettings; absent, the
    largest increment is ``1/load_steps`` (the scene format's minimum continuation
    steps: :func:`statics.max_load_step` is None there)."""
    from simsoft_jax.solvers.statics import settings_from_scene
    plain = settings_from_scene(Scene.from_dict(BASE).solver)
    assert plain.max_load_step is None and plain.level_tolerance == 1e-3
    given = {**BASE, "solver": {**BASE["solver"], "level_tolerance": 0.0, "max_load_step": 0.5}}
    settings = settings_from_scene(Scene.from_dict(given).solver)
    assert settings.level_tolerance == 0.0 and settings.max_load_step == 0.5


def test_node_resolution_negative_and_arc_length():
    d = mutate((("loads",), [
        {"kind": "force", "rod": "arm", "node": -1, "vector": [1, 0, 0]},
        {"kind": "force", "rod": "arm", "node": -5, "vector": [1, 0, 0]},
        {"kind": "moment", "rod": "arm", "s": 0.26, "vector": [1, 0, 0]},   # inside element 2
        {"kind": "moment", "rod": "arm", "s": 0.5, "vector": [1, 0, 0]},
        {"kind": "distributed_force", "rod": "arm", "vector": [0, 0, -1]},
    ]))
    loads = Scene.from_dict(d).loads
    assert [ld.node for ld in loads] == [4, 0, None, 4, None]
    assert loads[2].element == 2 and loads[2].xi == pytest.approx(0.08, abs=1e-12)  # not rounded


def test_arc_lengths_of_geometries():
    d = mutate((ROD + ("geometry",), {"kind": "helix", "radius": 0.1, "pitch": 0.05, "turns": 2}),
               (ROD + ("elements",), 8))  # 90 degrees per element, the limit
    g = Scene.from_dict(d).rods[0].geometry
    assert g.arc_length == pytest.approx(2 * math.hypot(2 * math.pi * 0.1, 0.05))
    d = mutate((ROD + ("geometry",), {"kind": "arc", "radius": 2.0, "angle_deg": 90}))
    assert Scene.from_dict(d).rods[0].geometry.arc_length == pytest.approx(math.pi)
    d = mutate((ROD + ("geometry",), {"kind": "polyline", "points": [[0, 0, 0], [3, 4, 0], [3, 4, 1]]}))
    assert Scene.from_dict(d).rods[0].geometry.arc_length == pytest.approx(6.0)


def test_rotation_forms_agree():
    vec = Scene.from_dict(mutate((ROD + ("base",), {"rotation": [0, 0, math.pi / 2]}))).rods[0]
    axis = Scene.from_dict(mutate((ROD + ("base",), {"rotation": {"axis": [0, 0, 5], "angle_deg": 90}}))).rods[0]
    expected = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    np.testing.assert_allclose(vec.base_rotation, expected, atol=1e-15)
    np.testing.assert_allclose(axis.base_rotation, expected, atol=1e-15)
    R = Scene.from_dict(mutate((ROD + ("base",), {"rotation": [0.3, -0.2, 1.1]}))).rods[0].base_rotation
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-14)
    assert np.linalg.det(R) == pytest.approx(1.0)
    small = Scene.from_dict(mutate((ROD + ("base",), {"rotation": [1e-10, 0, 0]}))).rods[0].base_rotation
    np.testing.assert_allclose(small, [[1, 0, 0], [0, 1, -1e-10], [0, 1e-10, 1]], atol=1e-20)


def test_drive_constraint_rows():
    rotation = [[0, 0, 0], {"axis": [0, 2, 0], "angle_deg": 180}]
    d = mutate((("solver",), DYNAMIC),
               (("constraints",), [{**DRIVE, "node": 0, "rotation": rotation, "slides_along": [2, 0, 0]}]))
    (c,) = Scene.from_dict(d).constraints
    assert c.kind == "drive" and c.node == 0
    np.testing.assert_allclose(c.rotation, [[0, 0, 0], [0, math.pi, 0]])
    np.testing.assert_array_equal(c.times, [0.0, 1.0])
    np.testing.assert_array_equal(c.slides_along, [1.0, 0.0, 0.0])
    # displacement omitted -> zeros, one row per time
    d["constraints"][0].pop("displacement")
    np.testing.assert_array_equal(Scene.from_dict(d).constraints[0].displacement, np.zeros((2, 3)))


def test_material_forms():
    d = mutate((("materials",), [{"name": "al", "E": 70e9, "G": 26e9, "density": 2700}]),
               (ROD + ("material",), "al"))
    assert Scene.from_dict(d).rods[0].material.name == "al"
    d = mutate((ROD + ("material",), {"E": 1e6, "nu": 0.5, "density": 1000, "viscosity": 0.1}))
    assert Scene.from_dict(d).rods[0].material.viscosity == 0.1


def test_overrides_without_section_or_material():
    stiffness = {"EA": 1e3, "GAy": 1e3, "GAz": 1e3, "GJ": 1, "EIy": 1, "EIz": 2}
    inertia = {"rhoA": 0.1, "rhoJ": 2, "rhoIy": 1, "rhoIz": 1}
    d = mutate((ROD + ("section",), DEL), (ROD + ("material",), DEL),
               (ROD + ("stiffness",), stiffness), (ROD + ("inertia",), inertia))
    rod = Scene.from_dict(d).rods[0]
    assert rod.section is None and rod.material is None
    np.testing.assert_array_equal(rod.stiffness, [1e3, 1e3, 1e3, 1, 1, 2])
    np.testing.assert_array_equal(rod.inertia, [0.1, 0.1, 0.1, 2, 1, 1])
    # a section needs a material
    d = mutate((ROD + ("material",), DEL), (ROD + ("stiffness",), stiffness))
    with pytest.raises(ValueError, match=re.escape("rods[0].material")):
        Scene.from_dict(d)


def test_table_profile_from_file(tmp_path):
    (tmp_path / "law.csv").write_text("t, scale\n0, 0\n1.0, 0.5  # comment\n\n2 1\n")
    d = mutate((LOAD + ("profile",), {"kind": "table", "file": "law.csv"}))
    scene = Scene.from_dict(d, base_dir=tmp_path)
    np.testing.assert_array_equal(scene.loads[0].profile.t, [0, 1, 2])
    np.testing.assert_array_equal(scene.loads[0].profile.scale, [0, 0.5, 1])
    # the file is read once: to_dict is self-contained and round-trips from anywhere
    assert Scene.from_dict(scene.to_dict()) == scene
    (tmp_path / "bad.txt").write_text("0 0\n1 x\n")
    d = mutate((LOAD + ("profile",), {"kind": "table", "file": "bad.txt"}))
    with pytest.raises(ValueError, match=re.escape("loads[0].profile.file")):
        Scene.from_dict(d, base_dir=tmp_path)
    # load_scene resolves relative to the scene file's folder
    (tmp_path / "scene.json").write_text(json.dumps(
        mutate((LOAD + ("profile",), {"kind": "table", "file": "law.csv"}))))
    assert load_scene(tmp_path / "scene.json").loads[0].profile.t.tolist() == [0, 1, 2]


def test_toml_and_json_give_the_same_scene(tmp_path):
    toml_text = """
name = "pair"
[solver]
kind = "dynamic"
t_end = 1.0
dt = 0.01
[gravity]
vector = [0.0, 0.0, -9.81]
[[rods]]
name = "arm"
material = "spring_steel"
section = { shape = "circle", diameter = 2e-3 }
elements = 8
geometry = { kind = "arc", radius = 0.5, angle_deg = 90.0 }
base = { position = [0.0, 0.0, 1.0], rotation = { axis = [0, 1, 0], angle_deg = 90 } }
[[constraints]]
kind = "clamp"
rod = "arm"
node = 0
[[loads]]
kind = "moment"
rod = "arm"
s = 0.7
vector = [0.0, 0.49, 0.0]
frame = "local"
profile = { kind = "linear", rate = 1.0 }
[[initial_velocity]]
rod = "arm"
angular = [0.0, 3.14159, 0.0]
"""
    (tmp_path / "a.toml").write_text(toml_text)
    import tomllib
    (tmp_path / "a.json").write_text(json.dumps(tomllib.loads(toml_text)))
    a, b = load_scene(tmp_path / "a.toml"), load_scene(tmp_path / "a.json")
    assert a.source.endswith("a.toml") and b.source.endswith("a.json")
    assert a.replace(source=None) == b.replace(source=None)
    x = 0.7 / (0.5 * math.pi / 2) * 8              # inside element 7: not rounded
    assert a.loads[0].node is None and a.loads[0].element == 7
    assert a.loads[0].xi == pytest.approx(x - 7, abs=1e-12)
    np.testing.assert_array_equal(a.initial_velocity[0].linear, np.zeros(3))


@pytest.mark.parametrize("suffix", [".toml", ".json"])
def test_save_load_round_trip(tmp_path, suffix):
    d = mutate((("materials",), [{"name": "soft \"rubber\"", "E": 1e6, "nu": 0.45, "density": 1100}]),
               (ROD + ("material",), "soft \"rubber\""),
               (("solver",), {**DYNAMIC, "rho_inf": 0.5, "inertia": "lumped"}),
               (("gravity",), {"vector": [0, 0, -9.81]}),
               (ROD + ("base",), {"position": [1, 2, 3], "rotation": {"axis": [1, 1, 0], "angle_deg": 33.3}}),
               (ROD + ("initial",), {"points": [[0, 0, 0], [0.25, 0.01, 0], [0.5, 0, 0]]}),
               (("constraints",), [BASE["constraints"][0],
                                   {**DRIVE, "rotation": [[0, 0, 0], {"axis": [0, 0, 1], "angle_deg": 45}]}]),
               (("loads",), [{"kind": "force", "rod": "arm", "s": 0.25, "vector": [1e-300, 0.1, -4.448],
                              "profile": {"kind": "table", "t": [0, 1], "scale": [0, 1]}}]))
    scene = Scene.from_dict(d)
    path = tmp_path / f"scene{suffix}"
    save_scene(scene, path)
    again = load_scene(path)
    assert again.replace(source=None) == scene
    assert again.to_dict() == scene.to_dict() == d


@pytest.mark.parametrize("path", EXAMPLES, ids=[p.name for p in EXAMPLES])
def test_example_scenes_load(path, tmp_path):
    scene = load_scene(path)
    assert scene.rods and scene.name == path.stem
    for suffix in (".toml", ".json"):  # and survive a save/load round trip
        save_scene(scene, tmp_path / f"copy{suffix}")
        assert load_scene(tmp_path / f"copy{suffix}").replace(source=None) == scene.replace(source=None)


def test_example_scenes_content():
    names = {p.name for p in EXAMPLES}
    assert {"cantilever_tip_force.toml", "princeton_theta30.toml", "helical_synthetic.json"} <= names
    princeton = load_scene(ROOT / "examples" / "scenes" / "princeton_theta30.toml")
    rod = princeton.rods[0]
    th = math.radians(30)
    np.testing.assert_allclose(rod.base_rotation,
                               [[1, 0, 0], [0, math.cos(th), -math.sin(th)], [0, math.sin(th), math.cos(th)]],
                               atol=1e-15)
    assert rod.shear_coefficients == (0.590, 0.833)
    assert princeton.gravity is not None and princeton.loads[0].node == 16
    helical = load_scene(ROOT / "examples" / "scenes" / "helical_synthetic.json")
    assert helical.solver.kind == "dynamic" and helical.solver.t_end == 3.0 and helical.solver.dt == 0.01
    assert helical.rods[0].elements == 10
    assert {ld.profile.kind for ld in helical.loads} == {"smoothstep"}


def test_file_errors(tmp_path):
    with pytest.raises(ValueError, match="unsupported"):
        load_scene(tmp_path / "scene.yaml")
    with pytest.raises(ValueError, match="cannot read"):
        load_scene(tmp_path / "missing.toml")
    (tmp_path / "broken.toml").write_text("[solver\nkind = 1")
    with pytest.raises(ValueError, match=re.escape("broken.toml")):
        load_scene(tmp_path / "broken.toml")
    (tmp_path / "nan.json").write_text(json.dumps(
        mutate((("gravity",), {"vector": [0, 0, float("nan")]}))))
    with pytest.raises(ValueError, match=re.escape("gravity.vector[2]: must be finite")):
        load_scene(tmp_path / "nan.json")


def test_numpy_inputs_are_accepted_and_raw_is_plain():
    d = mutate((LOAD + ("vector",), np.array([0.0, 0.0, -1.0])), (ROD + ("elements",), np.int64(4)))
    scene = Scene.from_dict(d)
    assert scene.rods[0].elements == 4
    json.dumps(scene.to_dict())  # plain types only
    assert not scene.loads[0].vector.flags.writeable
