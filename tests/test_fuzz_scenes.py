"""Seeded fuzz test of the scene pipeline (issue 17), slow lane.

About 200 scenes mutated from examples/scenes (a key dropped, or a value replaced by 0, -1,
1e300, 1e-300, NaN, infinity, a wrong type), with small element counts and a few time
steps so each runs fast. Every scene must end in one of two ways:

* rejected by the validator with one ValueError whose message starts with a key path
  (``rods[0].section.width: ...``, ``solver: ...``), or
* accepted by it (``run`` then never refuses its input: the validator runs every input
  check) and solved to a Result with a status code, within the solver's work bounds (static: at
  most ``max_attempts`` load steps, each at most ``max_iterations`` Newton passes plus
  its backtracks; dynamic: at most ``2**max_halvings`` sub-steps per step, each at most
  ``max_iterations`` iterations); its JSON file is strict (no NaN / Infinity tokens) and
  its NPZ file loads.

Any other exception, work past the bounds or a non-strict file fails the test.
"""
import json
import random
import re
import sys
import warnings

import numpy as np
import pytest

import simsoft_jax as sj
from conftest import SCENES_DIR
from simsoft_jax.solvers.dynamics import DynamicSettings
from simsoft_jax.solvers.statics import settings_from_scene
from simsoft_jax.solvers.status import Status

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

SEED, COUNT = 17, 200
KEY_PATH = r"^[A-Za-z_]\w*(\[\d+\])?(\.\w+(\[\d+\])?)*: "
EXTREMES = [0, -1, 1e300, 1e-300, float("nan"), float("inf"), "text", True, [], {}, None]
CODES = {s.code for s in Status if s != Status.NOT_RUN}


def _base_scenes():
    scenes = []
    for path in sorted(SCENES_DIR.glob("*")):
        if path.suffix == ".json":
            d = json.loads(path.read_text())
        elif path.suffix == ".toml":
            d = tomllib.loads(path.read_text())
        else:
            continue
        scenes.append((path.name, _small(d)))
    return scenes


def _small(d):
    """Few elements (6 per rod, 3 per segment; arcs and helices cut to fit the 90-degree
    element limit) and at most 4 time steps."""
    for rod in d.get("rods", []):
        if "segments" in rod:
            rod.pop("elements", None)
            for seg in rod["segments"]:
                seg["elements"] = 3
        else:
            rod["elements"] = 6
        geometry = rod.get("geometry", {})
        if geometry.get("kind") == "helix":
            geometry["turns"] = min(geometry["turns"], 1.0)
        rod.pop("initial", None)  # restarts read other files
    solver = d["solver"]
    if solver["kind"] == "dynamic":
        solver["t_end"] = 4 * solver["dt"]
        solver["save_every"] = 1
    return d


def _leaves(value, path=()):
    """Every (path, value) below ``value``: dict keys and list items."""
    out = []
    if isinstance(value, dict):
        for key, item in value.items():
            out.append((path + (key,), item))
            out += _leaves(item, path + (key,))
    elif isinstance(value, list):
        for i, item in enumerate(value):
            out.append((path + (i,), item))
            out += _leaves(item, path + (i,))
    return out


def _mutate(d, rng):
    """One change: half the time a number scaled to an extreme (x 0, -1, 1e300, 1e-300,
    1e6, 1e-6), else a key dropped or a value replaced by one of EXTREMES."""
    d = json.loads(json.dumps(d))
    leaves = _leaves(d)
    numbers = [(p, v) for p, v in leaves if isinstance(v, (int, float))
               and not isinstance(v, bool)]
    if rng.random() < 0.5:
        path, value = rng.choice(numbers)
        factor = rng.choice([0, -1, 1e300, 1e-300, 1e6, 1e-6])
        new = value * factor if value else factor
        new = type(value)(new) if isinstance(value, int) and abs(new) < 1e15 else new
    else:
        path, _ = rng.choice(leaves)
        new = "drop" if rng.random() < 0.3 else rng.choice(EXTREMES)
    parent = d
    for key in path[:-1]:
        parent = parent[key]
    if isinstance(new, str) and new == "drop":
        del parent[path[-1]]
    else:
        parent[path[-1]] = new
    return d, f"{'.'.join(map(str, path))} -> {new!r}"


def _cases():
    rng = random.Random(SEED)
    bases = _base_scenes()
    return [(name, *_mutate(d, rng)) for name, d in (rng.choice(bases) for _ in range(COUNT))]


def _within_work_bounds(scene, result):
    """The solve stayed inside the loop bounds its settings set (no run-away loop)."""
    raw, solver = result.raw, scene.solver
    if result.kind == "static":
        settings = settings_from_scene(solver)
        attempts = int(raw.load_steps) + int(raw.step_failures)
        passes = settings.max_iterations + 1 + settings.line_search_steps
        return (attempts <= settings.max_attempts
                and result.newton_iterations <= attempts * passes)
    halvings = DynamicSettings.max_halvings
    substeps = np.asarray(raw.substeps)
    attempts = substeps + halvings + 1    # accepted sub-steps plus the failed tries
    return (np.all(substeps <= 2 ** halvings) and np.all(
        np.asarray(raw.iterations) <= attempts * (int(solver.max_iterations) + 1)))


def _strict(text):
    def reject(token):
        raise AssertionError(f"non-strict JSON token {token}")
    return json.loads(text, parse_constant=reject)


@pytest.mark.slow
def test_fuzzed_scenes_are_rejected_by_key_or_end_with_a_status(tmp_path):
    outcomes = {"rejected": 0, "ran": 0}
    for k, (name, scene, change) in enumerate(_cases()):
        label = f"case {k} ({name}: {change})"
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                parsed = sj.Scene.from_dict(scene, base_dir=SCENES_DIR)
        except ValueError as err:
            assert re.match(KEY_PATH, str(err)), f"{label}: message without key path: {err}"
            outcomes["rejected"] += 1
            continue
        try:
            result = sj.run(parsed)
        except ValueError as err:   # validate accepted it: run must not refuse its input
            pytest.fail(f"{label}: read as valid, refused by run: {err}")
        assert _within_work_bounds(parsed, result), f"{label}: past the solver's work bounds"
        assert result.status in CODES and result.message, label
        assert result.converged == (result.status == "converged"), label
        text = result.save(tmp_path / "out.json").read_text()
        data = _strict(text)
        assert data["status"] == result.status, label
        with np.load(result.save(tmp_path / "out.npz")) as z:
            assert str(z["status"]) == result.status, label
        outcomes["ran"] += 1
    # the mix exercises both ends
    assert outcomes["rejected"] >= 40 and outcomes["ran"] >= 40, outcomes
