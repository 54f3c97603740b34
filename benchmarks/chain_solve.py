"""Cost of the block-tridiagonal chain solve (:mod:`simsoft_jax.math.linalg`): one
factorization and one solve of a random, diagonally dominant chain of 6x6 blocks, as the
static Newton pass does it, for growing node counts, on the package's path (dense LU up
to ``DENSE_LIMIT_NODES`` nodes, cyclic-reduction levels down to that size above) and on
the dense LU alone; and the solve alone with stored factors (modified Newton, implicit
derivatives).

    PYTHONPATH=. python benchmarks/chain_solve.py [--quick] [--out DIR]   (by hand)

Each figure: 2000 factorizations and solves inside one compiled loop whose matrix depends
on the previous solution (nothing is hoisted out of the loop), the fastest of 3 runs,
per factorization and solve, in microseconds. Not a test.
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

import jax
import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
import common  # noqa: E402

from simsoft_jax.math import xla, linalg  # noqa: E402

LOOPS = 2000


def chain(n: int):
    rng = np.random.default_rng(n)
    diag = rng.normal(size=(n, 6, 6)) + 12.0 * np.eye(6)
    return ((diag, rng.normal(size=(n - 1, 6, 6)), rng.normal(size=(n - 1, 6, 6))),
            rng.normal(size=(n, 6)))


def microseconds(n: int, dense_limit: int, solve_only: bool) -> float:
    """Per factorization and solve (or per solve with stored factors), us."""
    blocks, b = chain(n)
    default = linalg.DENSE_LIMIT_NODES
    linalg.DENSE_LIMIT_NODES = dense_limit     # read at trace time

    def loop(blocks, b):
        stored = linalg.factorize(blocks)

        def body(_, x):
            if solve_only:
                return linalg.solve_factored(stored, b + 1e-3 * x)
            moved = (blocks[0] + 1e-9 * x[0, 0],) + tuple(blocks[1:])
            return linalg.block_solve(moved, b + 1e-3 * x)
        return jax.lax.fori_loop(0, LOOPS, body, b)

    try:
        run = xla.jit(loop)
        jax.block_until_ready(run(blocks, b))
    finally:
        linalg.DENSE_LIMIT_NODES = default
    best = np.inf
    for _ in range(3):
        start = time.perf_counter()
        jax.block_until_ready(run(blocks, b))
        best = min(best, time.perf_counter() - start)
    return 1e6 * best / LOOPS


def run(out: Path, quick: bool = False) -> dict:
    """Chain solve: factorize + solve and solve alone, package path against dense LU."""
    info = common.machine()
    sizes = (8, 16, 32) if quick else (4, 8, 12, 16, 25, 50, 100)
    rows = [dict(nodes=n,
                 package_us=microseconds(n, linalg.DENSE_LIMIT_NODES, False),
                 dense_us=microseconds(n, n, False),
                 package_solve_us=microseconds(n, linalg.DENSE_LIMIT_NODES, True),
                 dense_solve_us=microseconds(n, n, True)) for n in sizes]
    common.table(rows, [("nodes", "nodes", "d"), ("package_us", "factorize+solve us", ".1f"),
                        ("dense_us", "dense LU us", ".1f"),
                        ("package_solve_us", "solve us", ".1f"),
                        ("dense_solve_us", "dense solve us", ".1f")],
                 title=f"chain solve (dense up to {linalg.DENSE_LIMIT_NODES} nodes, "
                       "cyclic reduction above)")
    info["load_average_end"] = common.machine()["load_average"]
    result = {"machine": info, "dense_limit_nodes": linalg.DENSE_LIMIT_NODES, "rows": rows}
    common.save_json(out, "chain_solve", result)
    return result


if __name__ == "__main__":
    sys.exit(common.standalone(run)())
