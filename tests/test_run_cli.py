"""sj.run, Result.to_dict / save and the command line (spec: shared/spec/scene-format.md,
"Result files" and "Python entry points").

All in-process runs use the structure of examples/scenes/cantilever_tip_force.toml (one
16-element rod, clamp at node 0, dead tip loads, default solver settings), so they share
one compilation. The command-line runs are subprocesses; they share a JAX persistent
compilation cache in a temporary folder (a speed-up only).

Physics reference for the cantilever (Al 7075 strip 3.2024 x 12.377 mm lying flat, 1 lbf
along -z, i.e. along the height): Euler-Bernoulli tip deflection F L^3 / (3 E I_y),
I_y = w h^3 / 12; the tip rotation is 2 % of a radian, so the linear formula holds to
~1e-4 relative (plus shear, F L / (k G A) ~ 5e-4 relative).
"""
import json
import os
import subprocess
import sys

import numpy as np
import pytest

import simsoft_jax as sj  # enables float64
from conftest import REPO_ROOT, SCENES_DIR

ROOT = REPO_ROOT
EXAMPLES = SCENES_DIR
# keys of static results (dynamic results have "time" instead of "stability")
CONTRACT_KEYS = {"name", "kind", "converged", "status", "message", "newton_iterations",
                 "residual_norm", "wall_time_s", "compile_time_s", "rods", "stability"}
L, W, H, E = 0.508, 3.2024e-3, 12.377e-3, 71.7e9
F = 4.448


def scene_dict(force=(0.0, 0.0, -F), moment=None, base_rotation=(0.0, 0.0, 0.0), **solver):
    """Same structure as examples/scenes/cantilever_tip_force.toml."""
    loads = [{"kind": "force", "rod": "beam", "node": -1, "vector": list(force),
              "frame": "world", "profile": {"kind": "constant"}}]
    if moment is not None:
        loads = [{"kind": "moment", "rod": "beam", "node": -1, "vector": list(moment),
                  "frame": "world"}]
    base_rot = base_rotation if isinstance(base_rotation, dict) else list(base_rotation)
    return {
        "name": "cantilever_tip_force",
        "solver": {"kind": "static", "tolerance": 1e-10, "max_iterations": 50,
                   "load_steps": 10, **solver},
        "rods": [{"name": "beam", "material": "aluminum_7075",
                  "section": {"shape": "rectangle", "width": W, "height": H},
                  "elements": 16, "geometry": {"kind": "straight", "length": L},
                  "base": {"position": [0.0, 0.0, 0.0], "rotation": base_rot}}],
        "constraints": [{"kind": "clamp", "rod": "beam", "node": 0}],
        "loads": loads,
    }


def toml_text(d):
    """A TOML file for the scene_dict() layout (flat values, inline tables)."""
    def val(v):
        if isinstance(v, bool):
            return "true" if v else "false"
        if isinstance(v, str):
            return json.dumps(v)
        if isinstance(v, (int, float)):
            return repr(float(v)) if isinstance(v, float) else str(v)
        if isinstance(v, (list, tuple)):
            return "[" + ", ".join(val(x) for x in v) + "]"
        if isinstance(v, dict):
            return "{ " + ", ".join(f"{k} = {val(x)}" for k, x in v.items()) + " }"
        raise TypeError(v)

    lines = [f"name = {val(d['name'])}", "", "[solver]"]
    lines += [f"{k} = {val(v)}" for k, v in d["solver"].items()]
    for key in ("rods", "constraints", "loads"):
        for item in d[key]:
            lines += ["", f"[[{key}]]"] + [f"{k} = {val(v)}" for k, v in item.items()]
    return "\n".join(lines) + "\n"


def euler_bernoulli_tip(force):
    return force * L**3 / (3.0 * E * W * H**3 / 12.0)


@pytest.fixture(scope="module")
def result():
    return sj.run(scene_dict())


