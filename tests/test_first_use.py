"""What a new user meets first: ``simsoft-jax validate`` never imports JAX (it only reads
the scene), float64 holds whatever the import order (the package imports JAX lazily),
``sj.run``, ``sj.solve_static`` and ``sj.simulate`` say on stderr when they compile a
program for a new scene structure (and not when they load one, nor with
``SIMSOFT_JAX_QUIET=1``), the command line's help texts are
plain and complete, and every notebook cell has an id (nbformat 4.5).

Each check runs in a fresh Python process: what a process has imported is the point."""
from __future__ import annotations

import json
import os
import re
import subprocess
import sys

import pytest

from conftest import NOTEBOOKS_DIR, REPO_ROOT, SCENES_DIR

SCENE = SCENES_DIR / "cantilever_tip_force.toml"


def python(code: str, env=None, timeout=300) -> subprocess.CompletedProcess:
    """Run ``code`` in a fresh interpreter in the repository root."""
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          cwd=REPO_ROOT, env=env or dict(os.environ), timeout=timeout)


def test_validate_reads_the_scene_without_importing_jax():
    proc = python(
        "import sys\n"
        "from simsoft_jax.cli import main\n"
        f"code = main(['validate', {str(SCENE)!r}])\n"
        "print('exit', code, 'jax imported:', 'jax' in sys.modules)\n")
    assert proc.returncode == 0, proc.stderr
    assert "valid static scene; rods: beam (16 elements)" in proc.stdout
    assert "exit 0 jax imported: False" in proc.stdout


def test_importing_the_package_does_not_import_jax_until_a_solver_is_used():
    proc = python(
        "import sys, simsoft_jax as sj\n"
        f"scene = sj.load_scene({str(SCENE)!r})\n"
        "print('after load_scene:', 'jax' in sys.modules)\n"
        "sj.StaticSettings\n"
        "print('after StaticSettings:', 'jax' in sys.modules)\n")
    assert proc.returncode == 0, proc.stderr
    assert "after load_scene: False" in proc.stdout
    assert "after StaticSettings: True" in proc.stdout


@pytest.mark.parametrize("imports", [
    "import jax\nfrom simsoft_jax.solvers.statics import solve_static",
    "from simsoft_jax.solvers.statics import solve_static\nimport jax",
    "import simsoft_jax as sj\nsj.solve_static\nimport jax",
    "import jax, jax.numpy as jnp\njnp.zeros(1)\nimport simsoft_jax.math.lie",
])
def test_float64_whatever_the_import_order(imports):
    """The solvers need float64: ``jax_enable_x64`` is on and new arrays are float64
    however the package and JAX are imported (also against ``JAX_ENABLE_X64=0``)."""
    env = dict(os.environ, JAX_ENABLE_X64="0")
    proc = python(imports + "\nimport jax, jax.numpy as jnp\n"
                  "print(jax.config.jax_enable_x64, jnp.asarray(1.0).dtype, "
                  "(jnp.ones(3) / 3).dtype)\n", env=env)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.split() == ["True", "float64", "float64"]


def test_sj_run_says_when_it_compiles(tmp_path):
    """A fresh cache: one line announces the compile of the static solver and its time;
    a second run in the same process, and a later process (which loads the stored
    program), say nothing; ``SIMSOFT_JAX_QUIET=1`` silences a compile."""
    env = dict(os.environ, SIMSOFT_JAX_CACHE_DIR=str(tmp_path / "cache"),
               JAX_COMPILATION_CACHE_DIR=str(tmp_path / "cache"))
    env.pop("SIMSOFT_JAX_CACHE", None)
    env.pop("SIMSOFT_JAX_QUIET", None)
    code = ("import simsoft_jax as sj\n"
            f"scene = sj.load_scene({str(SCENE)!r})\n"
            "for _ in range(2):\n"
            "    assert sj.run(scene).converged\n")
    first = python(code, env)
    assert first.returncode == 0, first.stderr
    lines = [line for line in first.stderr.splitlines() if "compiling" in line]
    assert len(lines) == 1, first.stderr
    assert re.fullmatch(r"compiling the static solver for this scene structure "
                        r"\(kept for next time\)\.\.\. \d+\.\d s", lines[0])
    later = python(code, env)
    assert later.returncode == 0, later.stderr
    assert "compiling" not in later.stderr
    quiet = python(code, dict(env, SIMSOFT_JAX_QUIET="1", SIMSOFT_JAX_CACHE="0"))
    assert quiet.returncode == 0, quiet.stderr
    assert "compiling" not in quiet.stderr


