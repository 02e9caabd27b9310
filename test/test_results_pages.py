"""The results pages' tables are generated, not typed: each block of docs/results/*.md is rendered from a
recorded result file (docs/results/data/*.json, written by the study commands and by `make bench`, with
its date, commit and machine) by tools/docs_reference.py, the same generator as the reference pages; the
pages in the repository are those the recorded files give, byte for byte, and a changed recorded file makes
``--check`` fail. A study's recorded tables are its report's, byte for byte."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import REPO_ROOT

sys.path.insert(0, str(REPO_ROOT / "tools"))
import docs_reference

from bracing_experiments.recorded import provenance, record_report, render_table, report_tables

RESULTS = REPO_ROOT / "docs" / "results"


def _blocks(text: str) -> list[re.Match[str]]:
    return list(docs_reference.RESULTS_BLOCK.finditer(text))


def test_the_results_tables_are_those_the_recorded_files_give() -> None:
    pages = docs_reference.results_pages()
    assert set(pages) == set(RESULTS.glob("*.md"))
    blocks = {page.name: _blocks(text) for page, text in pages.items()}
    assert len(blocks["performance.md"]) >= 3 and len(blocks["index.md"]) >= 3
    for page, text in pages.items():
        assert page.read_text() == text, f"{page} is stale: run python tools/docs_reference.py"
        for block in _blocks(text):  # each block a table (or a study's conclusion) and the provenance of its file
            table = block["body"].startswith("| ") and "\n|---|" in block["body"]
            assert table or block["body"].startswith("**"), block["body"][:200]
            recorded = json.loads((RESULTS / "data" / block["file"]).read_text())["recorded"]
            assert f"Recorded {recorded['date']}, commit {recorded['commit']}" in block["body"]


def test_a_changed_recorded_file_makes_the_check_fail(tmp_path: Path) -> None:
    data = tmp_path / "data"
    shutil.copytree(RESULTS / "data", data)
    assert docs_reference.main(["--check"], data_dir=data) == 0  # the copy: every page current

    bench = json.loads((data / "bench.json").read_text())
    bench["engine_vs_mujoco"] = 0.8235
    (data / "bench.json").write_text(json.dumps(bench))
    assert docs_reference.main(["--check"], data_dir=data) == 1
    page = docs_reference.results_pages(data)[RESULTS / "performance.md"]
    assert "| **engine / MuJoCo** | 0.824 | >= 2 |" in page

    study = json.loads((data / "paper_study.json").read_text())
    (data / "bench.json").write_text((RESULTS / "data" / "bench.json").read_text())
    study["tables"]["1-braced-passive-and-free"]["rows"][0][5] = "1"
    (data / "paper_study.json").write_text(json.dumps(study))
    assert docs_reference.main(["--check"], data_dir=data) == 1


def test_a_recorded_report_renders_its_tables_byte_for_byte(tmp_path: Path) -> None:
    """The paper study's report as a fresh clone produces it (docs/paper_study/report.md): every table
    recorded, keyed by the heading above it, and rendered back exactly as the report printed it."""
    report = tmp_path / "report.md"
    shutil.copy(REPO_ROOT / "docs" / "paper_study" / "report.md", report)
    path = record_report(report, "paper", Path("paper_4link.yaml"), REPO_ROOT)
    recorded = json.loads(path.read_text())
    text = report.read_text()
    printed = re.findall(r"(?m)^(\|.*\|\n\|(?:---\|)+\n(?:\|.*\|\n?)*)", text)
    assert len(recorded["tables"]) == len(printed) >= 3
    for table, block in zip(recorded["tables"].values(), printed, strict=True):
        assert render_table(table) == block.rstrip("\n")
    assert recorded["study"] == "paper" and recorded["config"] == "paper_4link.yaml"
    assert recorded["recorded"]["commit"] == provenance(REPO_ROOT)["commit"]
    assert recorded["recorded"]["machine"]["cores"] >= 1


def test_tables_are_keyed_by_the_heading_above_them() -> None:
    text = "# A\n\n**1. First**, words\n\n| x | y |\n|---|---|\n| 1 | a b |\n\n| z |\n|---|\n| 2 |\n"
    text += "\n## B c\n\n| w |\n|---|\n"
    tables = report_tables(text)
    assert tables == {
        "1-first": {"header": ["x", "y"], "rows": [["1", "a b"]]},
        "1-first-2": {"header": ["z"], "rows": [["2"]]},
        "b-c": {"header": ["w"], "rows": []},
    }


def test_a_recording_names_its_commit_and_whether_the_code_differed(tmp_path: Path) -> None:
    """``dirty`` when tracked code (src, config, bench, tools) differs from the commit; a docs edit is not."""

    def git(*args: str) -> str:
        done = subprocess.run(["git", "-C", str(tmp_path), *args], capture_output=True, text=True, check=True)
        return done.stdout.strip()

    git("init", "-q")
    for path in ("src/law.py", "docs/page.md"):
        (tmp_path / path).parent.mkdir(parents=True)
        (tmp_path / path).write_text("x\n")
    git("add", ".")
    git("-c", "user.name=t", "-c", "user.email=t@t", "commit", "-q", "-m", "one")
    head = git("rev-parse", "--short=7", "HEAD")
    assert (provenance(tmp_path)["commit"], provenance(tmp_path)["dirty"]) == (head, False)
    (tmp_path / "docs" / "page.md").write_text("y\n")
    assert provenance(tmp_path)["dirty"] is False
    (tmp_path / "src" / "law.py").write_text("y\n")
    assert provenance(tmp_path)["dirty"] is True
    assert provenance(tmp_path / "src")["commit"] == head  # from anywhere in the checkout
    outside = tmp_path.parent / "not_a_checkout"
    outside.mkdir(exist_ok=True)
    assert (provenance(outside)["commit"], provenance(outside)["dirty"]) == (None, None)


@pytest.mark.parametrize(
    ("file", "table"),
    [
        ("optimize_paper_4link.json", "optimum-2"),  # bracing-optimize's tables.json
        ("ur5_table.json", "runs"),  # bracing-sweep --record
        ("tiago_table.json", "runs"),  # bracing-sweep --record, the three variants zipped
        ("engine_comparison.json", "engine-comparison"),  # tools/engine_comparison.py --record
        ("tiago_cmd_vel.json", "tiago-cmd-vel"),  # tools/tiago_cmd_vel.py --record
        ("robustness.json", "1-link-masses-and-inertias-2"),  # a study's table beside the one its section renders
    ],
)
def test_each_recorded_run_renders_its_page_block_and_a_changed_cell_fails_the_check(
    tmp_path: Path, file: str, table: str
) -> None:
    data = tmp_path / "data"
    shutil.copytree(RESULTS / "data", data)
    recorded = json.loads((data / file).read_text())
    page = docs_reference.results_pages(data)[RESULTS / "index.md"]
    assert f"<!-- results: {file} {table} -->\n{render_table(recorded['tables'][table])}\n" in page
    assert page == (RESULTS / "index.md").read_text()
    recorded["tables"][table]["rows"][0][1] += "0"
    (data / file).write_text(json.dumps(recorded))
    assert docs_reference.main(["--check"], data_dir=data) == 1
