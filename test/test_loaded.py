"""``make test-loaded``'s mechanism (tools/loaded.sh): CPU-bound burners run beside the command, the
command's exit status is the script's, and the burners are gone when the script ends, however it ends.

One burner only here: the suite shares its machine, and one is enough to show the mechanism.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
LOADED = ROOT / "tools" / "loaded.sh"
GIVE_UP_S = 60.0
"""[s] a bound on waits that end by cause (a burner's first CPU tick, its exit): only a hang reaches it."""

# Run by the command under test: waits (by cause) until every burner has used CPU time, prints their ticks.
CHECK_BURNERS = """
import pathlib, sys, time
pids = pathlib.Path(sys.argv[1]).read_text().split()
def cpu_ticks(pid):  # utime + stime, fields 14 and 15 of /proc/PID/stat
    fields = pathlib.Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return int(fields[11]) + int(fields[12])
start = {pid: cpu_ticks(pid) for pid in pids}
give_up = time.monotonic() + float(sys.argv[2])
while any(cpu_ticks(pid) == start[pid] for pid in pids) and time.monotonic() < give_up:
    time.sleep(0.05)
print(" ".join(str(cpu_ticks(pid) - start[pid]) for pid in pids))
sys.exit(3)
"""


def alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except FileNotFoundError:
        return False
    return state != "Z"


def wait_until_gone(pids: list[int]) -> list[int]:
    give_up = time.monotonic() + GIVE_UP_S
    while any(alive(pid) for pid in pids) and time.monotonic() < give_up:
        time.sleep(0.05)
    return [pid for pid in pids if alive(pid)]


def test_burners_run_beside_the_command_and_are_gone_after(tmp_path: Path) -> None:
    pids_file = tmp_path / "burners"
    env = dict(os.environ, LOADED_BURNERS="1", LOADED_PIDS_FILE=str(pids_file))
    argv = ["bash", str(LOADED), sys.executable, "-c", CHECK_BURNERS, str(pids_file), str(GIVE_UP_S)]
    done = subprocess.run(argv, env=env, capture_output=True, text=True, timeout=2 * GIVE_UP_S)
    assert done.returncode == 3, done.stderr  # the command's status, not the burners'
    burners = [int(pid) for pid in pids_file.read_text().split()]
    assert len(burners) == 1 and "1 CPU-bound burner(s) beside" in done.stderr
    assert all(int(ticks) > 0 for ticks in done.stdout.split()), done.stdout  # it burnt CPU while the command ran
    assert not any(alive(pid) for pid in burners)  # stopped before the script returned


def test_burners_stop_when_the_script_is_killed(tmp_path: Path) -> None:
    """SIGKILL runs no trap: each burner sees its script gone and ends by itself."""
    pids_file, command_pid = tmp_path / "burners", tmp_path / "command"
    env = dict(os.environ, LOADED_BURNERS="1", LOADED_PIDS_FILE=str(pids_file))
    command = f"echo $$ > {command_pid}; exec sleep {GIVE_UP_S:g}"
    script = subprocess.Popen(["bash", str(LOADED), "bash", "-c", command], env=env, stderr=subprocess.DEVNULL)
    try:
        give_up = time.monotonic() + GIVE_UP_S
        while not (command_pid.exists() and command_pid.read_text().strip()) and time.monotonic() < give_up:
            time.sleep(0.05)
        burners = [int(pid) for pid in pids_file.read_text().split()]
        assert burners and all(alive(pid) for pid in burners)
        script.kill()
        script.wait()
        assert wait_until_gone(burners) == []
    finally:
        if command_pid.exists() and command_pid.read_text().strip():
            os.kill(int(command_pid.read_text()), signal.SIGKILL)  # the orphaned command (the script cannot)
        if script.poll() is None:
            script.kill()


def test_make_test_loaded_runs_pytest_through_it() -> None:
    """The target's recipe (make -n prints it without running it): PYTEST_ARGS, if given, replaces the suite."""
    # as make runs this test: its command-line variables (PYTEST_ARGS) are in the environment and MAKEFLAGS
    env = {k: v for k, v in os.environ.items() if k not in ("MAKEFLAGS", "MFLAGS", "MAKELEVEL", "PYTEST_ARGS")}

    def recipe(*args: str) -> list[str]:
        done = subprocess.run(["make", "-n", "test-loaded", *args], cwd=ROOT, env=env, capture_output=True, text=True)
        assert done.returncode == 0, done.stderr
        return done.stdout.splitlines()

    assert recipe("PYTEST_ARGS=test/test_x.py -k y")[-1].endswith(
        "bash tools/loaded.sh python -m pytest test/test_x.py -k y"
    )
    assert recipe()[-1].endswith("bash tools/loaded.sh python -m pytest test")
