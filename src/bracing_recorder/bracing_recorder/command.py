"""bracing-recorder, the command: its options, the stop signals, recording until stopped (or until every
expected message is in), the drain and the bag's closing. What it records and how: ``recorder.py``."""

from __future__ import annotations

import argparse
import os
import signal
import sys
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from types import FrameType

import rclpy
from rclpy.signals import SignalHandlerOptions
from rclpy.utilities import remove_ros_args

from bracing_analysis import surfaces
from bracing_core.typestore import bracing_typestore
from bracing_msgs.msg import RunStatus
from bracing_recorder.bag_batch import BagWriter
from bracing_recorder.bag_notes import command_limit_notes, scenario_surfaces, scene_notes, task_notes
from bracing_recorder.bag_switch import BagRequest, BagRequests
from bracing_recorder.recorder import BAG_VERSION, Recorder, expected_counts
from bracing_ros.fastdds import use_fastdds_profile
from bracing_ros.lifetime import report_faults, stop_with_parent
from bracing_ros.status import StatusPublisher

MAX_SCENE_BACKLOG = 100_000
"""Recorded messages (3 per state, braced) kept for deriving /tf and markers later: ~30 MB, 30 s of a
lockstep run. Deriving cost ~150 us of CPU per state and, done beside the lockstep loop, slowed it
by 20-30 %, so it waits for an idle moment or the end of the run unless the queue grows past this.
(It now costs ~28 us, ~60 us with the writes, measured at the end of a run.) Derived as the batches come
instead (8 s paper runs, four of each alternately) the loop ran 5 % slower (2.39 -> 2.27x real
time; the two nodes alone 2.61x) for a bag closed ~0.4 s sooner after a 10 s run: the recorder's share of a
step stays under 10 % this way."""


STEPPING_CPU_LINE = "recorder process CPU while the run stepped"
"""The start of the line that gives ``Recorder.stepping_cpu_share`` at a bag's close (make bench reads it)."""


TUNINGS: tuple[tuple[str, type, float, str], ...] = (
    (
        "--batch",
        float,
        0.005,
        "after writing, let messages gather for this long before waiting again [s] (default 0.005): "
        "one wake-up per batch instead of one per message leaves the CPU to the nodes",
    ),
    ("--niceness", int, 0, "add this to the process's nice value (bracing-pair uses 10)"),
    (
        "--expect-states",
        int,
        0,
        "the states of a lockstep run: close the bag as soon as every topic has its messages and the "
        "simulator has said FINISHED on run_status (default 0: only when stopped)",
    ),
    ("--drain-idle", float, 0.2, "on stop, keep receiving until idle this long [s] (default 0.2)"),
    (
        "--drain-timeout",
        float,
        60.0,
        "on stop, drain for at most this long [s] (default 60: a recorder that fell behind on a busy "
        "machine may hold many messages in its queues, all acknowledged to their publishers)",
    ),
)
"""The recorder's numeric options: flag, type, default, help."""


