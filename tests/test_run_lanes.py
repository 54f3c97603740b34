"""The two-lane test runner (tests/run_lanes.py) and the commands that use it: the counts
it sums are read from pytest's own summary line, and the README's test command is the one
`.ci/run` runs."""
import importlib.util
import re

from conftest import REPO_ROOT

_spec = importlib.util.spec_from_file_location("run_lanes", REPO_ROOT / "tests" / "run_lanes.py")
run_lanes = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(run_lanes)


def test_counts_come_from_the_last_summary_line():
    log = ("....F.s\n"
           "FAILED tests/test_x.py::test_y - assert 1 == 2\n"
           "3 passed, 1 failed, 2 skipped, 1 error, 4 deselected in 2.50s\n")
    counts = run_lanes.lane_counts(log)
    assert (counts["passed"], counts["failed"], counts["skipped"], counts["errors"]) == (3, 1, 2, 1)
    assert run_lanes.lane_counts("no tests ran in 0.01s\n")["passed"] == 0


def test_readme_test_command_is_what_ci_runs():
    ci = (REPO_ROOT / ".ci" / "run").read_text(encoding="utf-8")
    readme = (REPO_ROOT / "README.md").read_text(encoding="utf-8")
    extra = re.search(r"pip install -q -e '(\.\[[a-z,]+\])'", ci).group(1)
    command = [line for line in ci.splitlines() if line.startswith("python tests/")][-1]
    assert f"pip install -e '{extra}' && {command}" in readme
