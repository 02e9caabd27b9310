"""make run: the paper's claim, reproduced. The paper scenario three ways, each as a bracing-pair
run (two node processes over DDS, recorded, reported with an animation), all three through one simulator,
controller and recorder (``session``: the next run begun by reset_simulation): braced; passive (no brace
task, the floor kept as an obstacle the elbow can rest on); in free space (the planes removed: the
paper's comparison). Then a side-by-side table and the comparison figures (compare_*.png, compare.md)."""

from __future__ import annotations

import argparse
import shutil
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from bracing_analysis.bag import BagReadError
from bracing_analysis.ratios import ratio_text, temperature_saving_text
from bracing_analysis.summary import SUMMARY_KEYS, heading
from bracing_bringup.run_plan import RunOptions
from bracing_bringup.session import Session
from bracing_core.numbers import number
from bracing_core.params import ConfigError
from bracing_core.variants import RUNS

if TYPE_CHECKING:
    from bracing_analysis.series import BagSeries

RATIOS = (("braced", "free_space"), ("braced", "passive"))
"""The ratios printed, the paper's headline (braced against free space) first."""
BASELINE = "free_space"
"""compare.md divides by this run: its ratios are the paper's headline (braced / free space)."""

ROWS = (
    *SUMMARY_KEYS[:6],
    "motor_temperature_max_c",
    "constraint_residual_max_m",
    "max_penetration_m",
    "real_time_factor",
)
"""The table's rows, summary.json's keys: its errors and energies (SUMMARY_KEYS' first six), the hottest motor, the
contacts' residual and depth, the speed (labels and units: ``summary.heading``)."""


def table(summaries: dict[str, dict[str, Any]]) -> str:
    """The runs' summaries (by run name, RUNS) side by side, then RATIOS of energy and hand error."""
    runs = [run for run in RUNS if run.name in summaries]
    columns = [summaries[run.name] for run in runs]
    rule = "-" * (28 + 13 * len(runs))
    lines = [f"{'':28s}" + "".join(f" {run.column:>12s}" for run in runs), rule]
    for key in ROWS:
        label, unit = heading(key)
        cells = "".join(f" {s[key]:12.4g}" if number(s.get(key)) else f" {'n/a':>12s}" for s in columns)
        lines.append(f"{label + (f' [{unit}]' if unit else ''):28s}{cells}")
    lines.append(rule)
    column = {run.name: run.column for run in runs}
    for a, b in RATIOS:
        if a in summaries and b in summaries:
            for key, what in (("energy_consumed_j", "energy ratio"), ("hand_rms_error_m", "hand RMS error ratio")):
                lines.append(f"{what} {column[a]} / {column[b]}: {ratio_text(key, summaries[a], summaries[b])}")
            saving = temperature_saving_text(summaries[a], summaries[b])
            lines.append(f"hottest motor {column[a]} vs {column[b]}: {saving}")
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="paper_run", description=__doc__)
    parser.add_argument("--config", type=Path, default=Path("config/paper_4link.yaml"))
    parser.add_argument("--output", type=Path, default=Path("out"))
    parser.add_argument("--duration", type=float, default=None)
    parser.add_argument("--mode", choices=("voltage", "torque"), default=None)
    args = parser.parse_args(argv)
    with Session() as session:  # the three runs through one simulator, controller and recorder
        summaries, read, code = _run_all(args, session)
        if code == 0:
            code = _closed(session)
    if code != 0:
        return code
    return _compare(args, summaries, read)


def _run_all(args: argparse.Namespace, session: Session) -> tuple[dict[str, dict[str, Any]], dict[str, Any], int]:
    """RUNS in turn through ``session``: their summaries and bags as read (by run name), the exit code."""
    summaries: dict[str, dict[str, Any]] = {}
    read: dict[str, BagSeries] = {}  # each run's bag as its report read it: the comparison's data
    for run in RUNS:
        output = args.output / run.name
        if output.exists():
            shutil.rmtree(output)  # this command owns the directory of each of its runs
        print(f"== {run.label}: bracing-pair --config {args.config} --output {output}{run.flags()}")
        options = RunOptions(
            args.config, output, args.duration, args.mode, bracing=run.bracing, free_space=run.free_space
        )
        try:
            result = session.run(options)
        except ConfigError as exc:
            print(f"error: {exc}", file=sys.stderr)
            return summaries, read, 2
        if result.exit_code != 0 or result.summary is None:
            print(f"{run.name} run failed: {result.message}", file=sys.stderr)
            return summaries, read, result.exit_code or 1
        summaries[run.name] = result.summary
        if result.series is not None:
            read[run.name] = result.series
    return summaries, read, 0


def _closed(session: Session) -> int:
    """The session's processes stopped: 0 if each exited well (as a fresh run's last check), else 1."""
    failed = {name: code for name, code in session.close().items() if code not in (0, None)}
    for name, code in failed.items():
        print(f"error: the {name} exited with code {code}", file=sys.stderr)
    return 1 if failed else 0


def _compare(args: argparse.Namespace, summaries: dict[str, dict[str, Any]], read: dict[str, Any]) -> int:
    """The table, the runs' files and the comparison figures."""
    print()
    print(table(summaries))
    dirs = [str(args.output / name) for name in summaries]
    print(f"\nbags, plots and summary.json: {', '.join(dirs[:-1])} and {dirs[-1]}")
    from bracing_analysis.animation import ANIMATION_FILES
    from bracing_analysis.compare import write_comparison  # matplotlib: only once there is something to draw

    for name in summaries:
        movies = [args.output / name / f for f in ANIMATION_FILES if (args.output / name / f).exists()]
        print(f"animation of the {name} run: " + (", ".join(map(str, movies)) or "none (see the report's message)"))
    try:
        baseline = BASELINE if BASELINE in summaries else None
        bags = [args.output / name / "bag" for name in summaries]
        series = [read[name] for name in summaries] if read.keys() == summaries.keys() else None
        compared = write_comparison(bags, args.output, baseline=baseline, series=series)
    except BagReadError as exc:
        print(f"error: comparison: {exc}", file=sys.stderr)
        return 1
    print(" vs ".join(run.column for run in RUNS) + ": " + ", ".join(str(p) for p in compared))
    return 0


if __name__ == "__main__":
    sys.exit(main())
