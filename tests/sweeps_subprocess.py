"""Child process of tests/test_sweeps_batched.py (not a test module).

    python sweeps_subprocess.py devices OUT.json
        two host CPU devices (sweeps.use_host_devices(2)); writes to OUT.json the
        sharded static sweep of POINTS, the gradient of a sharded sweep with its central
        finite difference, and the error (if any) of a vmapped chunk on the two devices.
    python sweeps_subprocess.py distributed OUT.npz PORT PROCESS_ID
        one of two jax.distributed processes on 127.0.0.1:PORT; each solves its share of
        the points, the shares are gathered and process 0 writes OUT.npz atomically.
"""
import json
import sys

import jax
import jax.numpy as jnp
import numpy as np

import simsoft_jax as sj
from simsoft_jax.studies import sweeps
from simsoft_jax.atomic_files import write_atomic

L = 0.3


def strip_scene(elements: int) -> dict:
    """A clamped spring-steel strip (L = 0.3 m, 2 x 10 mm) with a unit world force along y
    at its tip: the sweep tests' scene (also tests/test_sweeps.py)."""
    return {"name": "strip", "solver": {"kind": "static"},
            "rods": [{"name": "arm", "material": "spring_steel",
                      "section": {"shape": "rectangle", "width": 2e-3, "height": 10e-3},
                      "elements": elements, "geometry": {"kind": "straight", "length": L}}],
            "constraints": [{"kind": "clamp", "rod": "arm", "node": 0}],
            "loads": [{"kind": "force", "rod": "arm", "node": -1, "vector": [0.0, 1.0, 0.0],
                       "frame": "world"}]}


SCENE = strip_scene(4)
POINTS = {"force": np.array([0.5, 3.0, 8.0, 1.0, 5.0]), "stiff": np.array([1.0, 0.7, 1.3, 2.0, 1.0])}


def vary(model, q):
    """Tip force along y (N) and a factor on EI_z."""
    nodal = model.nodal_dead.at[-1, 1].set(q["force"])
    return model.replace(nodal_dead=nodal, stiffness=model.stiffness.at[:, 5].multiply(q["stiff"]))


def devices(out):
    model = sj.build_model(sj.Scene.from_dict(SCENE))
    eq = sweeps.static_sweep(model, vary, POINTS)
    try:   # vmapped chunks on several CPU devices: refused where jaxlib can hang on them
        sweeps.static_sweep(model, vary, POINTS, chunk=sweeps.FLAT_FROM)
        refused = ""
    except ValueError as error:
        refused = str(error)

    def tips(ei_scale):   # sum of the tip deflections (m) against a factor on EI_z
        m = model.replace(stiffness=model.stiffness.at[:, 5].multiply(ei_scale))
        return jnp.sum(sweeps.static_sweep(m, vary, POINTS).p[:, -1, 1])
    h = 1e-6
    result = {
        "devices": len(jax.devices()),
        "p_sharding_devices": len(eq.p.sharding.device_set),
        "p": np.asarray(eq.p).tolist(),
        "iterations": np.asarray(eq.iterations).tolist(),
        "converged": np.asarray(eq.converged).tolist(),
        "grad": float(jax.grad(tips)(1.0)),
        "fd_grad": float((tips(1.0 + h) - tips(1.0 - h)) / (2 * h)),
        "chunk_refused": refused,
    }
    write_atomic(out, lambda fh: json.dump(result, fh))


def distributed(out, port, process_id):
    jax.distributed.initialize(coordinator_address=f"127.0.0.1:{port}", num_processes=2,
                               process_id=process_id, initialization_timeout=60)
    model = sj.build_model(sj.Scene.from_dict(SCENE))
    share = sweeps.process_share(POINTS)
    eq = sweeps.static_sweep(model, vary, share)
    full = sweeps.gather_processes({"p": eq.p, "converged": eq.converged,
                                    "share_of": jnp.full(eq.converged.shape, process_id)},
                                   len(POINTS["force"]))
    if jax.process_index() == 0:
        write_atomic(out, lambda fh: np.savez(fh, **full), binary=True)
    jax.distributed.shutdown()


if __name__ == "__main__":
    if sys.argv[1] == "devices":
        sweeps.use_host_devices(2)      # before any JAX array exists in this process
        devices(sys.argv[2])
    else:
        distributed(sys.argv[2], int(sys.argv[3]), int(sys.argv[4]))