# ------------------------------------------------------------------------- sj.run inputs
def test_run_dict_scene_and_paths_agree(result, tmp_path):
    d = scene_dict()
    json_path = tmp_path / "scene.json"
    json_path.write_text(json.dumps(d))
    toml_path = tmp_path / "scene.toml"
    toml_path.write_text(toml_text(d))
    runs = [sj.run(sj.Scene.from_dict(d)), sj.run(json_path), sj.run(str(toml_path)),
            sj.run(sj.load_scene(toml_path))]
    for r in [result] + runs:
        assert r.converged
        assert r.positions("beam").shape == (17, 3)
        np.testing.assert_allclose(r.positions("beam"), result.positions("beam"),
                                   rtol=0, atol=1e-14)
        np.testing.assert_allclose(r.rotations("beam"), result.rotations("beam"),
                                   rtol=0, atol=1e-14)


def test_cantilever_tip_matches_beam_theory(result):
    p = result.positions("beam")
    np.testing.assert_allclose(p[0], 0.0, atol=1e-15)
    expected = euler_bernoulli_tip(F)
    assert abs(-p[-1, 2] - expected) / expected < 1.5e-3, (p[-1], expected)
    assert abs(p[-1, 1]) < 1e-12


def test_to_dict_has_exactly_the_contract_layout(result):
    d = result.to_dict()
    assert set(d) == CONTRACT_KEYS
    assert d["name"] == "cantilever_tip_force" and d["kind"] == "static"
    assert d["stability"] == {"negative_eigenvalues": 0, "stable": True}
    assert d["converged"] is True
    assert isinstance(d["newton_iterations"], int) and d["newton_iterations"] > 0
    for key in ("residual_norm", "wall_time_s", "compile_time_s"):
        assert isinstance(d[key], float) and np.isfinite(d[key]) and d[key] >= 0.0
    assert set(d["rods"]) == {"beam"}
    assert set(d["rods"]["beam"]) == {"positions", "rotations"}
    pos = np.asarray(d["rods"]["beam"]["positions"])
    rot = np.asarray(d["rods"]["beam"]["rotations"])
    assert pos.shape == (17, 3) and rot.shape == (17, 3, 3)
    np.testing.assert_array_equal(pos, result.positions("beam"))
    np.testing.assert_array_equal(rot, result.rotations("beam"))
    json.loads(json.dumps(d))            # plain Python types only


@pytest.mark.parametrize("rotation", [[0.0, 0.0, np.pi / 2],
                                      {"axis": [0.0, 0.0, 1.0], "angle_deg": 90.0}])
def test_rotations_are_orthonormal_with_local_axes_as_columns(result, rotation):
    """Base turned 90 deg about world z: local x (the rod axis) is world +y, so the first
    column of node 0 is +y and the rod lies along +y; local y is world -x."""
    r = sj.run(scene_dict(base_rotation=rotation))
    assert r.converged and r.compile_time_s == 0.0
    R, p = r.rotations("beam"), r.positions("beam")
    np.testing.assert_allclose(R[0][:, 0], [0.0, 1.0, 0.0], atol=1e-14)
    np.testing.assert_allclose(R[0][:, 1], [-1.0, 0.0, 0.0], atol=1e-14)
    np.testing.assert_allclose(R[0][:, 2], [0.0, 0.0, 1.0], atol=1e-14)
    np.testing.assert_allclose(np.einsum("nji,njk->nik", R, R), np.broadcast_to(np.eye(3), R.shape),
                               atol=1e-13)
    np.testing.assert_allclose(np.linalg.det(R), 1.0, atol=1e-13)
    assert p[-1, 1] == pytest.approx(L, rel=1e-3) and abs(p[-1, 0]) < 1e-12
    # every section's local x is the tangent of the deformed centreline
    tangents = np.diff(p, axis=0)
    tangents /= np.linalg.norm(tangents, axis=1, keepdims=True)
    mid = 0.5 * (R[:-1, :, 0] + R[1:, :, 0])
    np.testing.assert_allclose(np.einsum("ni,ni->n", tangents, mid), 1.0, atol=1e-5)


