"""Ctrl-C: in a dynamic run the host driver stops between chunks and keeps what it has
computed (status "interrupted"); the command line writes it and exits 130. Ctrl-C while
a program compiles or a static solve runs ends the command at once with exit 130 (it
once waited for the solve, over a minute, or crashed the interpreter's teardown with
SIGSEGV after a compile); Ctrl-C again while the states are written stops the writing,
leaving no file. Signals are sent to real subprocesses."""
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import simsoft_jax as sj
from simsoft_jax.solvers.dynamics.driver import CHUNK_STEPS

DT = 1e-3
T_CHUNK = CHUNK_STEPS * DT   # the end of the first chunk


def pendulum(t_end):
    """A soft cantilever released under gravity; chunks of CHUNK_STEPS steps of DT."""
    return {"name": "sag", "gravity": {"vector": [0.0, 0.0, -9.81]},
            "solver": {"kind": "dynamic", "dt": DT, "t_end": t_end},
            "rods": [{"name": "r", "material": "spring_steel",
                      "section": {"shape": "circle", "diameter": 0.002},
                      "elements": 4, "geometry": {"kind": "straight", "length": 0.2}}],
            "constraints": [{"kind": "clamp", "rod": "r", "node": 0}]}


def test_interrupt_after_the_first_chunk_keeps_it(tmp_path):
    seen = []

    def progress(t, t_end):
        seen.append(t)
        raise KeyboardInterrupt

    result = sj.run(pendulum(3 * T_CHUNK), progress=progress)
    assert len(seen) == 1 and seen[0] == pytest.approx(T_CHUNK, rel=1e-12)
    assert result.status == "interrupted" and not result.converged
    np.testing.assert_allclose(result.time, DT * np.arange(CHUNK_STEPS + 1), rtol=0,
                               atol=1e-12)
    assert result.failed_at == result.time[-1]
    assert result.positions("r").shape == (CHUNK_STEPS + 1, 5, 3)
    assert "interrupted" in result.message and f"t = {T_CHUNK:g} s" in result.message
    full = sj.run(pendulum(3 * T_CHUNK))              # same states as an uninterrupted run
    np.testing.assert_allclose(result.positions("r"), full.positions("r")[:CHUNK_STEPS + 1],
                               rtol=0, atol=1e-14)
    out = tmp_path / "out.json"
    result.save(out)
    d = json.loads(out.read_text(), parse_constant=lambda c: pytest.fail(c))
    assert d["status"] == "interrupted" and d["failed_at"] == {"time": result.time[-1]}
    assert len(d["time"]) == CHUNK_STEPS + 1


def cli(*args):
    """The command line ``simsoft-jax ARGS`` in a subprocess (its console entry, as the
    installed script runs it), stdout and stderr piped as text."""
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[1])}
    # a shell that starts the tests in the background ignores SIGINT, and a child Python
    # that inherits the ignore never raises KeyboardInterrupt: the child installs
    # Python's own handler before it runs the CLI (no preexec_fn: unsafe with threads)
    start = ("import runpy, signal; signal.signal(signal.SIGINT, signal.default_int_handler); "
             "runpy.run_module('simsoft_jax.cli', run_name='__main__')")
    return subprocess.Popen([sys.executable, "-c", start, *map(str, args)],
                            stderr=subprocess.PIPE, stdout=subprocess.PIPE, env=env, text=True)


def read_until(proc, marker: str, text: str = "") -> str:
    """stderr of ``proc`` read up to and including ``marker``."""
    while marker not in text:
        char = proc.stderr.read(1)
        assert char, text
        text += char
    return text


@pytest.mark.skipif(sys.platform == "win32", reason="SIGINT")
def test_cli_ctrl_c_writes_the_result_and_exits_130(tmp_path):
    scene, out = tmp_path / "sag.json", tmp_path / "out.json"
    scene.write_text(json.dumps(pendulum(50.0)))     # 125 chunks: far longer than the test
    proc = cli("run", scene, "-o", out)
    text = read_until(proc, "t = ")                    # the first progress report
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, text + err
    lines = [ln for ln in err.splitlines() if ln.strip() and not ln.startswith("\r")]
    assert lines[-1].startswith("interrupted at t = ") and str(out) in lines[-1]
    d = json.loads(out.read_text(), parse_constant=lambda c: pytest.fail(c))
    assert d["status"] == "interrupted" and d["converged"] is False
    assert T_CHUNK - 1e-9 <= d["time"][-1] < 50.0 and d["failed_at"]["time"] == d["time"][-1]


