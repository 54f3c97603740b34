"""Sweeps over the devices of a JAX mesh and over the processes of ``jax.distributed``.

Devices. A sweep's batch is split evenly over a one-axis :class:`jax.sharding.Mesh`
(axis ``"batch"``) with :func:`jax.shard_map`: each device solves its share
independently (its loops end when its own lanes are done) and the results come back
concatenated in the order of the points. The same code runs on GPUs and on CPU cores:
XLA exposes the host CPU as *one* device unless it is told otherwise, and the number of
host devices is fixed when JAX starts its backend (the flag
``--xla_force_host_platform_device_count=N`` in ``XLA_FLAGS``). :func:`use_host_devices`
sets it, and must run before anything in the process touches a JAX array (importing JAX
is fine; creating an array is not); the environment variable ``SIMSOFT_JAX_HOST_DEVICES``
gives its default. Each host device then runs on its own thread, one core each.

Processes. Under ``jax.distributed.initialize(...)`` (several processes, on one machine or
many), :func:`process_share` gives each process its contiguous share of the points (all
shares padded to the same length), the process solves it on its local devices, and
:func:`gather_processes` collects every share on every process
(:func:`jax.experimental.multihost_utils.process_allgather`) in the order of the points.
See docs/sweeps.md.
"""
from __future__ import annotations

import os

import jax
import jax.numpy as jnp
import numpy as np
from jax.sharding import Mesh, PartitionSpec

ENV_HOST_DEVICES = "SIMSOFT_JAX_HOST_DEVICES"
_FLAG = "--xla_force_host_platform_device_count"


def _backend_started() -> bool:
    try:
        from jax._src import xla_bridge
        return bool(xla_bridge.backends_are_initialized())
    except (ImportError, AttributeError):  # private API moved: assume started (safe side)
        return True


def use_host_devices(count: int | None = None) -> int:
    """Expose the host CPU as ``count`` JAX devices (default: ``$SIMSOFT_JAX_HOST_DEVICES``,
    else ``os.cpu_count()``), so that a sweep uses that many cores; returns ``count``.

    Sets ``--xla_force_host_platform_device_count`` in ``XLA_FLAGS``. It takes effect
    only if JAX's backend has not started in this process (call it at the top of a
    script, before any array is made); if it has started with another number of CPU
    devices a RuntimeError says so. Other flags in ``XLA_FLAGS`` are kept.
    """
    if count is None:
        count = int(os.environ.get(ENV_HOST_DEVICES) or os.cpu_count() or 1)
    count = int(count)
    if count < 1:
        raise ValueError(f"use_host_devices: count must be >= 1, got {count}")
    if _backend_started():
        have = len(jax.devices("cpu"))
        if have != count:
            raise RuntimeError(
                f"use_host_devices({count}): JAX has already started with {have} CPU "
                f"device(s); call it before any JAX array is created, or start Python "
                f"with XLA_FLAGS={_FLAG}={count}")
        return count
    flags = [f for f in os.environ.get("XLA_FLAGS", "").split() if not f.startswith(_FLAG)]
    os.environ["XLA_FLAGS"] = " ".join(flags + [f"{_FLAG}={count}"])
    return count


def batch_mesh(devices=None) -> Mesh:
    """A one-axis mesh named ``"batch"``: ``devices`` may be None (all local devices:
    every core exposed by :func:`use_host_devices`, or every GPU), an int (the first that
    many local devices), a sequence of devices, or a Mesh (returned as it is)."""
    if isinstance(devices, Mesh):
        return devices
    local = jax.local_devices()
    if devices is None:
        devices = local
    elif isinstance(devices, int):
        if not 1 <= devices <= len(local):
            raise ValueError(f"devices: {devices} asked, this process has {len(local)} "
                             f"local device(s) (see sweeps.use_host_devices)")
        devices = local[:devices]
    return Mesh(np.array(list(devices)), ("batch",))


def _pad(points: dict, multiple: int) -> tuple[dict, int]:
    """Points padded to a multiple of ``multiple`` by repeating the last one; (points, B)."""
    size = next(iter(points.values())).shape[0]
    extra = -size % multiple
    if extra:
        points = {k: jnp.concatenate([v, jnp.repeat(v[-1:], extra, axis=0)])
                  for k, v in points.items()}
    return points, size


def sharded_map(per_device, points: dict, mesh: Mesh):
    """``per_device(points_share)`` on every device of ``mesh``, the batch axis split
    evenly (padded by repeating the last point) and the outputs concatenated back to the
    original batch. Traceable and differentiable (``jax.shard_map``)."""
    points, size = _pad(points, mesh.size)
    spec = PartitionSpec("batch")
    out = jax.shard_map(per_device, mesh=mesh, in_specs=(spec,), out_specs=spec,
                        check_vma=False)(points)
    return jax.tree_util.tree_map(lambda x: x[:size], out)


def process_share(points: dict) -> dict:
    """This process's contiguous share of ``points`` (``{name: (B, ...)}``) under
    ``jax.distributed``: ``ceil(B / process_count)`` points, the last share padded by
    repeating the last point (so every process compiles the same shapes)."""
    arrays = {k: np.asarray(v) for k, v in points.items()}
    size = next(iter(arrays.values())).shape[0]
    share = -(-size // jax.process_count())
    start = jax.process_index() * share
    idx = np.minimum(np.arange(start, start + share), size - 1)
    return {k: v[idx] for k, v in arrays.items()}


def gather_processes(result, size: int):
    """Every process's share of a sweep result (leading batch axis), concatenated in
    process order and cut to the ``size`` points of the sweep: NumPy arrays, on every
    process (a collective: every process must call it)."""
    from jax.experimental import multihost_utils

    if jax.process_count() == 1:
        gathered = jax.tree_util.tree_map(np.asarray, result)
    else:
        gathered = multihost_utils.process_allgather(result, tiled=True)
    return jax.tree_util.tree_map(lambda x: np.asarray(x)[:size], gathered)