def test_same_structure_does_not_recompile(result):
    """Other load numbers, same structure: no compilation, and (small deflection) the tip
    deflection scales with the load."""
    r2 = sj.run(scene_dict(force=(0.0, 0.0, -2.0 * F)))
    r3 = sj.run(scene_dict(force=(0.0, 0.0, -0.5 * F)))
    assert r2.compile_time_s == 0.0 and r3.compile_time_s == 0.0
    assert r2.to_dict()["compile_time_s"] == 0.0
    z1, z2, z3 = (r.positions("beam")[-1, 2] for r in (result, r2, r3))
    assert z2 / z1 == pytest.approx(2.0, rel=2e-3)
    assert z3 / z1 == pytest.approx(0.5, rel=2e-3)


def test_nonconverged_result_is_reported_in_process(result):
    """A world tip moment that bends the 16-element rod by 60 rad (3.75 rad per element,
    past the pi an element's logarithm can represent) cannot be reached: the continuation
    stops short of the full load. Same structure: no compilation."""
    EIz = E * H * W**3 / 12.0
    r = sj.run(scene_dict(moment=(0.0, 0.0, 60.0 * EIz / L)))
    assert r.converged is False and r.compile_time_s == 0.0
    d = r.to_dict()
    assert d["converged"] is False
    assert CONTRACT_KEYS <= set(d)
    extras = {k: d[k] for k in set(d) - CONTRACT_KEYS}
    assert "load_level" in json.dumps(extras)     # where it failed
    assert np.isfinite(np.asarray(d["rods"]["beam"]["positions"])).all()


# ------------------------------------------------------------------------ command line
@pytest.fixture(scope="module")
def cli_env(tmp_path_factory):
    env = dict(os.environ)
    env.update(JAX_PLATFORMS="cpu",
               JAX_COMPILATION_CACHE_DIR=str(tmp_path_factory.mktemp("jax_cache")),
               JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS="0",
               JAX_PERSISTENT_CACHE_MIN_ENTRY_SIZE_BYTES="0")
    return env


def cli(env, *args):
    return subprocess.run([sys.executable, "-m", "simsoft_jax.cli", *map(str, args)],
                          capture_output=True, text=True, env=env, timeout=300, cwd=ROOT)


def test_cli_run_writes_json_and_npz(result, tmp_path, cli_env):
    scene = tmp_path / "cantilever.toml"
    scene.write_text(toml_text(scene_dict()))
    out_json, out_npz = tmp_path / "out.json", tmp_path / "out.npz"
    for out in (out_json, out_npz):
        proc = cli(cli_env, "run", scene, "-o", out, "--plot", out.with_suffix(".png"))
        assert proc.returncode == 0, proc.stderr
        assert out.exists() and out.with_suffix(".png").stat().st_size > 5000
    d = json.loads(out_json.read_text())
    assert set(d) == CONTRACT_KEYS
    assert d["converged"] is True and d["kind"] == "static"
    assert d["name"] == "cantilever_tip_force"
    pos = np.asarray(d["rods"]["beam"]["positions"])
    rot = np.asarray(d["rods"]["beam"]["rotations"])
    assert pos.shape == (17, 3) and rot.shape == (17, 3, 3)
    np.testing.assert_allclose(pos, result.positions("beam"), rtol=0, atol=1e-14)
    np.testing.assert_allclose(rot, result.rotations("beam"), rtol=0, atol=1e-14)

    with np.load(out_npz) as z:
        keys = set(z.files)
        assert {"converged", "newton_iterations", "beam/positions", "beam/rotations"} <= keys
        assert bool(z["converged"])
        assert int(z["newton_iterations"]) == d["newton_iterations"]
        np.testing.assert_array_equal(z["beam/positions"], pos)
        np.testing.assert_array_equal(z["beam/rotations"], rot)


def test_cli_validate(tmp_path, cli_env):
    good = tmp_path / "good.toml"
    good.write_text(toml_text(scene_dict()))
    proc = cli(cli_env, "validate", good)
    assert proc.returncode == 0, proc.stderr

    bad_dict = scene_dict()
    bad_dict["rods"][0]["section"]["width"] = -1.0
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(bad_dict))
    proc = cli(cli_env, "validate", bad)
    assert proc.returncode == 2
    assert "rods[0].section.width" in proc.stderr

    bad_dict = scene_dict()
    bad_dict["loads"][0]["node"] = 40          # the rod has 17 nodes
    bad.write_text(json.dumps(bad_dict))
    proc = cli(cli_env, "validate", bad)
    assert proc.returncode == 2
    assert "loads[0].node" in proc.stderr


