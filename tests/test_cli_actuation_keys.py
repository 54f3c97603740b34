"""``simsoft-jax run`` reads every key of the actuation and mechanism sections (issue 13):
a TOML scene with a pressure chamber, an attached mass at an offset with its inertia, a
dead force at an offset point, a tendon across a weld and a rigid body welded at the tip.
The file the command writes holds the same equilibrium as ``sj.run`` on the same file
(each term's physics is tested against closed forms in its own test module), its
``bodies`` and ``tendons`` entries, and the weld holds in it."""
import json
import subprocess
import sys

import numpy as np

import simsoft_jax as sj
from conftest import REPO_ROOT

SCENE = """
name = "every_actuation_key"
[solver]
kind = "static"
tolerance = 1e-12

[gravity]
vector = [0.0, 0.0, -9.81]

[[rods]]
name = "arm"
elements = 4
geometry = { kind = "straight", length = 0.4 }
stiffness = { EA = 2e3, GAy = 1e3, GAz = 1e3, GJ = 0.4, EIy = 0.5, EIz = 0.5 }
inertia = { rhoA = 0.1, rhoJ = 1e-4, rhoIy = 5e-5, rhoIz = 5e-5 }

[[rods]]
name = "tip"
elements = 2
geometry = { kind = "straight", length = 0.2 }
base = { position = [0.4, 0.0, 0.0] }
stiffness = { EA = 2e3, GAy = 1e3, GAz = 1e3, GJ = 0.4, EIy = 0.5, EIz = 0.5 }
inertia = { rhoA = 0.1, rhoJ = 1e-4, rhoIy = 5e-5, rhoIz = 5e-5 }

[[constraints]]
kind = "clamp"
rod = "arm"
node = 0

[[joints]]
kind = "weld"
a = { rod = "arm", node = -1 }
b = { rod = "tip", node = 0 }

[[bodies]]
name = "gripper"
mass = 0.05
inertia = [[1e-5, 0, 0], [0, 2e-5, 0], [0, 0, 2e-5]]
position = [0.65, 0.0, 0.0]

[[joints]]
kind = "weld"
a = { rod = "tip", node = -1, offset = [0.05, 0.0, 0.0] }
b = { body = "gripper" }

[[masses]]
rod = "arm"
node = 2
mass = 0.02
offset = [0.0, 0.01, 0.0]
inertia = [[1e-6, 0, 0], [0, 1e-6, 0], [0, 0, 1e-6]]

[[loads]]
kind = "force"
rod = "arm"
node = 3
vector = [0.0, 0.1, 0.0]
frame = "world"
offset = [0.0, 0.0, 0.01]

[[chambers]]
name = "c1"
rod = "arm"
area = 1e-4
offset = [0.0, -0.008]
pressure = 2e3

[[tendons]]
name = "t1"
rod = "arm"
to_rod = "tip"
offset = [0.01, 0.0]
tension = 3.0
"""


def test_cli_run_reads_every_actuation_and_mechanism_key(tmp_path):
    path, out = tmp_path / "scene.toml", tmp_path / "out.json"
    path.write_text(SCENE)
    proc = subprocess.run([sys.executable, "-m", "simsoft_jax.cli", "run", str(path), "-o",
                           str(out)], capture_output=True, text=True, timeout=600,
                          cwd=REPO_ROOT)
    assert proc.returncode == 0, proc.stderr
    d = json.loads(out.read_text())
    api = sj.run(sj.load_scene(path))
    assert api.converged and d["converged"]
    for rod in ("arm", "tip"):
        np.testing.assert_allclose(d["rods"][rod]["positions"], api.positions(rod),
                                   rtol=0, atol=1e-12)
    position, rotation = (np.asarray(d["bodies"]["gripper"][k]) for k in ("position",
                                                                         "rotation"))
    np.testing.assert_allclose(position, api.body_pose("gripper")[0], rtol=0, atol=1e-12)
    assert d["tendons"] == {"t1": {"tension": 3.0}}
    tip_p, tip_R = api.positions("tip")[-1], api.rotations("tip")[-1]
    np.testing.assert_allclose(position, tip_p + tip_R @ [0.05, 0.0, 0.0], rtol=0, atol=1e-10)
    np.testing.assert_allclose(rotation, tip_R, rtol=0, atol=1e-10)
    # the actuators and loads moved the arm out of its plane and off its axis
    assert np.abs(api.positions("tip")[-1, 1:]).min() > 1e-3
