"""JAX's persistent compilation cache for the command line and the Python API.

A compiled solver program is written to a cache folder and read back by the next
process that needs the same program (same model structure, static settings, jax
version and machine), so the second run of a scene structure starts without compiling.

Where: ``$SIMSOFT_JAX_CACHE_DIR`` if set, else ``$XDG_CACHE_HOME/simsoft_jax/xla``, else
``~/.cache/simsoft_jax/xla``. Off: ``SIMSOFT_JAX_CACHE=0`` (or the command line's
``--no-cache``). A cache folder the user gave JAX already (``jax_compilation_cache_dir``,
e.g. by ``JAX_COMPILATION_CACHE_DIR``) is kept. Every program is cached, however short
its compilation (JAX's own threshold, 1 s, would leave out the small programs that a
fresh process compiles while building a model, and the gradient programs of
``jax.grad`` around :func:`simsoft_jax.solve_static` or :func:`simsoft_jax.simulate`,
whose backward passes compile in under a second), also in a folder given to JAX, unless
``JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS`` sets another threshold. The solvers'
entry points turn it on: :func:`simsoft_jax.run`, :func:`simsoft_jax.solve_static`,
:func:`simsoft_jax.simulate` and the command line. Where the ``filelock`` package is
installed (JAX needs it for this), the folder is bounded to ``MAX_BYTES`` (least
recently used entries dropped); otherwise it grows (each program is 0.1-2 MB).

JAX's cache keeps the compiled code, but a hit still pays the Python tracing of the
solver and its lowering to StableHLO (1-2 s of a fresh process), and reading back a
program stored as traced StableHLO (``jax.export``) still pays its lowering (~0.4 s)
and JAX's backend checks (~0.5 s). :func:`compile_stored` keeps the solver programs as
loadable executables instead (``jax.experimental.serialize_executable``, in
``<cache>/programs/``, bounded to ``MAX_BYTES / 4``, least recently used dropped), so
a later process only loads one (~0.3-0.5 s for the helical rollout).

A program compiled (not loaded) for a new structure says so: one line on stderr,
"compiling the static solver for this scene structure (kept for next time)... 41.2 s"
(``SIMSOFT_JAX_QUIET=1`` silences it).

The cache is trusted code: keep it in a folder only you can write to (JAX's warning on
``jax.config.update("jax_compilation_cache_dir", ...)``).
"""
from __future__ import annotations

import contextlib
import functools
import hashlib
import importlib.util
import os
import platform
import re
import sys
import threading
import time
import warnings
from pathlib import Path

import jax
import jaxlib
import numpy as np
from jax.experimental import serialize_executable

from ..math import xla
from ..atomic_files import write_atomic

ENV_DIR = "SIMSOFT_JAX_CACHE_DIR"
ENV_SWITCH = "SIMSOFT_JAX_CACHE"
ENV_QUIET = "SIMSOFT_JAX_QUIET"
ENV_MIN_COMPILE_TIME = "JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS"   # JAX's own
# the programs' names in the compile message
PROGRAM_NAMES = {"static": "the static solver", "rollout": "the dynamic solver"}
# jax.monitoring duration event of a program loaded from ``<cache>/programs/`` (keyword
# ``fun_name``, as JAX's compile events), for counters of compiled-or-loaded programs
LOADED_EVENT = "/simsoft_jax/compile_cache/program_loaded"
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
        if switched_off():
            return None
        _keep_every_program()
        return current
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
    _keep_every_program()
    if importlib.util.find_spec("filelock") is not None:
        jax.config.update("jax_compilation_cache_max_size", MAX_BYTES)
    return str(folder)


def _keep_every_program() -> None:
    """JAX's persistent cache keeps every program, however short its compilation (module
    docstring), unless ``JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS`` is set. JAX's
    other threshold, the entry size (``jax_persistent_cache_min_entry_size_bytes``), is 0
    by default: no program is left out for its size."""
    if (ENV_MIN_COMPILE_TIME not in os.environ
            and jax.config.jax_persistent_cache_min_compile_time_secs != 0.0):
        jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)


