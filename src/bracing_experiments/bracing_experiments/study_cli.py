"""What every bracing-study form's command does (the paper study, robustness, pays): check the form's
configuration, run its specs as one sweep on the executor, then whatever the form runs after them (an
optimiser's search), Ctrl-C and a configuration error met the same way; the form writes its report."""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Generic, Protocol, TypeVar

from bracing_experiments.cli import run_command
from bracing_experiments.executors import Executor
from bracing_experiments.experiment import RunSpec
from bracing_experiments.running import SweepResult, run_sweep


class Form(Protocol):
    """A study form's runs (paper's Study, Robustness, Pays)."""

    @property
    def specs(self) -> Sequence[RunSpec]: ...


FormT = TypeVar("FormT", bound=Form)
AfterT = TypeVar("AfterT")


@dataclass
class FormRun(Generic[FormT, AfterT]):
    """A study form's runs, done: what its report is written from."""

    config: Path  # the scenario file
    study: FormT
    sweep: SweepResult  # the form's specs' sweep
    after: AfterT  # what the form ran after its sweep (an optimiser's search)
    where: str  # the executor's description
    wall_time_s: float  # from the command's start, its checks included


def run_form(
    name: str,
    args: argparse.Namespace,
    build: Callable[[], tuple[Path, FormT]],
    after: Callable[[FormT, Executor], AfterT],
) -> FormRun[FormT, AfterT] | int:
    """The form's runs (``cli.run_command``): ``build`` (its scenario file and runs, every run checked,
    ConfigError otherwise), the sweep of its specs in --output on the executor, then ``after`` on the same
    executor. An exit code instead when the configuration is refused or Ctrl-C stops it."""
    began = time.perf_counter()

    def work(built: tuple[Path, FormT], executor: Executor) -> tuple[SweepResult, AfterT]:
        config, study = built
        print(f"{name}: {len(study.specs)} runs of {config} on {executor.description}", file=sys.stderr)
        sweep = run_sweep(study.specs, args.output, executor, progress=not args.no_progress)
        return sweep, after(study, executor)

    ran = run_command(name, args, build, work)
    if isinstance(ran, int):
        return ran
    (config, study), (sweep, more) = ran.built, ran.done
    return FormRun(config, study, sweep, more, ran.where, time.perf_counter() - began)
