"""Instant restarts (issue 16, item 5): the command line and ``sj.run`` keep compiled
solver programs in the cache folder (loadable executables, beside JAX's persistent
compilation cache), so a second run of a scene structure in a new process compiles
nothing; ``--cache-dir`` moves the cache, ``--no-cache`` and
``SIMSOFT_JAX_CACHE=0`` turn it off. The tests never touch the user's home: conftest
points ``SIMSOFT_JAX_CACHE_DIR`` at a folder of the session, and the subprocess test
uses its own folder."""
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

from conftest import arc
from simsoft_jax import cli
from simsoft_jax.solvers import compile_cache

# counts JAX's persistent-cache events around one command line run
_COUNTING_RUN = """
import collections, json, sys, jax
seen = collections.Counter()
jax.monitoring.register_event_listener(lambda event, **kw: seen.update([event]))
jax.monitoring.register_event_duration_secs_listener(lambda event, d, **kw: seen.update([event]))
from simsoft_jax import cli
code = cli.main(sys.argv[1:])
print(json.dumps({"code": code, "misses": seen["/jax/compilation_cache/cache_misses"],
                  "compiled": seen["/jax/core/compile/backend_compile_duration"],
                  "loaded": seen["/simsoft_jax/compile_cache/program_loaded"]}))
"""


def cantilever(moment):
    """A clamped rod under a tip moment about local y: exact pure bending, kappa = moment
    (EI = 1), for any element count."""
    return {"name": "tip", "solver": {"kind": "static"},
            "rods": [{"name": "rod", "elements": 2, "geometry": {"kind": "straight",
                                                                 "length": 1.0},
                      "stiffness": {"EA": 1e5, "GAy": 1e5, "GAz": 1e5, "GJ": 1.0,
                                    "EIy": 1.0, "EIz": 1.0},
                      "inertia": {"rhoA": 1.0, "rhoJ": 1.0, "rhoIy": 1.0, "rhoIz": 1.0}}],
            "constraints": [{"kind": "clamp", "rod": "rod", "node": 0}],
            "loads": [{"kind": "moment", "rod": "rod", "node": -1, "frame": "local",
                       "vector": [0.0, moment, 0.0]}]}


def counted_run(args):
    out = subprocess.run([sys.executable, "-c", _COUNTING_RUN, *args], capture_output=True,
                         text=True, timeout=600, env=os.environ)
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout.splitlines()[-1]), out.stdout


def test_second_process_reads_every_program_from_the_cache(tmp_path):
    """A new process running the same structure with another load compiles nothing: the
    solver (with its stability check) is loaded, compiled, from the folder given by
    ``--cache-dir`` (before or after ``run``); both processes bend the rod exactly."""
    cache = tmp_path / "xla"
    for k, moment in enumerate((0.3, 0.6)):
        (tmp_path / f"s{k}.json").write_text(json.dumps(cantilever(moment)))
    cold, _ = counted_run(["--cache-dir", str(cache), "run", str(tmp_path / "s0.json"),
                           "-o", str(tmp_path / "r0.json")])
    assert cold["code"] == 0 and cold["compiled"] >= 1
    assert [p.name.split("-")[0] for p in (cache / "programs").iterdir()] == ["static"]
    warm, text = counted_run(["run", str(tmp_path / "s1.json"), "--cache-dir", str(cache),
                              "--no-stability", "-o", str(tmp_path / "r1.json")])
    assert warm["code"] == 0 and warm["misses"] == 0 and warm["compiled"] == 0, (warm, text)
    assert warm["loaded"] == 1, warm
    assert "compile " in text and "solve " in text
    for k, kappa in enumerate((0.3, 0.6)):
        rod = json.loads((tmp_path / f"r{k}.json").read_text())["rods"]["rod"]
        np.testing.assert_allclose(rod["positions"], arc(kappa, np.linspace(0, 1, 3))[0],
                                   rtol=0, atol=1e-10)


# the derivative of the cantilever's tip height with respect to a factor on its stiffness,
# in a process of its own, with JAX's persistent-cache events counted
_COUNTING_GRADIENT = """
import collections, json, sys, jax
import simsoft_jax as sj
seen = collections.Counter()
jax.monitoring.register_event_listener(lambda event, **kw: seen.update([event]))
model = sj.build_model(sj.Scene.from_dict(json.loads(sys.argv[1])))
tip = lambda s: sj.solve_static(model.replace(stiffness=s * model.stiffness)).p[-1, 2]
slope = float(jax.grad(tip)(1.0))
print(json.dumps({"slope": slope, "hits": seen["/jax/compilation_cache/cache_hits"],
                  "misses": seen["/jax/compilation_cache/cache_misses"]}))
"""


def test_second_process_reads_the_gradient_programs_from_the_cache(tmp_path):
    """``jax.grad`` around ``sj.solve_static``, outside any ``jit``, compiles several
    programs (forward, backward, small ones of JAX's own), some in well under a second:
    a second process finds every one of them in the cache (no miss), even in a folder
    given to JAX itself and without JAX's compile-time threshold set. Both give the
    exact pure-bending slope: tip height ``-(1 - cos k) / k`` with ``k = M / (s EI)``,
    so ``d/ds = (k sin k + cos k - 1) / k`` at ``s = 1``."""
    env = dict(os.environ, SIMSOFT_JAX_CACHE_DIR=str(tmp_path / "xla"),
               JAX_COMPILATION_CACHE_DIR=str(tmp_path / "xla"))
    for name in ("SIMSOFT_JAX_CACHE", "JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS"):
        env.pop(name, None)
    counts = []
    for _ in range(2):
        out = subprocess.run([sys.executable, "-c", _COUNTING_GRADIENT,
                              json.dumps(cantilever(0.6))], capture_output=True, text=True,
                             timeout=600, env=env)
        assert out.returncode == 0, out.stderr
        counts.append(json.loads(out.stdout.splitlines()[-1]))
    k = 0.6
    exact = (k * np.sin(k) + np.cos(k) - 1.0) / k
    for c in counts:
        np.testing.assert_allclose(c["slope"], exact, rtol=1e-8)
    assert counts[0]["misses"] >= 3, counts
    # the second process compiles nothing: JAX's programs are read from the cache (the
    # solve's own program, which simsoft_jax stores itself, is not counted there)
    assert counts[1]["misses"] == 0 and counts[1]["hits"] >= counts[0]["misses"] - 1, counts


