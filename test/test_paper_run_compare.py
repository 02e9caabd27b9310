"""make run's comparison (bracing_bringup.paper_run) draws from what each run's report read: every bag is read
once, and compare.md and the compare_*.png are byte for byte those drawn from the bags read again."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest
import ros_helpers

from bracing_analysis.bag import read_series
from bracing_analysis.compare import COMPARE_MD, write_comparison
from bracing_bringup.paper_run import BASELINE
from bracing_core.variants import RUNS

READS_COUNTED = """
import sys
import bracing_analysis.bag as bag
from bracing_bringup.paper_run import main

reads = []
read_series = bag.read_series
bag.read_series = lambda path, *a, **k: reads.append(str(path)) or read_series(path, *a, **k)
code = main(sys.argv[1:])
print("bags read:", *reads, sep="\\n  ")
sys.exit(code)
"""
"""paper_run with every read_series call counted (the comparison imports it from bag when first used)."""

DURATION_S = "0.05"


@pytest.fixture(scope="module")
def paper_run(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, str]:
    """make run's three runs, short: their directory and what the command printed."""
    out = tmp_path_factory.mktemp("paper_run") / "out"
    argv = [sys.executable, "-c", READS_COUNTED, "--output", str(out), "--duration", DURATION_S]
    done = ros_helpers.run(argv, timeout=600)
    assert done.returncode == 0, done.stdout + done.stderr
    return out, done.stdout


def test_each_bag_is_read_once(paper_run: tuple[Path, str]) -> None:
    out, printed = paper_run
    reads = printed.split("bags read:\n", 1)[1].split()
    assert sorted(reads) == sorted(str(out / run.name / "bag") for run in RUNS)


def test_the_comparison_is_the_one_of_the_bags_read_again(paper_run: tuple[Path, str], tmp_path: Path) -> None:
    out, _ = paper_run
    bags = [out / run.name / "bag" for run in RUNS]
    again = write_comparison(bags, tmp_path, baseline=BASELINE)
    assert [p.name for p in again][-1] == COMPARE_MD and len(again) > 1  # figures, then the table
    for path in again:  # the PNGs too: Agg writes the same bytes for the same data (no timestamp)
        assert (out / path.name).read_bytes() == path.read_bytes(), path.name
    # ... and from the series handed over instead: the same files (the check can tell them apart).
    handed = write_comparison(bags, tmp_path / "handed", baseline=BASELINE, series=[read_series(b) for b in bags])
    assert [(p.name, p.read_bytes()) for p in handed] == [(p.name, p.read_bytes()) for p in again]
    swapped = [read_series(b) for b in reversed(bags)]
    write_comparison(bags, tmp_path / "swapped", baseline=BASELINE, series=swapped)
    assert (tmp_path / "swapped" / COMPARE_MD).read_bytes() != (out / COMPARE_MD).read_bytes()
