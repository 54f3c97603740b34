"""Instant restarts (issue 16, item 5): the command line and ``sj.run`` keep compiled
programs in JAX's persistent compilation cache, so a second run of a scene structure in
a new process compiles nothing; ``--cache-dir`` moves the cache, ``--no-cache`` and
``SIMSOFT_JAX_CACHE=0`` turn it off. The tests never touch the user's home: conftest
points ``SIMSOFT_JAX_CACHE_DIR`` at a folder of the session, and the subprocess test
uses its own folder."""
import importlib.util
import json
import os
import subprocess
import sys
from pathlib import Path

from simsoft_jax import cli, compile_cache

# counts JAX's persistent-cache events around one command line run
_COUNTING_RUN = """
import collections, json, sys, jax
seen = collections.Counter()
jax.monitoring.register_event_listener(lambda event, **kw: seen.update([event]))
from simsoft_jax import cli
code = cli.main(sys.argv[1:])
print(json.dumps({"code": code, "misses": seen["/jax/compilation_cache/cache_misses"],
                  "hits": seen["/jax/compilation_cache/cache_hits"]}))
"""


def cantilever(force):
    return {"name": "tip", "solver": {"kind": "static"},
            "rods": [{"name": "rod", "elements": 2, "geometry": {"kind": "straight",
                                                                 "length": 1.0},
                      "stiffness": {"EA": 1e5, "GAy": 1e5, "GAz": 1e5, "GJ": 1.0,
                                    "EIy": 1.0, "EIz": 1.0},
                      "inertia": {"rhoA": 1.0, "rhoJ": 1.0, "rhoIy": 1.0, "rhoIz": 1.0}}],
            "constraints": [{"kind": "clamp", "rod": "rod", "node": 0}],
            "loads": [{"kind": "force", "rod": "rod", "node": -1, "vector": [0, 0, force]}]}


def counted_run(args):
    out = subprocess.run([sys.executable, "-c", _COUNTING_RUN, *args], capture_output=True,
                         text=True, timeout=600, env=os.environ)
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout.splitlines()[-1]), out.stdout


def test_second_process_reads_every_program_from_the_cache(tmp_path):
    """A new process running the same structure with another load compiles nothing: every
    program (solver with its stability check, model building) is read from the cache folder
    given by ``--cache-dir`` (before or after ``run``), the traced solver programs too."""
    cache = tmp_path / "xla"
    for k, force in enumerate((-0.01, -0.02)):
        (tmp_path / f"s{k}.json").write_text(json.dumps(cantilever(force)))
    cold, _ = counted_run(["--cache-dir", str(cache), "run", str(tmp_path / "s0.json")])
    assert cold["code"] == 0 and cold["misses"] >= 2
    if importlib.util.find_spec("flatbuffers"):   # jax.export needs it to store programs
        assert [p.name.split("-")[0] for p in (cache / "traced").iterdir()] == ["static"]
    warm, text = counted_run(["run", str(tmp_path / "s1.json"), "--cache-dir", str(cache),
                              "--no-stability"])
    assert warm["code"] == 0 and warm["misses"] == 0 and warm["hits"] >= 1, warm
    assert "compile " in text and "solve " in text


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
    scene.write_text(json.dumps(cantilever(-0.01)))
    assert cli.main(["--no-cache", "validate", str(scene)]) == 0
    assert os.environ["SIMSOFT_JAX_CACHE"] == "0" and compile_cache.enable() is None
    assert compile_cache.jax.config.jax_compilation_cache_dir == before
