"""The README's and the docs' examples do what they say: the nodes started by hand
(docs/tutorials/by-hand.md) run the duration their second params file gives (a ``-p duration:=2.0``
ran the file's 10 s), in a domain of their own, recorded by the project's recorder; and ``make run``
is told one way."""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

from conftest import REPO_ROOT
from ros_helpers import hold_test_domain

from bracing_analysis.bag import read_series

README = REPO_ROOT / "README.md"
BY_HAND = REPO_ROOT / "docs" / "tutorials" / "by-hand.md"
PAGES = [README, *sorted(page for page in (REPO_ROOT / "docs").rglob("*.md") if "_build" not in page.parts)]
"""The README and every page of the docs site (their examples are read as one)."""
BEGIN, END = "<!-- by-hand: begin", "<!-- by-hand: end -->"


def by_hand_block() -> str:
    """The shell block between the by-hand tutorial's markers."""
    text = BY_HAND.read_text()
    assert BEGIN in text and END in text, "the by-hand tutorial has no runnable block"
    block = text.split(BEGIN)[1].split(END)[0]
    return block.split("```sh\n")[1].split("```")[0]


def code_lines() -> list[str]:
    """Every line of the code blocks of the README and the docs."""
    text = "\n".join(page.read_text() for page in PAGES)
    blocks = re.findall(r"```[a-z]*\n(.*?)```", text, flags=re.DOTALL)
    return [line for block in blocks for line in block.splitlines()]


def test_the_nodes_by_hand_run_and_record_what_the_readme_says(tmp_path: Path) -> None:
    domain = hold_test_domain()
    script = by_hand_block()
    run_dir = tmp_path / "by_hand"
    for old, new in (("ROS_DOMAIN_ID=101", f"ROS_DOMAIN_ID={domain}"), ("run=out/by_hand", f"run={run_dir}")):
        assert old in script
        script = script.replace(old, new)
    done = subprocess.run(
        ["bash", "-c", "set -e\n" + script], cwd=REPO_ROOT, capture_output=True, text=True, timeout=300
    )
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    assert "finished at t = 2.000000 s" in done.stdout + done.stderr  # the second file's duration, not 10 s
    counts = read_series(run_dir / "bag").topic_counts
    assert counts["/joint_states"] == counts["/motor_command"] == 2001  # every step, the first included
    assert (run_dir / "summary.json").is_file() and (run_dir / "hand_y.png").is_file()


def test_no_readme_example_overrides_the_nodes_with_p() -> None:
    """rcl lets a node's own section of the params file win over a global ``-p``: the node examples
    of the README and the docs use a second params file instead."""
    nodes = ("bracing-simulator", "bracing-controller", "ros2 run bracing_sim", "ros2 run bracing_controller")
    lines = [line for line in code_lines() if any(node in line for node in nodes)]
    assert lines, "neither the README nor the docs start a node"
    assert [line for line in lines if re.search(r"\s-p\s", line)] == []


def test_make_run_is_told_one_way() -> None:
    """``make run`` makes three runs (bracing_bringup.paper_run.RUNS), wherever the README or the docs
    say it."""
    for page in PAGES:
        assert not re.search(r"both runs|two runs'|the two runs\b", page.read_text()), page
    for page in (README, REPO_ROOT / "docs" / "getting-started.md"):
        text = page.read_text()
        assert "make run     # set up if needed, run the paper scenario braced, passive and in free space" in text
        assert "`make run` runs the paper's task three times" in text