# the derivative of a falling rod's tip height after 5 steps with respect to a factor on
# its stiffness (reverse mode, the rollout's adjoint) and its central difference, in a
# process of its own, with the compiled and the loaded programs counted by name
_COUNTING_ROLLOUT_GRADIENT = """
import collections, json, sys, jax
import simsoft_jax as sj
from simsoft_jax.solvers import compile_cache
compiled, loaded = collections.Counter(), collections.Counter()
def listen(event, duration, **kw):
    if event == "/jax/core/compile/backend_compile_duration":
        compiled.update([kw.get("fun_name", "?")])
    elif event == compile_cache.LOADED_EVENT:
        loaded.update([kw.get("fun_name", "?")])
jax.monitoring.register_event_duration_secs_listener(listen)
scene = sj.Scene.from_dict(json.loads(sys.argv[1]))
model = sj.build_model(scene)
settings = sj.DynamicSettings(dt=0.01, steps=5)
def tip(k, differentiable=True):
    return sj.simulate(model.replace(stiffness=model.stiffness * k), settings,
                       differentiable=differentiable).p[-1, -1, 2]
slope = float(jax.grad(tip)(1.0))
h = 1e-4
fd = (float(tip(1.0 + h, False)) - float(tip(1.0 - h, False))) / (2 * h)
print(json.dumps({"slope": slope, "fd": fd, "compiled": dict(compiled),
                  "loaded": dict(loaded)}))
"""


def test_second_process_loads_the_rollout_gradient_program(tmp_path):
    """``jax.grad`` through a differentiable rollout, outside any ``jit``: the first
    process compiles the dynamic solver and the gradient's backward program and keeps
    both in the cache folder; a second process loads both and compiles neither. Both
    give the central-difference slope."""
    env = dict(os.environ, SIMSOFT_JAX_CACHE_DIR=str(tmp_path / "xla"),
               JAX_COMPILATION_CACHE_DIR=str(tmp_path / "xla"))
    env.pop("SIMSOFT_JAX_CACHE", None)
    scene = dict(cantilever(0.0), solver={"kind": "dynamic", "dt": 0.01, "t_end": 0.05},
                 loads=[], gravity={"vector": [0.0, 0.0, -9.81]})
    scene["rods"][0]["stiffness"] = {"EA": 1e4, "GAy": 1e4, "GAz": 1e4, "GJ": 0.5,
                                     "EIy": 0.5, "EIz": 0.5}
    counts = []
    for _ in range(2):
        out = subprocess.run([sys.executable, "-c", _COUNTING_ROLLOUT_GRADIENT,
                              json.dumps(scene)], capture_output=True, text=True,
                             timeout=600, env=env)
        assert out.returncode == 0, out.stderr
        counts.append(json.loads(out.stdout.splitlines()[-1]))
    for c in counts:
        assert abs(c["slope"]) > 1e-6, c
        np.testing.assert_allclose(c["slope"], c["fd"], rtol=1e-5)
    first, second = counts
    assert first["compiled"].get("jit(rollout_gradient)") == 1, first
    stored = {p.name.split("-")[0] for p in (tmp_path / "xla" / "programs").iterdir()}
    assert stored == {"rollout", "rollout_gradient"}, stored
    assert not any("gradient" in name or "chunk" in name for name in second["compiled"]), second
    assert second["loaded"] == {"jit(rollout)": 1, "jit(rollout gradient)": 1}, second


def test_cache_folder_and_switch(monkeypatch, tmp_path):
    """Default folder: $SIMSOFT_JAX_CACHE_DIR, else $XDG_CACHE_HOME/simsoft_jax/xla, else
    ~/.cache/simsoft_jax/xla; SIMSOFT_JAX_CACHE=0 (or --no-cache) leaves JAX alone."""
    monkeypatch.setenv("SIMSOFT_JAX_CACHE_DIR", str(tmp_path / "mine"))
    assert compile_cache.default_dir() == tmp_path / "mine"
    monkeypatch.delenv("SIMSOFT_JAX_CACHE_DIR")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    assert compile_cache.default_dir() == tmp_path / "simsoft_jax" / "xla"
    monkeypatch.delenv("XDG_CACHE_HOME")
    assert compile_cache.default_dir() == Path.home() / ".cache" / "simsoft_jax" / "xla"
    before = compile_cache.jax.config.jax_compilation_cache_dir
    for value in ("0", "off", "False"):
        monkeypatch.setenv("SIMSOFT_JAX_CACHE", value)
        assert compile_cache.switched_off() and compile_cache.enable() is None
    monkeypatch.setenv("SIMSOFT_JAX_CACHE", "1")
    assert not compile_cache.switched_off()
    scene = tmp_path / "s.json"
    scene.write_text(json.dumps(cantilever(0.3)))
    assert cli.main(["--no-cache", "validate", str(scene)]) == 0
    assert os.environ["SIMSOFT_JAX_CACHE"] == "0" and compile_cache.enable() is None
    assert compile_cache.jax.config.jax_compilation_cache_dir == before
