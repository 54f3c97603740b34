"""Ctrl-C in a dynamic run: the host driver stops between chunks and keeps what it has
computed (status "interrupted"); the command line writes it and exits 130."""
import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import simsoft_jax as sj
from simsoft_jax.dynamics.driver import CHUNK_STEPS

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


@pytest.mark.skipif(sys.platform == "win32", reason="SIGINT")
def test_cli_ctrl_c_writes_the_result_and_exits_130(tmp_path):
    scene, out = tmp_path / "sag.json", tmp_path / "out.json"
    scene.write_text(json.dumps(pendulum(50.0)))     # 125 chunks: far longer than the test
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[1])}
    # a shell that starts the tests in the background ignores SIGINT, and a child Python
    # that inherits the ignore never raises KeyboardInterrupt: the child installs
    # Python's own handler before it runs the CLI (no preexec_fn: unsafe with threads)
    start = ("import runpy, signal; signal.signal(signal.SIGINT, signal.default_int_handler); "
             "runpy.run_module('simsoft_jax.cli', run_name='__main__')")
    proc = subprocess.Popen([sys.executable, "-c", start, "run", str(scene), "-o", str(out)],
                            stderr=subprocess.PIPE, stdout=subprocess.PIPE, env=env, text=True)
    text = ""
    while "t = " not in text:                          # the first progress report
        char = proc.stderr.read(1)
        assert char, text
        text += char
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, text + err
    lines = [ln for ln in err.splitlines() if ln.strip() and not ln.startswith("\r")]
    assert lines[-1].startswith("interrupted at t = ") and str(out) in lines[-1]
    d = json.loads(out.read_text(), parse_constant=lambda c: pytest.fail(c))
    assert d["status"] == "interrupted" and d["converged"] is False
    assert T_CHUNK - 1e-9 <= d["time"][-1] < 50.0 and d["failed_at"]["time"] == d["time"][-1]