def _parse(argv: Sequence[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        prog="bracing-recorder",
        description="Record the bracing topics to a rosbag2 bag (mcap storage).",
    )
    parser.add_argument("--output", required=True, help="bag directory to create (must not exist)")
    parser.add_argument("--namespace", default="", help="namespace of the recorded nodes")
    parser.add_argument("--contacts", default="", help="comma-separated contact names (contact_wrench/<name>)")
    parser.add_argument(
        "--ground-truth",
        action="store_true",
        help="also record ground_truth/joint_states and ground_truth/motor_state (a simulator with sensors.*)",
    )
    surfaces.add_params_file_option(
        parser,
        "a params file the nodes run with (repeat for each, in order): its contact surfaces go into the bag's "
        "metadata, and the markers draw spheres and cylinders as such",
    )
    parser.add_argument(
        "--scenario",
        default=None,
        metavar="NAME",
        help="the scenario's name, kept in the bag's metadata for the report (default: the first params file's name)",
    )
    parser.add_argument(
        "--no-scene",
        action="store_true",
        help="record only what arrives: no /tf, /tf_static or contact_markers (they cost CPU per state)",
    )
    parser.add_argument(
        "--from-batches",
        action="store_true",
        help="take the per-state topics from the nodes' record_batch (their record_batch parameter > 0; "
        "bracing-pair sets both) instead of subscribing to each: one DDS delivery per batch, not per message",
    )
    parser.add_argument(
        "--stay",
        action="store_true",
        help="with --expect-states: once a bag is closed, wait for the next (its output parameter set: "
        "bracing_recorder.bag_switch) instead of exiting; SIGINT or SIGTERM ends it",
    )
    for flag, kind, default, text in TUNINGS:
        parser.add_argument(flag, type=kind, default=default, help=text)
    args = parser.parse_args(list(argv))
    if args.stay and not args.expect_states:
        parser.error("--stay needs --expect-states (a bag closes by itself only once it has every message)")
    return args


class StopRequest:
    """SIGINT/SIGTERM: the first asks the recorder to drain and close the bag, a second to close it
    at once (still a readable bag)."""

    def __init__(self) -> None:
        self.requested = False
        self.urgent = False

    def on_signal(self, signum: int, frame: FrameType | None) -> None:
        del signum, frame
        if self.requested:
            self.urgent = True  # second signal: skip the drain, still close the bag
        self.requested = True


def _open_writer(output: Path, scenario: str | None, shapes: Mapping[str, surfaces.Shape]) -> BagWriter:
    writer = BagWriter(output, version=BAG_VERSION)
    for key, value in scene_notes(scenario, shapes).items():
        writer.set_custom_data(key, value)
    writer.open()
    return writer


def _write_task_metadata(writer: BagWriter, params_files: list[str], ground_truth: bool) -> None:
    """Read while the nodes start (custom_data is written when the bag closes): off the start's path."""
    for key, value in {**task_notes(params_files, ground_truth), **command_limit_notes(params_files)}.items():
        writer.set_custom_data(key, value)


def _record_until_stopped(
    node: Recorder,
    args: argparse.Namespace,
    stop: StopRequest,
    contacts: list[str],
    expect_states: int,
    serve: Callable[[], None] = lambda: None,
) -> bool:
    """Record until a stop signal, or until every expected message (of ``expect_states``) is in; True in
    the latter case. ``serve`` is called between takes (--stay: the next bag's requests answered)."""
    idle = False
    wanted = (
        expected_counts(contacts, expect_states, node.get_namespace(), args.ground_truth) if expect_states else None
    )
    while not stop.requested:
        serve()
        # a lockstep bag's messages are written after the last step (``Recorder.record``'s defer)
        got = node.record(0.0 if idle and node.scene_backlog else 0.1, defer=wanted is not None)
        idle = not got
        if idle:
            node.write_pending()  # the run paused or ended: the CPU is free
        if got and wanted is not None and node.simulator_finished and node.has_every_message(wanted):
            return True  # nothing more will come (the simulator's last warning came before FINISHED): no drain
        if node.scene_backlog and (idle or node.scene_backlog > MAX_SCENE_BACKLOG):
            node.derive(0.05)  # idle (nothing came for 0.1 s), or the queue would grow too large
        elif got and args.batch > 0.0:
            time.sleep(args.batch)  # messages wait in the subscriptions' queues (deep, reliable)
    return False


def _drain(node: Recorder, args: argparse.Namespace, stop: StopRequest, complete: bool) -> None:
    """Receive what is still in flight until idle for drain_idle (bounded), then derive the rest of
    the scene: the bag has /tf and markers for every state it holds."""
    start = time.monotonic()
    node.last_receive = start
    while not stop.urgent and not complete:
        now = time.monotonic()
        if now - node.last_receive >= args.drain_idle or now - start >= args.drain_timeout:
            break
        node.record(0.05)
        node.derive(0.01)
    while not stop.urgent and node.derive(0.1):
        pass


def _close(writer: BagWriter | None, node: Recorder | None, status: StatusPublisher | None, output: Path) -> None:
    if writer is not None:  # None: stopped between two bags (--stay)
        _close_bag(writer, node, status, output)
    if node is not None:
        node.destroy_node()
    if rclpy.ok():
        rclpy.shutdown()


def _close_bag(writer: BagWriter, node: Recorder | None, status: StatusPublisher | None, output: Path) -> None:
    if node is not None:
        node.write_pending()  # stopped while a run stepped
    writer.close()
    print(f"recorder closed the bag at {time.time():.6f}", flush=True)
    if status is not None:
        status.say(RunStatus.BAG_CLOSED)
        status.flush()  # bracing-pair has it before this process ends
    total = node.received if node is not None else 0
    states = node.counts.get("/clock", 0) if node is not None else 0
    print(f"recorder wrote {total} messages to {output}", flush=True)  # a line of its own: tools wait for it
    if node is not None and states:
        print(f"recorder took and wrote them in {node.record_time / states * 1e6:.0f} us of CPU per state", flush=True)
    if node is not None and (share := node.stepping_cpu_share) is not None:
        print(f"{STEPPING_CPU_LINE}: {share:.2%} of a core", flush=True)  # make bench reads it
    if node is not None and node.derived:
        states = node.counts.get("/tf", 0)
        cost = f", {node.scene_time / states * 1e6:.0f} us of CPU per state" if states else ""
        print(f"recorder derived {node.derived} messages (/tf, /tf_static, contact_markers){cost}", flush=True)


@dataclass
class _OpenBag:
    """The bag being recorded: its writer (None between two bags) and what it was asked for."""

    writer: BagWriter | None
    request: BagRequest


def _record_bags(
    node: Recorder, status: StatusPublisher, bag: _OpenBag, args: argparse.Namespace, stop: StopRequest
) -> None:
    """Record ``bag`` and, with --stay, each next one asked for (``bag_switch``), until stopped; ``bag``
    is the one still open when it ends (its writer None if none is)."""
    requests = BagRequests(node, bag.request) if args.stay else None
    try:
        _record_each_bag(node, status, bag, args, stop, requests)
    finally:
        if requests is not None:
            requests.destroy()


def _record_each_bag(
    node: Recorder,
    status: StatusPublisher,
    bag: _OpenBag,
    args: argparse.Namespace,
    stop: StopRequest,
    requests: BagRequests | None,
) -> None:
    """``_record_bags``' loop: a bag until it is complete (or the stop), then, with ``requests``, the next."""
    contacts = [c.strip() for c in args.contacts.split(",") if c.strip()]
    while bag.writer is not None:
        status.say(RunStatus.READY)
        print(f"recorder subscribed at {time.time():.6f}", flush=True)
        print("recorder ready", flush=True)
        _write_task_metadata(bag.writer, list(bag.request.params_files), args.ground_truth)
        serve = requests.serve if requests is not None else lambda: None
        complete = _record_until_stopped(node, args, stop, contacts, bag.request.expect_states, serve)
        _drain(node, args, stop, complete)
        if requests is None or stop.requested:
            return
        _close_bag(bag.writer, node, status, bag.request.output)
        bag.writer = None
        following = requests.wait(lambda: stop.requested)
        if following is not None:
            shapes = scenario_surfaces(list(following.params_files))
            bag.request, bag.writer = following, _open_writer(following.output, following.scenario or None, shapes)
            node.next_bag(bag.writer, shapes)


def main(argv: Sequence[str] | None = None) -> int:
    """Run the recorder until SIGINT/SIGTERM; returns the exit code."""
    report_faults()  # its stack on a crash, and every thread's on SIGUSR1 (a hang)
    full = list(sys.argv[1:] if argv is None else argv)
    args = _parse(remove_ros_args(["recorder", *full])[1:])
    contacts = [c.strip() for c in args.contacts.split(",") if c.strip()]
    output = Path(args.output)
    if output.exists():
        print(f"recorder: error: {output} exists already, not overwriting", file=sys.stderr)
        return 2
    stop = StopRequest()
    signal.signal(signal.SIGINT, stop.on_signal)
    signal.signal(signal.SIGTERM, stop.on_signal)
    stop_with_parent()  # a SIGKILLed bracing-pair still gets its bag closed
    try:
        typestore = bracing_typestore()
    except (FileNotFoundError, OSError) as exc:
        print(f"recorder: error: {exc}", file=sys.stderr)
        return 2
    shapes = scenario_surfaces(args.params_files)
    scenario = args.scenario or (Path(args.params_files[0]).stem if args.params_files else None)
    if args.niceness:
        os.nice(args.niceness)
    use_fastdds_profile()  # the nodes' discovery settings: matched at once when started together
    rclpy.init(args=["recorder", *full], signal_handler_options=SignalHandlerOptions.NO)
    first = BagRequest(output, tuple(args.params_files), scenario or "", args.expect_states)
    writer = _open_writer(output, scenario, shapes)
    bag = _OpenBag(writer, first)
    node: Recorder | None = None
    status: StatusPublisher | None = None
    try:
        node = Recorder(
            writer,
            typestore,
            namespace=args.namespace,
            contacts=contacts,
            scene=not args.no_scene,
            shapes=shapes,
            ground_truth=args.ground_truth,
            from_batches=args.from_batches,
        )
        status = StatusPublisher(node)  # what bracing-pair follows
        _record_bags(node, status, bag, args, stop)
    finally:
        _close(bag.writer, node, status, bag.request.output)
    return 0


if __name__ == "__main__":
    sys.exit(main())
