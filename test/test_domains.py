"""ROS domain ids are held exclusively while a run lives (domain_coordinator), from 1-100."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from ros_helpers import REPO_ROOT, pair_argv

from bracing_bringup.domains import hold_domain, is_held_elsewhere

HOLD = """
from bracing_bringup.domains import hold_domain
with hold_domain() as d:
    print(d.domain_id, flush=True)
    input()
"""


def test_held_ids_are_distinct_within_the_safe_range_and_free_again_after() -> None:
    with hold_domain() as a, hold_domain() as b:
        assert a.exclusive and b.exclusive
        assert a.domain_id != b.domain_id
        assert 1 <= a.domain_id <= 100 and 1 <= b.domain_id <= 100
    assert not is_held_elsewhere(a.domain_id)


def test_another_process_never_gets_a_held_id() -> None:
    """The hold is machine-wide (a bound port), not per process."""
    other = subprocess.Popen(
        [sys.executable, "-c", HOLD], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, cwd=REPO_ROOT
    )
    try:
        assert other.stdout is not None
        theirs = int(other.stdout.readline())
        assert is_held_elsewhere(theirs)
        with hold_domain() as mine:
            assert mine.domain_id != theirs
        with hold_domain(theirs) as asked:  # an explicit id wins, but is not exclusive
            assert asked.domain_id == theirs and not asked.exclusive
    finally:
        other.communicate("\n", timeout=10)
    assert not is_held_elsewhere(theirs)  # released when its holder ends


def test_pair_says_when_its_domain_id_is_held_by_another_run(tmp_path: Path) -> None:
    with hold_domain() as held:
        done = subprocess.run(
            [*pair_argv(tmp_path / "run", "--duration", "0.05"), "--domain-id", str(held.domain_id)],
            capture_output=True,
            text=True,
            timeout=120,
            cwd=REPO_ROOT,
        )
    assert done.returncode == 0, done.stdout + done.stderr
    assert f"ROS_DOMAIN_ID={held.domain_id} (--domain-id) is held by another run" in done.stderr
