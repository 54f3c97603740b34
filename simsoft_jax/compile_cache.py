"""JAX's persistent compilation cache for ``simsoft-jax run`` and :func:`simsoft_jax.run`.

A compiled solver program is written to a cache folder and read back by the next
process that needs the same program (same model structure, integer settings, jax
version and machine), so the second run of a scene structure starts without compiling.

Where: ``$SIMSOFT_JAX_CACHE_DIR`` if set, else ``$XDG_CACHE_HOME/simsoft_jax/xla``, else
``~/.cache/simsoft_jax/xla``. Off: ``SIMSOFT_JAX_CACHE=0`` (or the command line's
``--no-cache``). A cache folder the user gave JAX already (``jax_compilation_cache_dir``,
e.g. by ``JAX_COMPILATION_CACHE_DIR``) is kept. Every program is cached, however short
its compilation (JAX's own threshold, 1 s, would leave out the small programs that a
fresh process compiles while building a model). Where the ``filelock`` package is
installed (JAX needs it for this), the folder is bounded to ``MAX_BYTES`` (least
recently used entries dropped); otherwise it grows (each program is 0.1-2 MB).

JAX's cache keeps the compiled code; the Python tracing of the solver (1-2 s of a fresh
process) would still be paid. :func:`compile_stored` keeps the traced program too
(``jax.export``, in ``<cache>/traced/``; needs the ``flatbuffers`` package), so a later
process only reads both back.

The cache is trusted code: keep it in a folder only you can write to (JAX's warning on
``jax.config.update("jax_compilation_cache_dir", ...)``).
"""
from __future__ import annotations

import functools
import hashlib
import importlib.util
import os
import warnings
from pathlib import Path

import jax
import numpy as np

from ._xla import compiler_options
from .output import write_atomic

ENV_DIR = "SIMSOFT_JAX_CACHE_DIR"
ENV_SWITCH = "SIMSOFT_JAX_CACHE"
MAX_BYTES = 2 * 1024 ** 3


def default_dir() -> Path:
    """The cache folder when none is given: ``$SIMSOFT_JAX_CACHE_DIR``, else
    ``$XDG_CACHE_HOME/simsoft_jax/xla``, else ``~/.cache/simsoft_jax/xla``."""
    if os.environ.get(ENV_DIR):
        return Path(os.environ[ENV_DIR]).expanduser()
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base).expanduser() / "simsoft_jax" / "xla"


def switched_off() -> bool:
    """``SIMSOFT_JAX_CACHE`` set to 0, false, no or off (any case)."""
    return os.environ.get(ENV_SWITCH, "1").strip().lower() in ("0", "false", "no", "off")


def enable(path=None) -> str | None:
    """Turn the persistent cache on in this process and return its folder (None: off).

    ``path`` (a folder) overrides the default and any folder set before. Without
    ``path``: nothing changes when it is switched off (:func:`switched_off`) or JAX
    already has a cache folder (it is returned). A folder that cannot be created gives
    a warning and leaves the cache off. Cheap to call again.
    """
    current = jax.config.jax_compilation_cache_dir
    if path is None and (switched_off() or current):
        return None if switched_off() else current
    folder = Path(path).expanduser() if path is not None else default_dir()
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        warnings.warn(f"compilation cache: cannot create {str(folder)!r} "
                      f"({err.strerror or err}); compiling without it", stacklevel=2)
        return None
    if current and current != str(folder):
        from jax.experimental.compilation_cache import compilation_cache
        compilation_cache.reset_cache()   # JAX opens its cache folder once per process
    jax.config.update("jax_compilation_cache_dir", str(folder))
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
    if importlib.util.find_spec("filelock") is not None:
        jax.config.update("jax_compilation_cache_max_size", MAX_BYTES)
    return str(folder)


@functools.cache
def _source_key() -> str:
    """Hash of this package's source and the jax version: a traced program stored by
    another version of either is never used."""
    root = Path(__file__).resolve().parent
    digest = hashlib.sha256(jax.__version__.encode())
    for path in sorted(root.rglob("*.py")):
        digest.update(str(path.relative_to(root)).encode() + path.read_bytes())
    return digest.hexdigest()


def _read_exported(path: Path):
    """The stored traced program at ``path``, or None (absent, unreadable, or written by
    a jax that cannot read it)."""
    try:
        return jax.export.deserialize(bytearray(path.read_bytes()))
    except Exception:  # noqa: BLE001 -- any failure means: trace it again
        return None


def compile_stored(jitted, args: tuple, out_tree, name: str):
    """``jitted.lower(*args).compile()`` that skips the Python tracing in later processes.

    With the cache on (and the ``flatbuffers`` package that JAX needs to serialize), the
    traced program (``jax.export``) is kept in ``<cache>/traced/`` under a hash of its
    argument structure (pytree, shapes, dtypes), this package's source and the jax
    version; a later process reads it back and compiles it, and the compilation itself
    comes from the persistent cache. ``out_tree``: the pytree structure of the outputs.
    Returns a callable with ``jitted``'s signature.
    """
    folder = jax.config.jax_compilation_cache_dir
    if not folder or importlib.util.find_spec("flatbuffers") is None:
        return jitted.lower(*args).compile()
    leaves, tree = jax.tree_util.tree_flatten(args)
    signature = repr((name, tree, [(np.shape(x), str(x.dtype if hasattr(x, "dtype") else np.result_type(x)),
                                    bool(getattr(x, "weak_type", False))) for x in leaves]))
    key = hashlib.sha256((signature + _source_key()).encode()).hexdigest()[:40]
    path = Path(folder) / "traced" / f"{name}-{key}.jaxexport"
    exported = _read_exported(path)
    if exported is None:
        flat = jax.jit(lambda *xs: jax.tree_util.tree_leaves(
            jitted(*jax.tree_util.tree_unflatten(tree, xs))))
        exported = jax.export.export(flat)(*leaves)
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            write_atomic(path, lambda fh: fh.write(exported.serialize()), binary=True)
        except OSError:
            pass  # a read-only cache: compile without storing
    def program(*xs):
        return exported.call(*xs)

    program.__name__ = program.__qualname__ = getattr(jitted, "__name__", name)
    options = compiler_options()
    compiled = jax.jit(program, **({"compiler_options": options} if options else {})
                       ).lower(*leaves).compile()
    return lambda *a: jax.tree_util.tree_unflatten(
        out_tree, compiled(*jax.tree_util.tree_leaves(a)))
