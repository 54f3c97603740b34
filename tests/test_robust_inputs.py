"""Bad input is refused while the scene is read, with one line naming the key or file:

* ``simsoft-jax validate`` refuses exactly what ``simsoft-jax run`` refuses: every check
  of the state a scene starts in (held rods, joint points, welds, tendon crossings,
  contact radius, folded start points) gives both commands the same one-line error, and
  neither solves;
* damaged or binary files read by a scene (a restart result, a table), numbers beyond
  the solver's limits, repeated JSON keys, huge or control-character names;
* ``--plot`` / ``--animate`` checked before solving; result files written with the
  permissions of any new file; the documented stopping rules and tendon rules.
"""
import json
import os
import re
import stat
import zipfile

import numpy as np
import pytest

import simsoft_jax as sj
from simsoft_jax.cli import main
from simsoft_jax.atomic_files import write_atomic
from simsoft_jax.solvers.statics import StaticSettings

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
STIFF = {"EA": 2e3, "GAy": 1e3, "GAz": 1e3, "GJ": 0.4, "EIy": 0.5, "EIz": 0.5}
INERTIA = {"rhoA": 0.1, "rhoJ": 1e-4, "rhoIy": 5e-5, "rhoIz": 5e-5}


def rod(name="r", elements=2, length=1.0, position=(0.0, 0.0, 0.0), **extra):
    return {"name": name, "material": "spring_steel",
            "section": {"shape": "circle", "diameter": 0.002}, "elements": elements,
            "geometry": {"kind": "straight", "length": length},
            "base": {"position": list(position)}, **extra}


def table_rod(name="r", position=(0.0, 0.0, 0.0)):
    """A rod given by stiffness and inertia tables (no section, so no contact radius)."""
    return {"name": name, "elements": 2, "geometry": {"kind": "straight", "length": 1.0},
            "stiffness": STIFF, "inertia": INERTIA, "base": {"position": list(position)}}


def clamp(name="r", node=0):
    return {"kind": "clamp", "rod": name, "node": node}


def static(**extra):
    return {"solver": {"kind": "static"}, "rods": [rod()], "constraints": [clamp()], **extra}


def weld(a, na, b, nb, offset_a=None):
    end_a = {"rod": a, "node": na} | ({} if offset_a is None else {"offset": offset_a})
    return {"kind": "weld", "a": end_a, "b": {"rod": b, "node": nb}}


# ---------------------------------------------------------------- validate == run


# (what, scene, the error line's start): one per check of the start state
START_ERRORS = [
    ("joint points apart",
     {"solver": {"kind": "static"}, "rods": [rod("a"), rod("b", position=(1.5, 0, 0))],
      "constraints": [clamp("a")], "joints": [weld("a", -1, "b", 0)]},
     "joints[0]: the joint points of ends a and b are 0.5 m apart at the start"),
    ("weld of two clamped nodes",
     {"solver": {"kind": "static"}, "rods": [rod("a"), rod("b", position=(1.0, 0, 0))],
      "constraints": [clamp("a"), clamp("a", -1), clamp("b")],
      "joints": [weld("a", -1, "b", 0)]},
     "joints[0]: both ends are held by clamps or drives"),
    ("tendon points apart at a weld",
     {"solver": {"kind": "static"},
      "rods": [table_rod("a"), table_rod("b", position=(1.0, 0, 0))],
      "constraints": [clamp("a")], "joints": [weld("a", -1, "b", 0)],
      "tendons": [{"name": "t", "rod": "a", "to_rod": "b", "offset": [0.0, 0.01],
                   "rod_offsets": {"b": [0.0, 0.03]}, "tension": 1.0}]},
     "tendons[0]: tendon 't' crosses the weld joints[0] from rod 'a' (node 2) to rod 'b' "
     "(node 0), but its routing points there are 0.02 m apart"),
    ("contact without a radius",
     {"solver": {"kind": "static"},
      "rods": [table_rod()],
      "constraints": [clamp()],
      "obstacles": [{"name": "floor", "kind": "plane", "point": [0, 0, -1],
                     "normal": [0, 0, 1]}]},
     "contact.radius: required: rod 'r' has no circular section"),
    ("start points folding back",
     {"solver": {"kind": "static"},
      "rods": [rod(elements=4, initial={"points": [[0, 0, 0], [1, 0, 0], [0, 0, 0]]})],
      "constraints": [clamp()]},
     "rods[0].initial.points: fold back on themselves: node 2 of rod 'r' has no tangent"),
]


