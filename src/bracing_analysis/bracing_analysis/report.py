"""``bracing-report DIR/bag [--output DIR]``: the paper's figures, an animation and summary.json.

Writes into the output directory (default: the bag's parent directory):
``hand_<axis>.png`` for each axis of the hand task (the paper's ``hand_y.png``, ``hand_z.png``: Figs. 6/7, 9/10,
13/14), ``brace_<axis>.png`` for each axis of a brace task (the paper's ``brace_y.png``: Figs. 11/15),
``normal_force.png`` (Figs. 12/16), ``energy.png`` (Fig. 8),
``motor_temperature.png`` (each motor's winding temperature; runs with the thermal model only),
``summary.json`` and ``animation.gif`` / ``animation.mp4`` (the arm moving, see ``animation``).
Each title names the scenario (the bag's note of it, else the robot's name) and cites the paper's
figures only for the paper's scenario; a dotted vertical line marks each parameter the controller
was given while it ran (``ros2 param set``), with the new value.
The axes are the tasks' (``hand.axes``, ``contacts.<name>.brace_axes``, which the recorder keeps in the
bag's metadata); a bag without them, or a task with none, gets the axes its desired hand path moves along
(y and z if none) and those along which a brace point moves (``axes.hand_axes``, ``axes.brace_axes``);
each brace plot draws the contacts whose task has its axis. Runs without contacts
skip the force plot; a bag without ``robot_description`` (recorded by an older version) gets
no animation unless ``--urdf`` names the robot.

``bracing-report BAG1 BAG2 ... --compare [--baseline NAME] [--output DIR]`` draws the runs side
by side instead (``compare_*.png`` and ``compare.md``, see ``compare``: ratios to the run NAME,
default the first; default output: the directory that holds the runs). Several bags without
``--compare``: a report for each. Exit code 2 on a missing or unreadable bag, or a baseline that
is none of the runs.

A bag cut short (its recorder killed before it closed the bag: no metadata.yaml, an mcap without its end)
is first recovered in its directory, as ``ros2 bag reindex`` does (``bag_recovery``), and the report says
so (a warning, also in summary.json). ``bracing-report --reindex BAG ...`` only recovers (a whole bag is
left as it is).
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from bracing_analysis.animation import DEFAULT_INTERVAL_S
from bracing_analysis.bag import BagReadError, read_series, resolve_bag
from bracing_analysis.bag_recovery import RecoveryError, recover_if_cut
from bracing_analysis.compare import BaselineError, default_compare_dir, write_comparison
from bracing_analysis.drawing import SUMMARY_FILE, report_series
from bracing_analysis.summary import format_summary
from bracing_core.numbers import number


def _previous(path: Path) -> dict[str, Any]:
    """An existing summary.json (the report cannot know from the bag what the run measured besides)."""
    try:
        value = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}
    return value if isinstance(value, dict) else {}


def _previous_wall_time(previous: dict[str, Any]) -> float | None:
    value = previous.get("wall_time_s")
    if number(value):
        return float(value)
    return None


def _previous_warnings(previous: dict[str, Any]) -> list[str]:
    value = previous.get("warnings")
    return [str(w) for w in value] if isinstance(value, list) else []


def recover_cut(bag: str | Path) -> str | None:
    """Recover ``bag`` in place if it was cut short (``bag_recovery``); what to say of it, None if it is
    whole. Raises BagReadError if it cannot be recovered."""
    path = resolve_bag(Path(bag))
    try:
        recovered = recover_if_cut(path)
    except RecoveryError as exc:
        raise BagReadError(str(exc)) from exc
    if recovered is None:
        return None
    return (
        f"the bag was cut short (its recorder stopped before closing it) and recovered: {recovered.describe()}; "
        "what it had not yet written is lost"
    )


def _previous_outcome(previous: dict[str, Any]) -> dict[str, str | None] | None:
    """A failed run's status, error and hint (the bag shows that it stopped, not why)."""
    if previous.get("status") != "failed":
        return None
    return {key: None if previous.get(key) is None else str(previous[key]) for key in ("status", "error", "hint")}


def default_output_dir(bag: str | Path) -> Path:
    """The bag's parent directory (the run directory DIR of DIR/bag)."""
    return resolve_bag(Path(bag)).resolve().parent