def test_solve_static_and_simulate_say_when_they_compile(tmp_path):
    """The Python API's own solvers announce their compile as ``sj.run`` does: one line
    each for the static solver, the dynamic one and a rollout's gradient (a
    differentiable rollout's forward pass is the dynamic solver already compiled) of a
    new structure, with its time, at the first call only; ``SIMSOFT_JAX_QUIET=1``
    silences it."""
    env = dict(os.environ, SIMSOFT_JAX_CACHE_DIR=str(tmp_path / "cache"),
               JAX_COMPILATION_CACHE_DIR=str(tmp_path / "cache"))
    env.pop("SIMSOFT_JAX_CACHE", None)
    env.pop("SIMSOFT_JAX_QUIET", None)
    static = ("import simsoft_jax as sj\n"
              f"model = sj.build_model(sj.load_scene({str(SCENE)!r}))\n"
              "for _ in range(2):\n"
              "    assert sj.solve_static(model).converged\n")
    dynamic = ("scene = sj.Scene.from_dict({'name': 'fall', 'solver': {'kind': 'dynamic',\n"
               "    'dt': 0.01, 't_end': 0.02}, 'gravity': {'vector': [0, 0, -9.81]},\n"
               "    'rods': [{'name': 'rod', 'elements': 2, 'geometry': {'kind': 'straight',\n"
               "    'length': 1.0}, 'stiffness': {'EA': 1e4, 'GAy': 1e4, 'GAz': 1e4,\n"
               "    'GJ': 1.0, 'EIy': 1.0, 'EIz': 1.0}, 'inertia': {'rhoA': 1.0,\n"
               "    'rhoJ': 1e-3, 'rhoIy': 1e-3, 'rhoIz': 1e-3}}],\n"
               "    'constraints': [{'kind': 'clamp', 'rod': 'rod', 'node': 0}]})\n"
               "settings = sj.DynamicSettings(dt=0.01, steps=2)\n"
               "for _ in range(2):\n"
               "    assert sj.simulate(sj.build_model(scene), settings).converged\n"
               "import jax\n"
               "model = sj.build_model(scene)\n"
               "def tip(k):\n"
               "    return sj.simulate(model.replace(stiffness=model.stiffness * k),\n"
               "                       settings, differentiable=True).p[-1, -1, 2]\n"
               "for _ in range(2):\n"
               "    assert abs(float(jax.grad(tip)(1.0))) > 0.0\n")
    first = python(static + dynamic, env)
    assert first.returncode == 0, first.stderr
    lines = [line for line in first.stderr.splitlines() if "compiling" in line]
    assert len(lines) == 3, first.stderr
    for line, what in zip(lines, ("static solver", "dynamic solver",
                                  "rollout gradient program")):
        assert re.fullmatch(rf"compiling the {what} for this scene structure "
                            r"\(kept for next time\)\.\.\. \d+\.\d s", line), line
    quiet = python(static, dict(env, SIMSOFT_JAX_QUIET="1", SIMSOFT_JAX_CACHE="0"))
    assert quiet.returncode == 0, quiet.stderr
    assert "compiling" not in quiet.stderr


def cli_help(*args) -> str:
    proc = subprocess.run([sys.executable, "-m", "simsoft_jax.cli", *args, "--help"],
                          capture_output=True, text=True, cwd=REPO_ROOT, timeout=120)
    assert proc.returncode == 0, proc.stderr
    return proc.stdout


def test_help_texts_are_plain_and_complete():
    top = cli_help()
    assert "``" not in top and ":mod:" not in top
    assert cli_help("bench").startswith("usage: simsoft-jax bench")
    princeton = cli_help("princeton")
    assert re.search(r"--elements ELEMENTS\s+finite elements", princeton)
    for command in ("run", "validate", "princeton", "calibrate", "predict"):   # after it too
        assert "--no-cache" in cli_help(command)
        assert "--no-cache" in cli_help(command, "--no-cache")


@pytest.mark.parametrize("notebook", sorted(NOTEBOOKS_DIR.glob("*.ipynb")), ids=lambda p: p.stem)
def test_every_notebook_cell_has_an_id(notebook):
    """nbformat >= 4.5 requires a unique ``id`` per cell (a missing one is an error in
    future nbformat versions)."""
    nb = json.loads(notebook.read_text(encoding="utf-8"))
    assert (nb["nbformat"], nb["nbformat_minor"]) >= (4, 5)
    ids = [cell.get("id") for cell in nb["cells"]]
    assert all(isinstance(i, str) and re.fullmatch(r"[a-zA-Z0-9-_]{1,64}", i) for i in ids)
    assert len(set(ids)) == len(ids)


def first_steps_blocks(language: str) -> list[str]:
    """The ``language`` code blocks of the README's "First steps" section."""
    readme = (REPO_ROOT / "README.md").read_text(encoding="utf-8")
    section = readme.split("## First steps", 1)[1].split("\n## ", 1)[0]
    return re.findall(rf"```{language}\n(.*?)```", section, re.S)


@pytest.mark.slow
def test_readme_first_steps_run(tmp_path):
    """The README's first steps as a new user types them: the commands (with the output
    folder moved to a temporary one) exit 0 and write their files; the Python blocks run
    in one process and give a converged static tip below the clamp, a dynamic trajectory
    of 301 states, and a gradient of the shape of the stiffness array that is finite."""
    commands = [line for block in first_steps_blocks("bash") for line in block.splitlines()
                if line.startswith("simsoft-jax")]
    assert len(commands) == 3
    for line in commands:
        args = line.split("#")[0].replace("out/", f"{tmp_path}/").split()[1:]
        proc = subprocess.run([sys.executable, "-m", "simsoft_jax.cli", *args],
                              capture_output=True, text=True, cwd=REPO_ROOT, timeout=900)
        assert proc.returncode == 0, (line, proc.stderr)
    for name in ("cantilever.json", "cantilever.png", "helical.npz", "helical.gif"):
        assert (tmp_path / name).stat().st_size > 1000, name
    code = "\n".join(first_steps_blocks("python")) + (
        "\nimport numpy as np\n"
        "assert result.converged and result.positions('beam')[-1, 2] < 0\n"
        "assert traj.converged and traj.time.shape == (301,)\n"
        "assert dz_dK.shape == model.stiffness.shape and np.isfinite(dz_dK).all()\n"
        "print('FIRST STEPS OK')\n")
    proc = python(code, timeout=900)
    assert proc.returncode == 0, proc.stderr
    assert "FIRST STEPS OK" in proc.stdout
