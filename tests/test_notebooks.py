"""Every notebook in notebooks/ executes top to bottom in its fast mode, and is stored
with its outputs stripped.

Each notebook runs in its own Python process (so its namespace and JAX state are fresh):
the code cells of the .ipynb JSON are executed in order in one namespace, with the
working directory set to notebooks/ (as Jupyter does), ``SIMSOFT_FAST=1`` (small meshes,
short runs), ``MPLBACKEND=Agg`` and ``SIMSOFT_OUT`` pointing into the test's tmp folder.
Notebooks assert their own physics (analytic references inside them), so a failing
check fails the test. Notebooks are collected with a glob: new ones are covered too.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from conftest import NOTEBOOKS_DIR, REPO_ROOT

ROOT = REPO_ROOT
NOTEBOOKS = sorted(NOTEBOOKS_DIR.glob("*.ipynb"))

RUNNER = r"""
import json, sys
notebook = json.load(open(sys.argv[1], encoding="utf-8"))
namespace = {"__name__": "__main__"}
for index, cell in enumerate(notebook["cells"]):
    if cell["cell_type"] == "code":
        source = "".join(cell["source"])
        exec(compile(source, f"{sys.argv[1]} [cell {index}]", "exec"), namespace)
print("NOTEBOOK COMPLETED")
"""


def test_notebooks_exist():
    names = [p.stem for p in NOTEBOOKS]
    for name in ("01_quickstart", "02_validation", "03_dynamics"):
        assert name in names


@pytest.mark.slow
@pytest.mark.parametrize("path", NOTEBOOKS, ids=[p.stem for p in NOTEBOOKS])
def test_notebook_runs_in_fast_mode(path, tmp_path, tmp_path_factory):
    """The code cells run in order in one namespace without error (the notebooks check
    their own numbers with asserts against references they compute)."""
    # the folder of lane 0 of tests/test_examples.py (that module's runs are over by now):
    # the notebooks reuse its compiled programs (pure bending, helical, the catheters and
    # the two control examples that notebook 09 runs whole)
    cache = tmp_path_factory.getbasetemp() / "jax_compilation_cache"
    cache.mkdir(exist_ok=True)
    env = dict(os.environ, SIMSOFT_FAST="1", MPLBACKEND="Agg", SIMSOFT_OUT=str(tmp_path),
               JAX_COMPILATION_CACHE_DIR=str(cache),
               JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS="0")
    proc = subprocess.run([sys.executable, "-c", RUNNER, str(path)], cwd=path.parent,
                          env=env, capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, f"{path.name} failed:\n{proc.stdout}\n{proc.stderr}"
    assert "NOTEBOOK COMPLETED" in proc.stdout


def _assert_stripped(notebook: dict, name: str):
    assert notebook["nbformat"] == 4, name
    for index, cell in enumerate(notebook["cells"]):
        if cell["cell_type"] == "code":
            assert cell.get("outputs") == [], f"{name} cell {index}: outputs not stripped"
            assert cell.get("execution_count") is None, f"{name} cell {index}: execution count"


@pytest.mark.parametrize("path", NOTEBOOKS, ids=[p.stem for p in NOTEBOOKS])
def test_notebook_outputs_are_stripped(path):
    """The file as it stands and, when the repository has it committed, the committed
    version carry no outputs and no execution counts."""
    _assert_stripped(json.loads(path.read_text(encoding="utf-8")), path.name)
    relative = path.relative_to(ROOT).as_posix()
    try:
        shown = subprocess.run(["git", "show", f"HEAD:{relative}"], cwd=ROOT,
                               capture_output=True, text=True, timeout=60)
    except OSError:      # no git on this machine
        return
    if shown.returncode == 0:
        _assert_stripped(json.loads(shown.stdout), f"HEAD:{relative}")