def write_report(
    bag: str | Path,
    output_dir: str | Path | None = None,
    wall_time_s: float | None = None,
    animation_interval_s: float | None = DEFAULT_INTERVAL_S,
    urdf: str | None = None,
) -> dict[str, Any]:
    """Read `bag`, write the plots, the animation and summary.json, and return the summary.

    The output directory defaults to the bag's parent. Without `wall_time_s`, the one in
    an existing summary.json there is kept, and so are its warnings (those the bag cannot show
    again: a target out of reach, slow real-time stepping) and a failed run's status, error and hint.
    `animation_interval_s` is the sim time between animation frames (None: no animation); `urdf` (the
    text) animates a bag that lacks robot_description. A bag cut short is recovered first
    (``recover_cut``), said in the warnings. Raises BagReadError on an unreadable bag.
    """
    recovery = recover_cut(bag)
    series = read_series(bag)
    out = Path(output_dir) if output_dir is not None else default_output_dir(bag)
    previous = _previous(out / SUMMARY_FILE)
    if wall_time_s is None:
        wall_time_s = _previous_wall_time(previous)
    warnings = ([recovery] if recovery else []) + _previous_warnings(previous)
    outcome = _previous_outcome(previous)
    return report_series(series, out, wall_time_s, animation_interval_s, urdf, warnings=warnings, outcome=outcome)


def main(argv: Sequence[str] | None = None) -> int:
    """Command line entry point; returns the exit code."""
    parser = argparse.ArgumentParser(
        prog="bracing-report",
        description="Plot a recorded bracing run (paper Figs. 6-16), animate the arm and write summary.json; "
        "with --compare, draw several runs side by side.",
    )
    parser.add_argument("bags", nargs="+", metavar="bag", help="rosbag2 bag directory (DIR/bag), or several")
    parser.add_argument("--compare", action="store_true", help="draw the runs side by side (compare_*.png, compare.md)")
    parser.add_argument(
        "--baseline",
        default=None,
        metavar="NAME",
        help="with --compare: the run (its directory name) the others are divided by (default: the first run)",
    )
    parser.add_argument(
        "--output",
        default=None,
        help="output directory (default: the bag's parent directory; with --compare, the directory holding the runs)",
    )
    parser.add_argument(
        "--wall-time", type=float, default=None, help="wall-clock duration of the run [s] (for real_time_factor)"
    )
    parser.add_argument(
        "--frame-interval",
        type=float,
        default=DEFAULT_INTERVAL_S,
        help=f"sim time between animation frames [s] (default {DEFAULT_INTERVAL_S})",
    )
    parser.add_argument("--no-animation", action="store_true", help="skip the animation")
    parser.add_argument("--urdf", type=Path, default=None, help="URDF to animate a bag without robot_description")
    parser.add_argument(
        "--reindex",
        action="store_true",
        help="only recover each bag cut short (its recorder killed: no metadata.yaml, an mcap without its end) "
        "in its directory, as `ros2 bag reindex` does: every complete message kept, the summary and metadata.yaml "
        "written anew; a whole bag is left as it is",
    )
    args = parser.parse_args(None if argv is None else list(argv))
    if args.frame_interval <= 0:
        parser.error("--frame-interval must be > 0")
    if len(args.bags) > 1 and not args.compare and (args.output is not None or args.wall_time is not None):
        parser.error("--output and --wall-time name one run: give one bag, or add --compare")
    if args.baseline is not None and not args.compare:
        parser.error("--baseline is for --compare")
    try:
        if args.reindex:
            return _reindex(args.bags)
        if args.compare:
            for bag in args.bags:
                recovery = recover_cut(bag)
                if recovery:
                    print(f"bracing-report: warning: {bag}: {recovery}")
            out = Path(args.output) if args.output is not None else default_compare_dir(args.bags)
            try:
                written = write_comparison(args.bags, out, baseline=args.baseline)
            except BaselineError as exc:
                print(f"bracing-report: error: {exc}", file=sys.stderr)
                return 2
            for path in written:
                print(f"written {path}")
            print((out / "compare.md").read_text(encoding="utf-8"))
            return 0
        urdf = args.urdf.read_text(encoding="utf-8") if args.urdf is not None else None
        for bag in args.bags:
            summary = write_report(
                bag,
                args.output,
                wall_time_s=args.wall_time,
                animation_interval_s=None if args.no_animation else args.frame_interval,
                urdf=urdf,
            )
            out = Path(args.output) if args.output is not None else default_output_dir(bag)
            print(format_summary(summary))
            print(f"report written to {out}")
    except (BagReadError, OSError) as exc:
        print(f"bracing-report: error: {exc}", file=sys.stderr)
        return 2
    return 0


def _reindex(bags: Sequence[str]) -> int:
    """--reindex: recover each bag cut short; say what became of each."""
    for bag in bags:
        recovery = recover_cut(bag)
        print(f"{bag}: {recovery or 'whole (it has its metadata.yaml and its end): left as it is'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
