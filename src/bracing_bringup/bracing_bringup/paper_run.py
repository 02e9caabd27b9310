"""make run: the paper's claim, reproduced. The paper scenario braced and unbraced, each
as a bracing-pair run (two node processes over DDS, recorded, reported with an animation),
then a side-by-side table and the comparison figures (compare_*.png, compare.md)."""

from __future__ import annotations

import argparse
import shutil
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from bracing_bringup.pair import RunOptions, run_pair
from bracing_bringup.summary import BagReadError
from bracing_core.params import ConfigError

ROWS: list[tuple[str, str, str]] = [
    ("hand_rms_error_m", "hand RMS error (t >= 2 s)", "m"),
    ("hand_max_error_m", "hand max error (t >= 2 s)", "m"),
    ("brace_rms_error_m", "brace RMS error", "m"),
    ("normal_force_rms_error_n", "normal force RMS error", "N"),
    ("energy_consumed_j", "energy consumed", "J"),
    ("copper_loss_j", "copper loss", "J"),
    ("constraint_residual_max_m", "max constraint residual", "m"),
    ("real_time_factor", "real-time factor", ""),
]


def table(braced: dict[str, Any], unbraced: dict[str, Any]) -> str:
    lines = [f"{'':28s} {'braced':>12s} {'unbraced':>12s}", "-" * 54]
    for key, label, unit in ROWS:
        cells = [
            f"{s[key]:12.4g}" if isinstance(s.get(key), (int, float)) else f"{'n/a':>12s}" for s in (braced, unbraced)
        ]
        lines.append(f"{label + (f' [{unit}]' if unit else ''):28s} {cells[0]} {cells[1]}")
    ratio = (
        braced["energy_consumed_j"] / unbraced["energy_consumed_j"] if unbraced["energy_consumed_j"] else float("nan")
    )
    hand = braced["hand_rms_error_m"] / unbraced["hand_rms_error_m"] if unbraced["hand_rms_error_m"] else float("nan")
    lines += [
        "-" * 54,
        f"energy ratio braced / unbraced: {ratio:.3f}",
        f"hand RMS error ratio braced / unbraced: {hand:.3f}",
    ]
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="paper_run", description=__doc__)
    parser.add_argument("--config", type=Path, default=Path("config/paper_4link.yaml"))
    parser.add_argument("--output", type=Path, default=Path("out"))
    parser.add_argument("--duration", type=float, default=None)
    parser.add_argument("--mode", choices=("voltage", "torque"), default=None)
    args = parser.parse_args(argv)
    summaries: dict[str, dict[str, Any]] = {}
    for name, bracing in (("braced", True), ("unbraced", False)):
        output = args.output / name
        if output.exists():
            shutil.rmtree(output)  # this command owns out/braced and out/unbraced
        print(
            f"== {name}: bracing-pair --config {args.config} --output {output}" + ("" if bracing else " --no-bracing")
        )
        try:
            result = run_pair(RunOptions(args.config, output, args.duration, args.mode, bracing))
        except ConfigError as exc:
            print(f"error: {exc}", file=sys.stderr)
            return 2
        if result.exit_code != 0 or result.summary is None:
            print(f"{name} run failed: {result.message}", file=sys.stderr)
            return result.exit_code or 1
        summaries[name] = result.summary
    print()
    print(table(summaries["braced"], summaries["unbraced"]))
    print(f"\nbags, plots and summary.json: {args.output / 'braced'} and {args.output / 'unbraced'}")
    from bracing_bringup.compare import write_comparison  # matplotlib: only once there is something to draw
    from bracing_bringup.report import ANIMATION_FILES

    for name in summaries:
        movies = [args.output / name / f for f in ANIMATION_FILES if (args.output / name / f).exists()]
        print(f"animation of the {name} run: " + (", ".join(map(str, movies)) or "none (see the report's message)"))
    try:
        compared = write_comparison([args.output / name / "bag" for name in summaries], args.output)
    except BagReadError as exc:
        print(f"error: comparison: {exc}", file=sys.stderr)
        return 1
    print("braced vs unbraced: " + ", ".join(str(p) for p in compared))
    return 0


if __name__ == "__main__":
    sys.exit(main())
