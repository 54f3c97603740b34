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

The cache is trusted code: keep it in a folder only you can write to (JAX's warning on
``jax.config.update("jax_compilation_cache_dir", ...)``).
"""
from __future__ import annotations

import importlib.util
import os
import warnings
from pathlib import Path

import jax

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