@pytest.mark.parametrize("what, scene, start", START_ERRORS,
                         ids=[w for w, _, _ in START_ERRORS])
def test_validate_refuses_what_run_refuses(tmp_path, capsys, what, scene, start):
    """Each check that building the model once made (so validate said "valid") now runs
    while the scene is read: validate and run exit 2 with the same one error line."""
    path = tmp_path / "scene.json"
    path.write_text(json.dumps(scene))
    assert main(["validate", str(path)]) == 2
    checked = capsys.readouterr()
    assert main(["run", "--no-cache", str(path)]) == 2
    ran = capsys.readouterr()
    assert checked.err == ran.err and checked.out == ran.out == ""
    assert checked.err.count("\n") == 1 and checked.err.startswith(f"error: {start}"), \
        checked.err


def test_build_model_checks_a_replaced_scene_again():
    """Scene.replace does not validate: build_model runs the start-state checks itself."""
    good = sj.Scene.from_dict({"solver": {"kind": "static"},
                               "rods": [rod("a"), rod("b", position=(1.0, 0, 0))],
                               "constraints": [clamp("a")],
                               "joints": [weld("a", -1, "b", 0)]})
    moved = good.replace(rods=(good.rods[0], sj.Scene.from_dict(static(rods=[
        rod("b", position=(1.25, 0, 0))], constraints=[clamp("b")])).rods[0]))
    with pytest.raises(ValueError, match=r"^joints\[0\]: the joint points of ends a and b "
                                         r"are 0\.25 m apart"):
        sj.build_model(moved)


def test_a_weld_across_a_gap_closed_by_the_offset_is_accepted():
    """The joint point is the node plus its offset: a weld whose offset bridges the gap
    exactly is valid (the gap check compares the two joint points)."""
    sj.Scene.from_dict({"solver": {"kind": "static"},
                        "rods": [rod("a"), rod("b", position=(1.5, 0, 0))],
                        "constraints": [clamp("a")],
                        "joints": [weld("a", -1, "b", 0, offset_a=[0.5, 0, 0])]})


# ---------------------------------------------------------------- files a scene reads

def restart_scene(result_file):
    return static(rods=[rod(initial={"result": str(result_file)})])


