"""What the experiment commands share (bracing-sweep, bracing-optimize, bracing-study and its robustness
study): their options, each defined once with its check, their exit codes, and how they stop and end."""

from __future__ import annotations

import argparse
import signal
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Generic, TypeVar

from bracing_core.params import ConfigError
from bracing_experiments.executors import STOP_REQUESTED, Executor, make_executor
from bracing_experiments.experiment import STATUS_FAILED

EXIT_FAILED = 1
EXIT_CONFIG = 2
EXIT_INTERRUPTED = 130

Built = TypeVar("Built")
Done = TypeVar("Done")


def add_output(parser: argparse.ArgumentParser, what: str) -> None:
    parser.add_argument("--output", required=True, type=Path, help=f"{what} directory (resumable)")


def add_duration(parser: argparse.ArgumentParser, each: str = "run") -> None:
    """--duration, checked by ``check_options``."""
    parser.add_argument("--duration", type=float, default=None, help=f"sim time per {each} [s] (default: the file's)")


def add_executor(parser: argparse.ArgumentParser, exclusive: bool = False) -> None:
    """--workers (checked by ``check_options``) and --scheduler (``executors.make_executor``); ``exclusive``:
    not both."""
    where: Any = parser.add_mutually_exclusive_group() if exclusive else parser
    where.add_argument("--workers", type=int, default=None, help="local worker processes (default: cores)")
    scheduler = "Dask scheduler tcp://HOST:PORT, or 'local' for a Dask LocalCluster"
    where.add_argument("--scheduler", default=None, help=scheduler)


def add_overrides(parser: argparse.ArgumentParser, each: str = "run") -> None:
    """--set KEY=VALUE: a scenario parameter the same in every run (``overrides.parse_single``)."""
    parser.add_argument(
        "--set",
        dest="sets",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help=f"override a scenario parameter in every {each}",
    )


def add_progress(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")


def add_scenario_and_seeds(parser: argparse.ArgumentParser) -> None:
    """--config (any scenario) and --seeds N (runs per condition; checked by ``check_options``): every
    bracing-study form's (bracing_experiments.study_runs seeds the runs and writes runs.csv)."""
    parser.add_argument(
        "--config",
        default=None,
        help="scenario params file, or a scenario's name in config/ (default: 'paper', config/paper_4link.yaml)",
    )
    parser.add_argument(
        "--seeds",
        type=int,
        default=1,
        help="runs per condition, each with its own sensors.noise_seed (the form's first, then the next ones; a run "
        "that draws no noise is run once for every seed); the report gives medians with their spread, and runs.csv "
        "every run (default 1)",
    )


def add_study_options(parser: argparse.ArgumentParser, exclusive_executors: bool = False) -> None:
    """bracing-study's options (every form's): the scenario and the seeds, the report's directory, each
    run's duration, the executor, the overrides of every run and the progress bar."""
    add_scenario_and_seeds(parser)
    add_output(parser, "report")
    add_duration(parser)
    add_executor(parser, exclusive_executors)
    add_overrides(parser)
    add_progress(parser)


def check_options(parser: argparse.ArgumentParser, args: argparse.Namespace) -> None:
    """The checks of --duration, --workers and --seeds (argparse's error: usage, the message, exit 2)."""
    if args.duration is not None and args.duration <= 0:
        parser.error("--duration must be > 0")
    if args.workers is not None and args.workers < 1:
        parser.error("--workers must be >= 1")
    if getattr(args, "seeds", 1) < 1:
        parser.error("--seeds must be >= 1")


def handle_stop_signals() -> None:
    """Ctrl-C and SIGTERM stop a sweep the same way (KeyboardInterrupt), even when started with SIGINT
    ignored (a background job of a non-interactive shell)."""

    def stop(signum: int, frame: object) -> None:
        STOP_REQUESTED.set()  # kept should the KeyboardInterrupt land in a finalizer and be dropped
        raise KeyboardInterrupt

    STOP_REQUESTED.clear()  # a command run again in the same process starts unstopped
    signal.signal(signal.SIGINT, stop)
    signal.signal(signal.SIGTERM, stop)


@dataclass
class Ran(Generic[Built, Done]):
    """A command's work, done (``run_command``)."""

    built: Built  # its configuration, checked
    done: Done  # what its work returned
    where: str  # the executor's description


def run_command(
    command: str,
    args: argparse.Namespace,
    build: Callable[[], Built],
    work: Callable[[Built, Executor], Done],
    interrupted: str | None = "the same command again runs the rest",
) -> Ran[Built, Done] | int:
    """A command's steps (every experiment command's): its stop signals handled, ``build`` (its configuration,
    every run checked before any starts), the executor of --workers / --scheduler, ``work`` on it. An exit
    code instead: EXIT_CONFIG on a configuration error (said on stderr), EXIT_INTERRUPTED on Ctrl-C or SIGTERM
    (said with ``interrupted``, what to do next; None: ``work`` said it)."""
    handle_stop_signals()
    try:
        built = build()
        executor = make_executor(args.workers, args.scheduler)
    except ConfigError as exc:
        return config_error(command, exc)
    try:
        with executor:
            return Ran(built, work(built, executor), executor.description)
    except ConfigError as exc:  # (a form's search after its runs)
        return config_error(command, exc)
    except KeyboardInterrupt:
        if interrupted is not None:
            print(f"{command}: interrupted; {interrupted}", file=sys.stderr)
        return EXIT_INTERRUPTED


def config_error(command: str, exc: ConfigError) -> int:
    """Say what is wrong with the command's configuration; its exit code."""
    print(f"{command}: error: {exc}", file=sys.stderr)
    return EXIT_CONFIG


def failed_runs(rows: Sequence[dict[str, Any]]) -> int:
    """How many rows of a table are failed runs (their error is in the row)."""
    return sum(1 for row in rows if row.get("status") == STATUS_FAILED)


def study_exit(command: str, rows: Sequence[dict[str, Any]], lost: Sequence[str], output: Path) -> int:
    """A study's exit code once its report is written: EXIT_FAILED (said on stderr) if a run failed or
    was lost, else 0."""
    failed = failed_runs(rows)
    if failed or lost:
        print(
            f"{command}: {failed} run(s) failed, {len(lost)} lost: see the report's cells and {output / 'results.csv'}",
            file=sys.stderr,
        )
        return EXIT_FAILED
    return 0
