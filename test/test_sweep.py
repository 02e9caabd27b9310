"""bracing-sweep and the --set overrides: parsing and validation, parallel runs equal to the same
runs one by one, failures as rows, Ctrl-C and resume, and a Dask cluster losing a worker."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow.parquet as pq
import pytest
from ctrl_c import main_interrupted_after

from bracing_bringup.pair import parse_args
from bracing_bringup.run_plan import command_line
from bracing_core.overrides import (
    CONTROLLER,
    SIMULATOR,
    destination,
    node_params,
    parse_assignment,
    parse_single,
    route,
    split_values,
)
from bracing_core.params import ConfigError
from bracing_core.rollout import build_scenario, run_closed_loop
from bracing_experiments import sweep
from bracing_experiments.executors import STOP_REQUESTED, DaskExecutor, LocalExecutor
from bracing_experiments.experiment import STATUS_FAILED, STATUS_OK, RunOutcome, execute_run
from bracing_experiments.running import RESULTS_CSV, RESULTS_PARQUET, ROW_FILE, ResultsStore, run_sweep
from bracing_experiments.sweep import build_specs, combinations

REPO_ROOT = Path(__file__).resolve().parents[1]
PAPER_YAML = REPO_ROOT / "config" / "paper_4link.yaml"
DASK = Path(sys.executable).parent / "dask"


# -- --set -------------------------------------------------------------------------------------------
def test_values_split_on_commas_outside_brackets_and_quotes() -> None:
    assert split_values("voltage,torque") == ["voltage", "torque"]
    assert split_values("[300,300],[150,150]") == ["[300,300]", "[150,150]"]
    assert split_values("[elbow],[]") == ["[elbow]", "[]"]
    assert split_values("'a,b',c") == ["'a,b'", "c"]


def test_values_parse_as_yaml_with_numbers_in_exponent_form() -> None:
    assert parse_assignment("hand.kp=[300,300],[1.5e2,150]") == ("hand.kp", [[300, 300], [150.0, 150]])
    assert parse_assignment("gravity_compensation=true,false") == ("gravity_compensation", [True, False])
    assert parse_assignment("contacts.names=[]") == ("contacts.names", [[]])
    assert parse_assignment("baumgarte=1e-3") == ("baumgarte", [0.001])  # YAML 1.1 would give a string
    assert parse_assignment("input_mode=torque") == ("input_mode", ["torque"])


def test_keys_go_to_the_nodes_that_read_them() -> None:
    assert destination("input_mode") == "shared"
    assert destination("contacts.elbow.desired_normal_force") == "shared"
    assert destination("contacts.wrist.frame") == "shared"  # any contact name
    assert destination("duration") == SIMULATOR
    assert destination("hand.kp") == CONTROLLER
    routed = route({"hand.kp": [1, 1], "duration": 2.0, "input_mode": "torque"})
    assert routed.for_node(SIMULATOR) == {"input_mode": "torque", "duration": 2.0}
    assert routed.for_node(CONTROLLER) == {"input_mode": "torque", "hand.kp": [1, 1]}


@pytest.mark.parametrize(
    ("sets", "named"),
    [
        (["hand.kpp=1,2"], "hand.kpp"),  # unknown key
        (["hand.kp=[300,300],[1,2,3]"], "hand.kp"),  # wrong length in the second value
        (["input_mode=voltage,torqe"], "input_mode"),  # not a choice
        (["contacts.elbow.friction=abc"], "contacts.elbow.friction"),  # wrong type
        (["contacts.elbow.kp=[1],[2]", "hand.kp=[1,1],[2,2],[3,3]"], "hand.kp"),  # --zip lengths differ
    ],
)
def test_a_bad_set_fails_before_any_run_naming_the_key(sets: list[str], named: str) -> None:
    with pytest.raises(ConfigError, match=named.replace(".", r"\.")):
        build_specs(PAPER_YAML, sets, zipped=len(sets) == 2, duration=1.0)


def test_grid_and_zip() -> None:
    values: dict[str, list[Any]] = {"a": [1, 2], "b": ["x", "y"]}
    assert combinations(values) == [{"a": 1, "b": "x"}, {"a": 1, "b": "y"}, {"a": 2, "b": "x"}, {"a": 2, "b": "y"}]
    assert combinations(values, zipped=True) == [{"a": 1, "b": "x"}, {"a": 2, "b": "y"}]


def test_pair_takes_the_same_overrides() -> None:
    options = parse_args(
        ["--config", str(PAPER_YAML), "--set", "hand.kp=[150,150]", "--set", "contacts.elbow.desired_normal_force=5"]
    )
    given = node_params(options.config, command_line(options))
    controller = given[CONTROLLER]
    assert controller["hand.kp"] == [150, 150]
    assert controller["contacts.elbow.desired_normal_force"] == 5
    assert given[SIMULATOR]["contacts.elbow.desired_normal_force"] == 5
    assert "hand.kp" not in given[SIMULATOR]
    with pytest.raises(ConfigError, match="one value expected"):
        parse_single(["hand.kp=[1,1],[2,2]"])


# -- local sweeps --------------------------------------------------------------------------------------
GRID = ["input_mode=voltage,torque", "contacts.elbow.desired_normal_force=10,5"]


def test_a_4_run_sweep_gives_the_numbers_of_the_same_runs_one_by_one(tmp_path: Path) -> None:
    specs = build_specs(PAPER_YAML, GRID, zipped=False, duration=2.0)
    assert len(specs) == 4 and len({s.run_id for s in specs}) == 4
    with LocalExecutor(2) as executor:
        result = run_sweep(specs, tmp_path, executor, progress=False)
    assert result.ran == 4 and not result.lost
    table = pq.read_table(tmp_path / RESULTS_PARQUET).to_pylist()
    assert [row["run_id"] for row in table] == [s.run_id for s in specs]  # the grid's order
    assert {(row["input_mode"], row["contacts.elbow.desired_normal_force"]) for row in table} == {
        ("voltage", 10),
        ("voltage", 5),
        ("torque", 10),
        ("torque", 5),
    }
    store = ResultsStore(tmp_path)
    for spec, row in zip(specs, table, strict=True):
        assert row["status"] == STATUS_OK
        # One by one through the existing in-process path: the same trajectory, to the last bit.
        mode, force = spec.varied["input_mode"], spec.varied["contacts.elbow.desired_normal_force"]
        alone = run_closed_loop(
            build_scenario(PAPER_YAML, shared={"input_mode": mode, "contacts.elbow.desired_normal_force": force}), 2.0
        )
        with np.load(store.run_dir(spec.run_id) / "arrays.npz") as arrays:
            assert np.array_equal(arrays["position"][:-1], alone.position)
            assert np.array_equal(arrays["normal_force"][:-1], alone.normal_force)
            assert arrays["energy_consumed"][-1] == alone.energy.consumed
        # ... and every metric of the row equals that of the same run executed serially here.
        serial = execute_run(spec).row
        for key, value in serial.items():
            if key not in ("wall_time_s", "real_time_factor", "worker"):
                assert row[key] == value, key
        assert row["energy_consumed_j"] == alone.energy.consumed
        assert row["sim_time_s"] == pytest.approx(2.0)
        summary = json.loads((store.run_dir(spec.run_id) / "summary.json").read_text())
        assert summary["hand_rms_error_m"] == row["hand_rms_error_m"]
    forces = {
        (r["input_mode"]): r["normal_force_max_error_n"] for r in table if r["contacts.elbow.desired_normal_force"] == 5
    }
    assert forces["torque"] < 1e-9 < 1.0 < forces["voltage"]  # eq. 40: torque input holds f_nd exactly
    csv_lines = (tmp_path / RESULTS_CSV).read_text().splitlines()
    assert len(csv_lines) == 5 and csv_lines[0].startswith('"run_id","status","error"')

    # The same command again: nothing to do, the same table.
    with LocalExecutor(1) as executor:
        again = run_sweep(specs, tmp_path, executor, progress=False)
    assert again.ran == 0 and again.skipped == 4
    assert pq.read_table(tmp_path / RESULTS_PARQUET).to_pylist() == table


def test_a_failing_run_is_a_row_and_the_sweep_goes_on(tmp_path: Path) -> None:
    # An elbow 5 cm below the plane is an infeasible start: a row with that error; the other runs run.
    specs = build_specs(PAPER_YAML, ["contacts.elbow.offset=0.0,0.05", "input_mode=voltage,torque"], False, 0.3)
    with LocalExecutor(2) as executor:
        result = run_sweep(specs, tmp_path, executor, progress=False)
    assert result.failed == 2
    table = pq.read_table(tmp_path / RESULTS_PARQUET).to_pylist()
    rows = {(r["contacts.elbow.offset"], r["input_mode"]): r for r in table}
    assert len(rows) == 4
    for mode in ("voltage", "torque"):
        assert rows[(0.0, mode)]["status"] == STATUS_OK
        failed = rows[(0.05, mode)]
        assert failed["status"] == STATUS_FAILED and "infeasible start" in failed["error"]
        assert failed["energy_consumed_j"] is None  # the column exists (other rows), the value is null


def _sweep_cli(output: Path, *extra: str) -> list[str]:
    return [
        sys.executable,
        "-m",
        "bracing_experiments.sweep",
        "--config",
        str(PAPER_YAML),
        "--output",
        str(output),
        "--no-progress",
        *extra,
    ]


def test_ctrl_c_keeps_every_finished_row_and_the_same_command_resumes(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """The command, Ctrl-C'd once its second row is saved (a SIGINT to its process then, whatever the
    machine's pace): exit 130, exactly those two rows in the table, and the same command again runs the
    other six, keeping the two."""
    sets = ["--set", "contacts.elbow.desired_normal_force=4,6,8,10,12,14,16,18", "--duration", "2", "--workers", "1"]
    argv = _sweep_cli(tmp_path, *sets)
    code, saved = main_interrupted_after(sweep.main, argv[3:], monkeypatch, ResultsStore, "save", 2)
    err = capsys.readouterr().err
    assert code == 130, err
    finished = {p.parent.name for p in tmp_path.glob(f"runs/*/{ROW_FILE}")}
    assert finished == {outcome.row["run_id"] for (outcome,) in saved} and len(finished) == 2
    table = pq.read_table(tmp_path / RESULTS_PARQUET).to_pylist()
    assert {row["run_id"] for row in table} == finished  # every finished row is in the table
    assert "interrupted" in err

    done = subprocess.run(argv, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert "6 run now, 2 done before" in done.stdout
    table = pq.read_table(tmp_path / RESULTS_PARQUET).to_pylist()
    assert len(table) == 8 and len({row["run_id"] for row in table}) == 8
    assert all(row["status"] == STATUS_OK for row in table)


def test_sweep_cli_rejects_a_bad_set_before_running(tmp_path: Path) -> None:
    done = subprocess.run(
        _sweep_cli(tmp_path, "--set", "hand.kp=[300,300],[1,2,3]"), capture_output=True, text=True, timeout=60
    )
    assert done.returncode == 2
    assert "hand.kp" in done.stderr and "expected 2 values" in done.stderr
    assert not (tmp_path / "runs").exists()


def test_record_writes_the_runs_varied_values_and_chosen_metrics_with_provenance(tmp_path: Path) -> None:
    """--record FILE --columns: one row per run (the varied value, then each metric as the table has it, a failed
    run's error), the date, commit and machine; a misspelt metric refused (exit 2)."""
    record, columns = tmp_path / "recorded.json", "contacts.elbow.normal_force_max_n,energy_consumed_j"
    sets = ["--set", "contacts.elbow.offset=0.0,0.05", "--duration", "0.3", "--workers", "1"]
    done = subprocess.run(
        _sweep_cli(tmp_path / "out", *sets, "--record", str(record), "--columns", columns),
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 1, done.stderr  # the 5 cm offset is an infeasible start: a failed row
    recorded = json.loads(record.read_text())
    assert recorded["study"] == "sweep" and recorded["config"] == PAPER_YAML.name
    assert set(recorded["recorded"]) == {"date", "time_utc", "commit", "dirty", "machine"}
    table = recorded["tables"]["runs"]
    assert table["header"] == ["contacts.elbow.offset", *columns.split(",")]
    ok = pq.read_table(tmp_path / "out" / RESULTS_PARQUET).to_pylist()[0]
    assert table["rows"][0] == ["0", f"{ok['contacts.elbow.normal_force_max_n']:.4g}", f"{ok['energy_consumed_j']:.4g}"]
    assert table["rows"][1][0] == "0.05" and table["rows"][1][1].startswith("failed: ") and table["rows"][1][2] == ""
    misspelt = subprocess.run(
        _sweep_cli(tmp_path / "out", *sets, "--record", str(record), "--columns", "energy_j"),
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert misspelt.returncode == 2 and "energy_j" in misspelt.stderr


# -- Dask ------------------------------------------------------------------------------------------------
def _kill_group(proc: subprocess.Popen[bytes]) -> None:
    if proc.poll() is None:
        try:
            os.killpg(proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
    proc.wait(10)


@pytest.fixture
def dask_cluster(tmp_path: Path) -> Iterator[tuple[str, list[subprocess.Popen[bytes]]]]:
    """A scheduler and two single-threaded workers, each its own process group on 127.0.0.1."""
    if not DASK.exists():
        pytest.skip("the dask CLI is not installed")
    scheduler_file = tmp_path / "scheduler.json"
    log = (tmp_path / "dask.log").open("wb")
    common = {"stdout": log, "stderr": subprocess.STDOUT, "start_new_session": True}
    scheduler = subprocess.Popen(
        [
            str(DASK),
            "scheduler",
            "--host",
            "127.0.0.1",
            "--port",
            "0",
            "--no-dashboard",
            "--scheduler-file",
            str(scheduler_file),
            "--idle-timeout",
            "300",
        ],
        **common,  # type: ignore[call-overload]
    )
    workers: list[subprocess.Popen[bytes]] = []
    try:
        deadline = time.monotonic() + 60
        while not scheduler_file.exists():
            assert scheduler.poll() is None and time.monotonic() < deadline, "the scheduler did not start"
            time.sleep(0.1)
        address = json.loads(scheduler_file.read_text())["address"]
        for name in ("a", "b"):
            workers.append(
                subprocess.Popen(
                    [
                        str(DASK),
                        "worker",
                        address,
                        "--nthreads",
                        "1",
                        "--nworkers",
                        "1",
                        "--host",
                        "127.0.0.1",
                        "--no-dashboard",
                        "--name",
                        name,
                        "--death-timeout",
                        "60",
                    ],
                    **common,  # type: ignore[call-overload]
                )
            )
        yield address, workers
    finally:
        for proc in [*workers, scheduler]:
            _kill_group(proc)
        log.close()


def test_dask_cluster_losing_a_worker_mid_sweep_loses_and_doubles_no_row(
    tmp_path: Path, dask_cluster: tuple[str, list[subprocess.Popen[bytes]]]
) -> None:
    import psutil

    address, workers = dask_cluster
    output = tmp_path / "sweep"
    specs = build_specs(PAPER_YAML, ["contacts.elbow.desired_normal_force=4,6,8,10,12,14"], False, 2.0)
    killed_pids: set[int] = set()
    arrived_before_kill: list[str] = []
    in_flight_on_b: list[str] = []  # run ids worker b was executing when it died

    with DaskExecutor(address, timeout=60) as executor:
        client = executor.client
        client.wait_for_workers(2, timeout=120)
        info = client.scheduler_info(n_workers=-1)["workers"]
        b_address = next(addr for addr, worker in info.items() if str(worker.get("name", "")).startswith("b"))

        def kill_worker_b(outcome: RunOutcome) -> None:
            if killed_pids:
                return
            arrived_before_kill.append(str(outcome.row["worker"]))
            deadline = time.monotonic() + 10
            while not in_flight_on_b and time.monotonic() < deadline:  # b may be between two tasks
                keys = client.processing(workers=[b_address]).get(b_address, [])
                in_flight_on_b.extend(str(key).removeprefix("bracing-")[:-9] for key in keys)
                time.sleep(0.02)
            group = psutil.Process(workers[1].pid)
            killed_pids.update({group.pid, *(child.pid for child in group.children(recursive=True))})
            _kill_group(workers[1])  # the nanny and its worker: the machine is gone

        result = run_sweep(specs, output, executor, progress=False, on_outcome=kill_worker_b)
    assert killed_pids, "no result arrived"
    assert in_flight_on_b, "worker b had nothing to lose"
    assert not result.lost and result.ran == 6
    table = pq.read_table(output / RESULTS_PARQUET).to_pylist()
    assert sorted(row["run_id"] for row in table) == sorted(s.run_id for s in specs)  # none lost, none doubled
    assert all(row["status"] == STATUS_OK for row in table)
    assert len(list(output.glob(f"runs/*/{ROW_FILE}"))) == 6
    worker_pid = {row["run_id"]: int(str(row["worker"]).rsplit(":", 1)[1]) for row in table}
    # Only what b had returned before it died carries its pid; what it was executing was redone by a.
    assert sum(pid in killed_pids for pid in worker_pid.values()) <= len(arrived_before_kill)
    assert len(set(worker_pid.values()) - killed_pids) == 1
    for run in in_flight_on_b:
        assert worker_pid[run] not in killed_pids
    # The same numbers as a local run of the same spec.
    local = execute_run(specs[-1]).row
    assert next(r for r in table if r["run_id"] == specs[-1].run_id)["energy_consumed_j"] == local["energy_consumed_j"]


def test_a_diverging_run_stops_as_the_simulator_node_would() -> None:
    (spec,) = build_specs(PAPER_YAML, ["divergence_speed=0.5"], zipped=False, duration=1.0)
    row = execute_run(spec).row
    assert row["status"] == STATUS_FAILED
    assert row["error"].startswith("DivergenceError: joint speed exceeds divergence_speed 0.5")


def _slow_square(x: int) -> int:
    time.sleep(0.05 * x)  # completes in the items' order
    return x * x


def test_a_ctrl_c_dropped_in_a_finalizer_still_stops_the_executor_at_the_next_result() -> None:
    """A SIGINT whose handler runs inside __del__ has its KeyboardInterrupt printed and dropped by
    Python ("Exception ignored in"): CI once saw bracing-optimize run all its trials after Ctrl-C.
    The commands' handler also sets STOP_REQUESTED, and the executor raises at the next result."""
    from bracing_experiments.cli import handle_stop_signals

    class SignalsOnCollection:
        def __del__(self) -> None:
            signal.raise_signal(signal.SIGINT)

    previous = signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM)
    handle_stop_signals()
    seen: list[int] = []
    try:
        with LocalExecutor(workers=1) as executor, pytest.raises(KeyboardInterrupt):
            for item, result, _ in executor.run(_slow_square, [1, 2, 3, 4]):
                seen.append(result if result is not None else -1)
                if item == 1:
                    SignalsOnCollection()  # collected at once: the handler's exception is dropped there
                    seen.append(0)  # ... so this line runs: only the flag is left to stop the loop
    finally:
        signal.signal(signal.SIGINT, previous[0])
        signal.signal(signal.SIGTERM, previous[1])
        STOP_REQUESTED.clear()
    assert seen == [1, 0]  # no result after the one during which Ctrl-C came