@pytest.mark.slow
def test_cli_run_plots_and_animates_a_dynamic_scene(tmp_path, cli_env):
    """``run --plot --animate``: snapshots and a GIF of a short dynamic run; asking for an
    animation of a static scene is an input error (exit 2)."""
    d = scene_dict()
    d["solver"] = {"kind": "dynamic", "dt": 0.002, "t_end": 0.02}
    d["rods"][0]["elements"] = 2
    scene = tmp_path / "dyn.json"
    scene.write_text(json.dumps(d))
    png, gif = tmp_path / "dyn.png", tmp_path / "dyn.gif"
    proc = cli(cli_env, "run", scene, "--plot", png, "--animate", gif)
    assert proc.returncode == 0, proc.stderr
    assert png.stat().st_size > 5000
    assert gif.read_bytes()[:6] in (b"GIF87a", b"GIF89a")
    static = tmp_path / "static.json"
    static.write_text(json.dumps(scene_dict()))
    proc = cli(cli_env, "run", static, "--animate", gif)
    assert proc.returncode == 2 and "--animate: needs a dynamic scene" in proc.stderr


def test_cli_nonconverged_writes_file_and_fails(tmp_path, cli_env):
    """One Newton iteration per step, one load step and a tip moment of ~8 rad: the solve
    fails; the result file is still written with "converged": false; exit code != 0."""
    EIz = E * H * W**3 / 12.0
    d = scene_dict(moment=(0.0, 0.0, 8.0 * EIz / L), max_iterations=1, load_steps=1)
    scene = tmp_path / "hard.json"
    scene.write_text(json.dumps(d))
    out = tmp_path / "hard_out.json"
    proc = cli(cli_env, "run", scene, "-o", out)
    assert proc.returncode != 0
    r = json.loads(out.read_text())
    assert r["converged"] is False
    assert CONTRACT_KEYS <= set(r)
    assert np.asarray(r["rods"]["beam"]["positions"]).shape == (17, 3)


# ------------------------------------------------------------------------ example scenes
# dynamic example scenes are run in test_dynamics_scenes.py
STATIC_EXAMPLES = sorted(p for p in EXAMPLES.glob("*") if p.suffix in (".toml", ".json")
                         and sj.load_scene(p).solver.kind == "static")


@pytest.mark.parametrize("path", STATIC_EXAMPLES, ids=[p.name for p in STATIC_EXAMPLES])
def test_example_static_scenes_run_and_converge(path):
    scene = sj.load_scene(path)
    r = sj.run(scene)
    assert r.converged, path.name
    for rod in scene.rods:
        p = r.positions(rod.name)
        assert p.shape == (rod.elements + 1, 3) and np.isfinite(p).all()
    if path.name == "cantilever_tip_force.toml":
        # the example is this file's cantilever: the same tip (beam theory checked above)
        expected = euler_bernoulli_tip(F)
        assert abs(-r.positions("beam")[-1, 2] - expected) / expected < 1.5e-3


def test_cli_help_lists_every_command(capsys):
    from simsoft_jax.cli import main
    with pytest.raises(SystemExit) as exit_info:
        main(["--help"])
    assert exit_info.value.code == 0
    printed = capsys.readouterr().out
    for command in ("run", "validate", "princeton", "calibrate", "bench"):
        assert f"    {command}" in printed


def test_cli_bench_passes_its_options_to_the_benchmark_suite(capsys):
    """``simsoft-jax bench --help`` is the help of benchmarks/run_all.py (nothing runs)."""
    from simsoft_jax.cli import main
    with pytest.raises(SystemExit) as exit_info:
        main(["bench", "--help"])
    assert exit_info.value.code == 0
    printed = capsys.readouterr().out
    assert "--only" in printed and "--quick" in printed and "throughput" in printed
