"""How many threads the OpenBLAS behind JAX's dense CPU factorizations may use.

On the CPU, JAX factorizes a dense matrix (``jax.scipy.linalg.lu_factor``; here the border
of rod-rod contact pairs, :mod:`simsoft_jax.couplings.rod_pairs`) with the LAPACK of
SciPy's bundled OpenBLAS, which splits a factorization of more than about 140 rows over
every core. Inside an XLA program, itself run on a pool of threads, that costs far more
than it gains: on a loaded 2-core machine the 396-row border of the cosseratbench pile
(32 contact pairs) took 44-75 ms of CPU per factorization, against 1.5 ms on one thread.

:func:`lapack_threads` limits every OpenBLAS loaded in the process for a block of code
and restores the previous counts after it. Where no OpenBLAS can be found (another BLAS,
a platform without ``/proc/self/maps``) it changes nothing. The setting is the process's:
other threads calling OpenBLAS meanwhile are limited too. ``OPENBLAS_NUM_THREADS=1`` in
the environment before Python starts has the same effect for the whole process.
"""
from __future__ import annotations

import contextlib
import ctypes
from pathlib import Path
from typing import Iterator, NamedTuple

# The thread-count functions (get, set) under the names OpenBLAS builds export them:
# SciPy's wheel, NumPy's (64-bit integers), a plain build.
NAMES = (("scipy_openblas_get_num_threads", "scipy_openblas_set_num_threads"),
         ("scipy_openblas_get_num_threads64_", "scipy_openblas_set_num_threads64_"),
         ("openblas_get_num_threads", "openblas_set_num_threads"))


class ThreadControl(NamedTuple):
    """One loaded OpenBLAS: its ``get_num_threads`` and ``set_num_threads`` functions."""
    get: ctypes._CFuncPtr
    set: ctypes._CFuncPtr


def loaded_openblas() -> list[ThreadControl]:
    """The OpenBLAS libraries mapped into this process (Linux), with their thread-count
    functions; empty where none is found."""
    try:
        maps = Path("/proc/self/maps").read_text().splitlines()
    except OSError:
        return []
    paths = sorted({line.split()[-1] for line in maps
                    if "openblas" in line.rsplit("/", 1)[-1].lower()})
    controls = []
    for path in paths:
        try:
            lib = ctypes.CDLL(path)          # already loaded: the same handle
        except OSError:
            continue
        for get_name, set_name in NAMES:
            get, put = getattr(lib, get_name, None), getattr(lib, set_name, None)
            if get is not None and put is not None:
                get.restype, put.argtypes = ctypes.c_int, (ctypes.c_int,)
                controls.append(ThreadControl(get, put))
                break
    return controls


@contextlib.contextmanager
def lapack_threads(count: int) -> Iterator[None]:
    """Run the block with every loaded OpenBLAS limited to ``count`` threads (module
    docstring); the previous counts are restored after it, also on an error."""
    if count < 1:
        raise ValueError(f"count: must be at least 1, got {count!r}")
    controls = loaded_openblas()
    before = [c.get() for c in controls]
    for c in controls:
        c.set(count)
    try:
        yield
    finally:
        for c, n in zip(controls, before):
            c.set(n)
