"""The shipped data (simsoft_jax/data): found through the package, documented, and the only
data the project reads (nothing reads a folder beside the repository)."""
import csv
import re
from pathlib import Path

import pytest

import simsoft_jax
from simsoft_jax.data_files import DATA_SETS, data_path

REPO = Path(__file__).resolve().parents[1]


def test_every_data_set_is_in_the_package_with_a_readme():
    package = Path(simsoft_jax.__file__).parent
    for name in DATA_SETS:
        folder = data_path(*name.split("/"))
        assert folder.is_dir() and folder.resolve().is_relative_to(package.resolve())
        readme = (folder / "README.md").read_text()
        assert "measured" in readme.lower() or "model output" in readme.lower()
        for table in folder.glob("*.csv"):
            with table.open(newline="") as handle:
                assert len(list(csv.DictReader(handle))) > 0, table


def test_pazy_measurements_are_the_tabulated_values():
    """52 measured rows; the mm column is the m column times 1000."""
    with data_path("real", "pazy_wing_technion", "tip_mass_sweep_measured.csv").open() as h:
        rows = list(csv.DictReader(h))
    assert len(rows) == 52
    for r in rows:
        assert float(r["tip_uz_mm"]) == pytest.approx(1e3 * float(r["tip_uz_m"]), abs=1e-9)


def test_unknown_name_names_the_data_sets():
    with pytest.raises(FileNotFoundError, match="pazy_wing_technion"):
        data_path("real", "no_such_set")


def test_nothing_reads_a_shared_folder_beside_the_repository():
    pattern = re.compile(r"shared/data|[\"']shared[\"']\s*/")
    offenders = []
    for folder in ("simsoft_jax", "examples", "notebooks", "tests", "benchmarks"):
        for path in (REPO / folder).rglob("*"):
            if path.suffix in (".py", ".ipynb", ".toml", ".md") and path != Path(__file__):
                if pattern.search(path.read_text(errors="ignore")):
                    offenders.append(str(path.relative_to(REPO)))
    assert not offenders, offenders