@functools.cache
def _source_key() -> str:
    """Hash of this package's source, the jax and jaxlib versions, the backend (platform,
    its version, device kind), the compile options asked for (whether this jaxlib takes
    them follows from its version; probing would compile a program), ``XLA_FLAGS`` and
    the CPU (machine type and feature flags): a program stored under another of any of
    them is never loaded."""
    root = Path(__file__).resolve().parent
    device = jax.devices()[0]
    digest = hashlib.sha256(repr((
        jax.__version__, jaxlib.__version__, device.platform, device.client.platform_version,
        device.device_kind, sorted(xla.CANDIDATE_OPTIONS.items()),
        os.environ.get("XLA_FLAGS", ""), platform.machine(), _cpu_flags())).encode())
    for path in sorted(root.rglob("*.py")):
        digest.update(str(path.relative_to(root)).encode() + path.read_bytes())
    return digest.hexdigest()


def _cpu_flags() -> str:
    """The CPU's feature flags (Linux ``/proc/cpuinfo``; empty elsewhere): compiled CPU
    code may use any of them."""
    try:
        with open("/proc/cpuinfo", encoding="ascii", errors="replace") as fh:
            return next((line for line in fh if line.startswith("flags")), "")
    except OSError:
        return ""


# Custom calls whose targets this module registers before loading a program (JAX
# registers the LAPACK ones lazily, when it lowers a linear-algebra operation; a loaded
# program calling an unregistered one would crash the process). A program calling any
# other custom call is not stored.
_LOADABLE_CALLS = re.compile(r"lapack_\w+")


def _registered_calls() -> bool:
    """Register the LAPACK custom calls (what lowering a linear solve does); False when
    this jax has no such hook (then nothing is loaded)."""
    try:
        from jax._src.lax import linalg
        linalg.initialize_lapack()
    except (ImportError, AttributeError):
        return False
    return True


def _load(path: Path, leaves, outputs: int, name: str):
    """The stored executable at ``path`` for arguments ``leaves`` with ``outputs``
    results, or None (absent, unreadable, or unloadable here). The custom calls are
    registered on a second thread while the executable loads (the registration imports
    SciPy's LAPACK, ~0.2 s; the loading runs outside the interpreter lock)."""
    if not path.is_file():
        return None
    start = time.perf_counter()
    registered = []
    thread = threading.Thread(target=lambda: registered.append(_registered_calls()))
    thread.start()
    try:
        in_tree = jax.tree_util.tree_structure((tuple(leaves), {}))
        out_tree = jax.tree_util.tree_structure([0] * outputs)
        compiled = serialize_executable.deserialize_and_load(path.read_bytes(), in_tree,
                                                              out_tree)
    except Exception:  # noqa: BLE001 -- any failure means: compile it again
        compiled = None
    thread.join()
    if compiled is None or not registered[0]:
        return None
    os.utime(path)   # recently used
    jax.monitoring.record_event_duration_secs(LOADED_EVENT, time.perf_counter() - start,
                                              fun_name=f"jit({name})")
    return compiled


def _store(path: Path, compiled) -> None:
    """Write ``compiled`` to ``path`` when it can be loaded again (see
    :data:`_LOADABLE_CALLS`), then drop the least recently used programs beyond
    ``MAX_BYTES / 4``. A read-only cache or an unserializable program: nothing stored."""
    calls = set(re.findall(r'custom_call_target="([^"]+)"', compiled.as_text() or ""))
    if not all(_LOADABLE_CALLS.fullmatch(c) for c in calls):
        return
    try:
        blob = serialize_executable.serialize(compiled)[0]
        path.parent.mkdir(parents=True, exist_ok=True)
        write_atomic(path, lambda fh: fh.write(blob), binary=True)
        stored = sorted(path.parent.glob("*.xla"), key=lambda f: f.stat().st_mtime)
        total = sum(f.stat().st_size for f in stored)
        for old in stored[:-1]:
            if total <= MAX_BYTES // 4:
                break
            total -= old.stat().st_size
            old.unlink()
    except (OSError, ValueError, NotImplementedError):
        pass


@contextlib.contextmanager
def announced(name: str, kept: bool):
    """Say on stderr that the program ``name`` is being compiled, then the seconds it took
    (one line; nothing with ``SIMSOFT_JAX_QUIET`` set to 1, true, yes or on)."""
    if os.environ.get(ENV_QUIET, "0").strip().lower() in ("1", "true", "yes", "on"):
        yield
        return
    what = PROGRAM_NAMES.get(name, f"the {name} program")
    print(f"compiling {what} for this scene structure"
          f"{' (kept for next time)' if kept else ''}...", end="", file=sys.stderr, flush=True)
    start = time.perf_counter()
    try:
        yield
    finally:
        print(f" {time.perf_counter() - start:.1f} s", file=sys.stderr, flush=True)


_CALLED = set()   # signatures of the calls first_call has seen


