"""Run the whole test suite in two pytest processes side by side, one per core.

    python tests/run_lanes.py [extra pytest arguments]

Lane 1 runs the tests not marked ``slow``, lane 2 the ``slow`` ones (example and notebook
runs, long rollouts): 22.4 and 21.6 min (a fresh clone) for the 1402 other and 120 slow tests on a
2-core AMD EPYC VM with the test compile flags of ``tests/conftest.py``. Each lane's
output goes to a log file and is printed whole when the lane ends (never interleaved),
with its 25 slowest tests;
the last line sums both lanes in pytest's words
(``total: N passed, N failed, N skipped``). The exit status is 0 only when both lanes pass
(a lane that selects no test at all, pytest's status 5, counts as passed). Each lane runs
with ``OPENBLAS_NUM_THREADS=1`` unless the environment sets it: one process per core, so
OpenBLAS's own threads in JAX's dense factorizations would only compete with the other
lane (``simsoft_jax.math.blas_threads``).
"""
from __future__ import annotations

import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
LANES = (("not slow", "-m", "not slow"), ("slow", "-m", "slow"))
OUTCOMES = ("passed", "failed", "errors", "skipped", "xfailed", "xpassed")
NO_TESTS_COLLECTED = 5
SLOWEST = 25            # each lane's log ends with its slowest tests (pytest --durations)


def lane_counts(text: str) -> dict[str, int]:
    """Counts from the last pytest summary line of ``text`` (``3 passed, 1 skipped in
    2.0s``); ``error`` and ``errors`` both count as errors."""
    counts = {key: 0 for key in OUTCOMES}
    summaries = [line for line in text.splitlines()
                 if re.search(r"\d+ (passed|failed|errors?|skipped|deselected)", line)]
    if summaries:
        for number, word in re.findall(r"(\d+) (\w+)", summaries[-1]):
            word = "errors" if word == "error" else word
            if word in counts:
                counts[word] += int(number)
    return counts


def main(extra: list[str]) -> int:
    logs = Path(tempfile.mkdtemp(prefix="simsoft_lanes_"))
    started = time.perf_counter()
    procs = []
    env = {"OPENBLAS_NUM_THREADS": "1", **os.environ}
    for name, *selection in LANES:
        log = open(logs / f"{name.replace(' ', '_')}.log", "w", encoding="utf-8")
        proc = subprocess.Popen([sys.executable, "-m", "pytest", "-q", f"--durations={SLOWEST}",
                                 *selection, *extra],
                                cwd=ROOT, stdout=log, stderr=subprocess.STDOUT, env=env)
        procs.append((name, proc, log))
    total = {key: 0 for key in OUTCOMES}
    status = 0
    for name, proc, log in procs:
        code = proc.wait()
        log.close()
        text = Path(log.name).read_text(encoding="utf-8", errors="replace")
        print(f"==================== lane '{name}' (exit {code}) ====================")
        print(text, flush=True)
        for key, value in lane_counts(text).items():
            total[key] += value
        if code not in (0, NO_TESTS_COLLECTED):
            status = 1
    failed = total["failed"] + total["errors"]
    if failed == 0 and total["passed"] == 0:
        status = 1
    print(f"both lanes took {time.perf_counter() - started:.0f} s; logs in {logs}")
    print(f"total: {total['passed']} passed, {failed} failed, {total['skipped']} skipped")
    return status


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