def long_static(elements):
    """A cantilever under a tip load in 2000 load levels, each solved to the tolerance:
    compiling takes seconds, solving minutes."""
    return {"solver": {"kind": "static", "load_steps": 2000, "level_tolerance": 0.0},
            "rods": [{"name": "r", "material": "spring_steel",
                      "section": {"shape": "circle", "diameter": 0.002},
                      "elements": elements, "geometry": {"kind": "straight", "length": 1.0}}],
            "constraints": [{"kind": "clamp", "rod": "r", "node": 0}],
            "loads": [{"kind": "force", "rod": "r", "node": -1, "vector": [0.0, 0.0, -5.0]}]}


def interrupt_static(tmp_path, elements, compiled):
    """Ctrl-C a long static run without the compilation cache while its solver program
    compiles (``compiled`` False: half a second after the command says it compiles) or
    while it solves (True: a second after it says how long the compile took); the command
    must end with 130 and the one line, without waiting for the compile or the solve
    (they take minutes here) and without a crash."""
    scene, out = tmp_path / "long.json", tmp_path / "out.json"
    scene.write_text(json.dumps(long_static(elements)))
    proc = cli("--no-cache", "run", scene, "-o", out)
    text = read_until(proc, "compiling the static solver")
    if compiled:
        text = read_until(proc, "\n", text)        # "... 18.0 s": compiled, now solving
    time.sleep(1.0 if compiled else 0.5)
    assert proc.poll() is None, text + proc.communicate()[1]
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=60)   # once: over a minute, or SIGSEGV (-11)
    assert proc.returncode == 130, text + err
    assert err.strip().splitlines()[-1] == ("interrupted before any state was computed: "
                                            "nothing written")
    assert not out.exists() and sorted(p.name for p in tmp_path.iterdir()) == ["long.json"]


@pytest.mark.skipif(sys.platform == "win32", reason="SIGINT")
def test_ctrl_c_while_compiling_exits_130(tmp_path):
    """Ctrl-C while the solver program compiles (the imports are done)."""
    interrupt_static(tmp_path, 200, compiled=False)


@pytest.mark.slow
@pytest.mark.skipif(sys.platform == "win32", reason="SIGINT")
def test_ctrl_c_in_a_long_static_solve_exits_130(tmp_path):
    """Ctrl-C once the program is compiled (about 20 s here), solving 2000 load levels of
    5000 elements (minutes)."""
    interrupt_static(tmp_path, 5000, compiled=True)


@pytest.mark.slow
@pytest.mark.skipif(sys.platform == "win32", reason="SIGINT")
def test_ctrl_c_again_stops_writing_a_large_result(tmp_path):
    """The first Ctrl-C stops the rollout and starts writing its states (here millions of
    numbers, seconds of JSON); a second one stops the writing at once: exit 130, no
    result file and no temporary file left, the old file (none here) unchanged."""
    scene, out = tmp_path / "big.json", tmp_path / "out.json"
    d = pendulum(100.0)
    d["solver"].update(dt=1e-4, max_steps=10**7)
    d["rods"][0]["elements"] = 20
    scene.write_text(json.dumps(d))
    proc = cli("run", scene, "-o", out)
    text = read_until(proc, "t = 1.2")     # 12000 saved states of 21 nodes
    proc.send_signal(signal.SIGINT)
    text = read_until(proc, "Ctrl-C again stops the writing", text)
    time.sleep(0.5)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, text + err
    assert err.strip().splitlines()[-1] == (f"interrupted while writing: {out} not written "
                                            "(the old file, if any, is unchanged)")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["big.json"]


GC_CALLBACK_CTRL_C = """
import gc, signal, sys, time
from simsoft_jax.pipeline.interrupts import raise_or_defer
if sys.argv[1] == "raise_or_defer":
    signal.signal(signal.SIGINT, raise_or_defer)
armed = [True]
def callback(phase, info):      # Ctrl-C lands while the collector runs this callback
    if phase == "start" and armed:
        armed.clear()
        signal.raise_signal(signal.SIGINT)
        sum(range(1000))         # Python code: the handler runs here, inside the callback
gc.callbacks.append(callback)
try:
    gc.collect()
    time.sleep(2.0)              # a deferred signal arrives during this
except KeyboardInterrupt:
    print("raised after the callback")
else:
    print("lost")
"""


@pytest.mark.skipif(sys.platform == "win32", reason="SIGINT")
@pytest.mark.parametrize("handler, expected", [("default", "lost"),
                                               ("raise_or_defer", "raised after the callback")])
def test_ctrl_c_inside_a_garbage_collector_callback(handler, expected):
    """Python drops a KeyboardInterrupt raised inside a garbage-collector callback (JAX
    runs one during its compiles): with its default handler the Ctrl-C is lost; the
    command line's handler sends it again once the callback has returned."""
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[1])}
    done = subprocess.run([sys.executable, "-c", GC_CALLBACK_CTRL_C, handler], env=env,
                          capture_output=True, text=True, timeout=60)
    assert done.stdout.strip() == expected, done.stderr