@pytest.mark.parametrize("damage", ["bytes", "truncated", "empty"])
def test_a_damaged_restart_file_is_named(tmp_path, capsys, damage):
    """A .npz that is not a zip archive, is cut short or empty: one line naming the key
    and the file (was a zipfile.BadZipFile traceback, in validate too)."""
    bad = tmp_path / "old.npz"
    if damage == "bytes":
        bad.write_bytes(b"\x80\x81not a zip" * 10)
    else:
        good = tmp_path / "good.npz"
        np.savez(good, **{"r/positions": np.zeros((3, 3)), "r/rotations": np.zeros((3, 3, 3))})
        data = good.read_bytes()
        bad.write_bytes(data[:len(data) // 2] if damage == "truncated" else b"")
    with pytest.raises(ValueError, match=r"^rods\[0\]\.initial\.result: old\.npz: not a "
                                         r"readable result file"):
        sj.Scene.from_dict(restart_scene(bad))
    scene = tmp_path / "s.json"
    scene.write_text(json.dumps(restart_scene(bad)))
    assert main(["validate", str(scene)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("error: rods[0].initial.result: old.npz")


def test_a_binary_table_file_is_named(tmp_path):
    table = tmp_path / "law.csv"
    table.write_bytes(bytes(range(128, 256)))
    scene = {"solver": {"kind": "dynamic", "dt": 0.1, "t_end": 1.0}, "rods": [rod()],
             "constraints": [clamp()],
             "loads": [{"kind": "force", "rod": "r", "node": -1, "vector": [0, 0, 1],
                        "profile": {"kind": "table", "file": "law.csv"}}]}
    with pytest.raises(ValueError) as err:
        sj.Scene.from_dict(scene, base_dir=tmp_path)
    assert str(err.value).startswith("loads[0].profile.file: ")
    assert "law.csv" in str(err.value) and "is not a text file (byte 0 is not UTF-8)" \
        in str(err.value)


def test_repeated_json_keys_are_refused(tmp_path):
    """JSON readers keep the last of two equal keys; the scene reader refuses, as the
    TOML reader does."""
    path = tmp_path / "s.json"
    path.write_text('{"solver": {"kind": "static", "kind": "dynamic"}, "rods": []}')
    with pytest.raises(ValueError, match=r"not valid JSON: the key 'kind' appears twice"):
        sj.load_scene(path)
    path.write_text('{"solver": {"kind": "static"}, "rods": [], "solver": {}}')
    with pytest.raises(ValueError, match=r"the key 'solver' appears twice"):
        sj.load_scene(path)


# ---------------------------------------------------------------- numbers and names

@pytest.mark.parametrize("solver, message", [
    ({"max_iterations": 10**30}, "solver.max_iterations: must be <= 10000, got 1000000"),
    ({"load_steps": 10**7}, "solver.load_steps: must be <= 1000000, got 10000000"),
    ({"kind": "dynamic", "t_end": 1.0, "dt": 1e-30, "max_steps": 10**40},
     "solver.max_steps: must be <= 100000000, got 1"),
    ({"kind": "dynamic", "t_end": 1.0, "dt": 0.1, "save_every": 10**9},
     "solver.save_every: must be <= 100000000"),
    ({"tolerance": 10**400}, "solver.tolerance: must be finite, got 1000000"),
])
def test_integers_beyond_the_solver_limits_are_refused(solver, message):
    """(was: max_iterations = 10**30 passed validate and overflowed inside the solver;
    max_steps = 10**40 failed in the dynamic driver; a 400-digit JSON number raised an
    OverflowError)"""
    scene = static()
    scene["solver"].update(solver)
    with pytest.raises(ValueError) as err:
        sj.Scene.from_dict(scene)
    assert str(err.value).startswith(message) and len(str(err.value)) < 200, str(err.value)


def test_contact_sizes_have_limits():
    for key, most in (("quadrature_points", 64), ("max_pairs", 1000)):
        scene = static(contact={"self": True, key: most + 1})
        with pytest.raises(ValueError, match=rf"^contact\.{key}: must be <= {most}, got"):
            sj.Scene.from_dict(scene)


def test_a_huge_name_is_not_repeated_in_full(tmp_path, capsys):
    """A 1 MB rod name in a constraint: the error stays short (the name cut)."""
    huge = "x" * 1_000_000
    scene = static(constraints=[clamp(huge)])
    with pytest.raises(ValueError) as err:
        sj.Scene.from_dict(scene)
    text = str(err.value)
    assert text.startswith("constraints[0].rod: no rod named 'xxxx") and len(text) < 300
    path = tmp_path / "s.json"
    path.write_text(json.dumps(static(**{huge: 1})))
    assert main(["validate", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: xxxx") and err.count("\n") == 1 and len(err) < 300


@pytest.mark.parametrize("name", ["a\nerror: fake line", "nul\x00name", "esc\x1b[2Jx",
                                  "sep\u2028x"])
def test_control_characters_in_names_are_escaped(tmp_path, capsys, name):
    """A name holding a newline, NUL or terminal escape cannot print a line of its own:
    the error is one line with the characters escaped."""
    path = tmp_path / "s.json"
    path.write_text(json.dumps(static(constraints=[clamp(name)])))
    assert main(["validate", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("error: constraints[0].rod: no rod named")
    assert not any(c in err[:-1] for c in "\x00\x1b\u2028\r\n")
    path.write_text(json.dumps(static(**{name: 1})))   # an unknown key
    assert main(["validate", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and not any(c in err[:-1] for c in "\x00\x1b\u2028\r\n")
    path.write_text(json.dumps(static(rods=[rod(name)], constraints=[clamp(name)])))
    assert main(["validate", str(path)]) == 0             # a valid scene: its summary line
    out = capsys.readouterr().out
    assert out.count("\n") == 1 and not any(c in out[:-1] for c in "\x00\x1b\u2028\r\n")


# ---------------------------------------------------------------- the command line

@pytest.mark.parametrize("option, value, message", [
    ("--plot", "missing_dir/fig.png", "--plot: folder 'missing_dir' does not exist"),
    ("--plot", "fig.xyz", "--plot: unsupported suffix '.xyz' of 'fig.xyz' (use "),
    ("--animate", "movie.avi", "--animate: unsupported suffix '.avi' of 'movie.avi' "
                               "(use .gif, .mp4)"),
    ("--animate", "movie.gif", "--animate: needs a dynamic scene"),
])
def test_figure_options_are_checked_before_solving(tmp_path, capsys, monkeypatch, option,
                                                   value, message):
    """(was: checked only after the solve, a matplotlib traceback for a missing folder)
    The solve is never reached: ``run`` is replaced by a function that fails the test."""
    import simsoft_jax.pipeline.results as results
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(results, "run", lambda *a, **k: pytest.fail("solved"))
    (tmp_path / "s.json").write_text(json.dumps(static()))
    assert main(["run", "s.json", option, value]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"error: {message}") and err.count("\n") == 1, err


@pytest.mark.parametrize("umask", [0o022, 0o077, 0o002])
def test_result_files_get_the_permissions_of_new_files(tmp_path, umask):
    """(was: owner-only, rw-------, whatever the umask) ``0666`` less the umask, as
    ``open`` gives a PNG beside it."""
    old = os.umask(umask)
    try:
        write_atomic(tmp_path / "out.json", lambda fh: fh.write("{}"))
        with open(tmp_path / "beside.png", "w"):
            pass
    finally:
        os.umask(old)
    mode = stat.S_IMODE(os.stat(tmp_path / "out.json").st_mode)
    assert mode == 0o666 & ~umask == stat.S_IMODE(os.stat(tmp_path / "beside.png").st_mode)


# ---------------------------------------------------------------- documented rules

def _docs():
    with open(os.path.join(ROOT, "docs", "scene-format.md"), encoding="utf-8") as fh:
        return fh.read()


def test_the_tolerance_row_states_every_stopping_rule():
    """``tolerance = 1e-300`` ends "converged" by the step and stagnation rules: the
    docs' definition of ``tolerance`` gives both, with the solver's values."""
    row = next(line for line in _docs().splitlines() if line.startswith("| `tolerance` |"))
    settings = StaticSettings()
    step = re.search(r"next Newton step is below `([^`]+)`", row)
    stagnation = re.search(r"stops halving below `([^`]+)` times", row)
    assert float(step.group(1)) == settings.step_tolerance
    assert float(stagnation.group(1)) == settings.stagnation_level
    assert "`1e-300`" in row


def test_docs_and_scene_reader_agree_on_displacement_tendons_in_dynamics():
    """The docs once said both that dynamics solves displacement-controlled tendons and
    that it refuses them; it solves them, with joints too, and the docs say so."""
    text = _docs()
    assert "A dynamic scene with a displacement-controlled tendon is refused" not in text
    assert "with joints, bodies, sliding drives (`slides_along`) and rod-rod contact" in text
    scene = {"solver": {"kind": "dynamic", "dt": 0.01, "t_end": 0.1},
             "rods": [rod(elements=4)], "constraints": [clamp()],
             "tendons": [{"name": "t", "rod": "r", "offset": [0.0, 0.001],
                          "displacement": -1e-4}]}
    sj.Scene.from_dict(scene)
    scene["rods"].append(rod("b", position=(1.0, 0, 0)))
    scene["joints"] = [weld("r", -1, "b", 0)]
    assert sj.Scene.from_dict(scene).tendons[0].displacement == -1e-4


def test_damaged_zip_member_is_named(tmp_path):
    """A zip archive whose member is damaged (a CRC error on reading) is named too."""
    good = tmp_path / "old.npz"
    np.savez(good, **{"r/positions": np.zeros((3, 3)), "r/rotations": np.zeros((3, 3, 3))})
    with zipfile.ZipFile(good) as z:
        members = {n: z.read(n) for n in z.namelist()}
    data = bytearray(good.read_bytes())
    start = data.find(members["r/positions.npy"][-20:])
    data[start:start + 8] = b"\xff" * 8       # stored data changed, CRC kept
    good.write_bytes(bytes(data))
    with pytest.raises(ValueError, match=r"^rods\[0\]\.initial\.result: old\.npz: not a "
                                         r"readable result file"):
        sj.Scene.from_dict(restart_scene(good))


def test_a_long_file_path_is_named_in_full(tmp_path):
    """Only runs of more than 1000 non-blank characters are cut: a 300-character path
    to a missing scene file is named whole."""
    path = tmp_path / ("d" * 120) / ("s" * 120 + ".json")
    assert len(str(path)) > 240
    with pytest.raises(ValueError) as err:
        sj.load_scene(path)
    assert str(err.value).startswith(f"{path}: cannot read scene file: ")