def first_call(name: str, args, *static):
    """:func:`announced` around a call of the program ``name`` on ``args`` (pytree) with
    the static arguments ``static`` (hashable) that this process has not made before
    (same pytree structure, shapes and dtypes: a call ``jax.jit`` compiles for), else a
    block that says nothing. For a program compiled by ``jax.jit`` itself, kept by
    JAX's persistent cache (a later process still traces and lowers it)."""
    leaves, tree = jax.tree_util.tree_flatten(args)
    signature = (name, tree, static,
                 tuple((getattr(x, "shape", ()), getattr(x, "dtype", type(x)))
                       for x in leaves))   # ~20 us for a model (np.shape: ~150 us)
    if signature in _CALLED:
        return contextlib.nullcontext()
    _CALLED.add(signature)
    return announced(name, kept=bool(jax.config.jax_compilation_cache_dir))


@contextlib.contextmanager
def _jax_cache_off():
    """JAX's own persistent cache off inside the block: a program read from it serializes
    without its compiled functions (loading that again fails), and a program stored
    here need not be kept twice."""
    from jax.experimental.compilation_cache import compilation_cache
    before = jax.config.jax_enable_compilation_cache
    jax.config.update("jax_enable_compilation_cache", False)
    compilation_cache.reset_cache()   # JAX decides once whether to use it
    try:
        yield
    finally:
        jax.config.update("jax_enable_compilation_cache", before)
        compilation_cache.reset_cache()


def _compile(jitted, tree, leaves, name: str, path: Path):
    """Trace and compile ``jitted`` over the flattened arguments ``leaves`` (with this
    package's compile options) and store it at ``path``. A program that can be stored
    (its custom calls all in :data:`_LOADABLE_CALLS`) is compiled outside JAX's cache;
    any other (e.g. GPU solver calls) through it, and not stored."""
    def program(*xs):
        return jax.tree_util.tree_leaves(jitted(*jax.tree_util.tree_unflatten(tree, xs)))

    program.__name__ = program.__qualname__ = getattr(jitted, "__name__", name)
    options = jitted.compiler_options()
    lowered = jax.jit(program, **({"compiler_options": options} if options else {})
                      ).lower(*leaves)
    calls = set(re.findall(r"custom_call @([\w.]+)", lowered.as_text()))
    if not all(_LOADABLE_CALLS.fullmatch(c) for c in calls):
        return lowered.compile()
    with _jax_cache_off():
        compiled = lowered.compile()
    _store(path, compiled)
    return compiled


def leaf_signature(leaves) -> tuple:
    """What a compiled program depends on in its argument leaves (arrays or Python
    scalars): one ``(shape, dtype name, weak type)`` per leaf, hashable."""
    return tuple((np.shape(x), np.dtype(x.dtype if hasattr(x, "dtype") else type(x)).name,
                  bool(getattr(x, "weak_type", False))) for x in leaves)


def compile_stored(jitted, args: tuple, out_tree, name: str, variant: str = ""):
    """``jitted.lower(*args).compile()`` that later processes load instead of tracing and
    compiling again.

    With the cache on, the compiled program (over the flattened arguments) is kept in
    ``<cache>/programs/`` under a hash of its argument structure (pytree, shapes,
    dtypes), this package's source and the machine (:func:`_source_key`); a later
    process loads it. ``jitted``: a :func:`simsoft_jax.math.xla.jit` program (compiled with its
    own options). ``out_tree``: the pytree structure of the outputs. Returns a callable
    with ``jitted``'s signature. Compiling (not loading) is announced (:func:`announced`).
    ``variant``: what else the program depends on (e.g. the static arguments bound in
    ``jitted``), part of the key.
    """
    folder = jax.config.jax_compilation_cache_dir
    if not folder:
        with announced(name, kept=False):
            return jitted.lower(*args).compile()
    leaves, tree = jax.tree_util.tree_flatten(args)
    signature = repr((name, variant, tree, leaf_signature(leaves)))
    key = hashlib.sha256((signature + _source_key()).encode()).hexdigest()[:40]
    path = Path(folder) / "programs" / f"{name.replace(' ', '_')}-{key}.xla"
    compiled = _load(path, leaves, out_tree.num_leaves, name)
    if compiled is None:
        with announced(name, kept=True):
            compiled = _compile(jitted, tree, leaves, name, path)
    return lambda *a: jax.tree_util.tree_unflatten(
        out_tree, compiled(*jax.tree_util.tree_leaves(a)))
