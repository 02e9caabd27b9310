"""bracing-pair: simulator + controller as separate processes over DDS, recorded to rosbag2.

    bracing-pair --config F [--duration S] [--output DIR] [--mode voltage|torque]
                 [--no-bracing | --free-space] [--real-time] [--domain-id N] [--set KEY=VALUE ...]
                 [--no-animation] [--timeline] [--network] [--engine bracing|mujoco]

Writes DIR/params.yaml (every parameter the nodes ran with), DIR/bag/ (mcap), DIR/logs/*.log,
DIR/summary.json, the report's PNGs and animation, and DIR/timeline.json (where the wall time
went: see ``timeline``). Exit 0 on success; 3 when the simulation diverged (summary.json, the
report and the bag up to the failure are written; its ``error`` names what ran away, its ``hint`` what
to change); 1 when an exception ended a node's run (its C++ path's on rcl, or its loop's: summary.json, the
report and the bag likewise, its ``error`` the node's line); otherwise non-zero with the failing process's
log tail. Ctrl-C stops the nodes and
still leaves a readable bag. A recorder that dies before it closes the bag (kill -9) leaves it cut
short: the bag is recovered (``bracing_analysis.bag_recovery``), the report drawn from it, and the
run says so (output and summary.json's warnings) and exits 1. A run that fails (or is stopped)
before its first step keeps only its logs, so the same --output works again.

``--engine mujoco``: the robot is MuJoCo's (``bracing_mujoco.mujoco_robot``, a mujoco_ros2_control
robot's topic face) and the controller runs unchanged with ``command_output: effort_forward``,
``input_mode: torque`` and ``use_sim_time`` (it follows the robot's /clock); the same bag, summary and
report, with n/a where a metric needs a topic only our simulator has (``contacts``, ``motor_state``).

This module is the command line; the run's plan is ``run_plan``, its supervision ``supervision``.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Sequence
from pathlib import Path

from bracing_bringup.run_plan import MUJOCO, RunOptions
from bracing_bringup.supervision import run_pair
from bracing_bringup.timeline import process_start_time
from bracing_core.overrides import parse_single
from bracing_core.params import ConfigError
from bracing_ros.fastdds import NETWORK_ENV
from bracing_ros.lifetime import report_faults

EXIT_CONFIG = 2


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="bracing-pair", description=__doc__.split("\n\n")[0] if __doc__ else None)
    parser.add_argument(
        "--config", required=True, type=Path, help="scenario params file (e.g. config/paper_4link.yaml)"
    )
    parser.add_argument("--duration", type=float, default=None, help="sim time [s] (default: the file's)")
    parser.add_argument("--output", type=Path, default=None, help="run directory (default: out/<time>)")
    parser.add_argument("--mode", choices=("voltage", "torque"), default=None, help="input mode override")
    parser.add_argument(
        "--no-bracing",
        action="store_true",
        help="the same task with no brace tasks and no desired forces; the surfaces stay as obstacles",
    )
    parser.add_argument(
        "--free-space", action="store_true", help="the surfaces removed (the paper's comparison); implies --no-bracing"
    )
    parser.add_argument("--real-time", action="store_true", help="wall-clock stepping instead of lockstep")
    parser.add_argument(
        "--domain-id",
        type=int,
        default=None,
        help="ROS_DOMAIN_ID (default: a free one of 1-100, held exclusively on this machine while the run lives)",
    )
    parser.add_argument("--quiet", action="store_true", help="no progress line")
    parser.add_argument(
        "--no-animation", action="store_true", help="no animation.gif / .mp4 (the report's figures only)"
    )
    parser.add_argument(
        "--timeline", action="store_true", help="print where the run's wall time went (also in DIR/timeline.json)"
    )
    parser.add_argument(
        "--network",
        action="store_true",
        help=f"DDS sockets on every interface, reachable from other machines (default: loopback and shared "
        f"memory only; {NETWORK_ENV}=1 does the same for nodes started by hand). Use SROS2 to do it securely",
    )
    parser.add_argument("--view", action="store_true", help="watch the run in a browser (bracing-view, 127.0.0.1)")
    parser.add_argument("--rrd", action="store_true", help="also write DIR/run.rrd (open with bracing-view or rerun)")
    parser.add_argument(
        "--engine",
        choices=("bracing", MUJOCO),
        default="bracing",
        help="the physics: bracing (our simulator) or mujoco (MuJoCo as a ros2_control robot; torque input, "
        "the controller's effort_forward output)",
    )
    parser.add_argument(
        "--set", dest="sets", action="append", default=[], metavar="KEY=VALUE", help="override a scenario parameter"
    )
    return parser


def parse_args(argv: Sequence[str] | None) -> RunOptions:
    """bracing-pair's options, checked (argparse's error: usage, the message, exit 2)."""
    parser = _parser()
    args = parser.parse_args(argv)
    if args.duration is not None and args.duration <= 0:
        parser.error("--duration must be > 0")
    if args.engine == MUJOCO and args.mode == "voltage":
        parser.error("--engine mujoco drives the joints' torques (a JointGroupEffortController): no --mode voltage")
    if args.domain_id is not None and not 0 <= args.domain_id <= 232:
        parser.error("--domain-id must be in 0-232 (ROS documents 0-101 as safe on Linux)")
    try:
        parameters = parse_single(args.sets)
    except ConfigError as exc:
        parser.error(str(exc))
    output = args.output or Path("out") / time.strftime("%Y%m%d-%H%M%S")
    return RunOptions(
        args.config,
        output,
        args.duration,
        args.mode,
        not args.no_bracing,
        args.real_time,
        args.domain_id,
        args.quiet,
        parameters=parameters,
        animation=not args.no_animation,
        show_timeline=args.timeline,
        free_space=args.free_space,
        network=args.network,
        view=args.view,
        rrd=args.rrd,
        engine=args.engine,
    )


def main(argv: Sequence[str] | None = None) -> int:
    options = parse_args(argv)
    options.command_start = process_start_time()  # the timeline counts the interpreter's start too
    report_faults()  # its stack on a crash, and every thread's on SIGUSR1 (a hang)
    try:
        result = run_pair(options)
    except ConfigError as exc:
        print(f"bracing-pair: error: {exc}", file=sys.stderr)
        return EXIT_CONFIG
    if result.exit_code != 0:
        print(f"bracing-pair: {result.message}", file=sys.stderr)
        return result.exit_code
    from bracing_analysis.summary import format_summary  # numpy: only once the run is over

    print(format_summary(result.summary or {}))
    print(f"bag: {result.output / 'bag'}  report and summary.json: {result.output}")
    if options.rrd:
        from bracing_view.view import write_rrd

        write_rrd(result.output / "bag", result.output / "run.rrd")
        print(f"rerun recording: {result.output / 'run.rrd'}  (bracing-view {result.output / 'bag'} to watch it)")
    if options.show_timeline and result.timeline is not None:
        print(result.timeline.format())
        phases = result.timeline.phases()
        print("  ".join(f"{k} {v:.2f}" for k, v in phases.items() if v is not None))
    return 0


if __name__ == "__main__":
    sys.exit(main())
