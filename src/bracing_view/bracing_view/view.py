"""``bracing-view [BAG]``: the run in a browser (rerun's web viewer, served on 127.0.0.1 only).

Live (no BAG): a node like RViz subscribes to what the simulator and controller publish and
logs it to rerun with sim time on the ``sim_time`` timeline. With BAG: the recorded run, through
the same ``Feed``, so a replay looks like the live view. ``--rrd FILE`` writes the recording.

Every message is reduced to numbers by the project's readers (``bracing_ros.wire``'s typestore)
and every link pose comes from the project's kinematics (``bracing_core.kinematics.LinkPoses``, pinocchio).
A state is drawn at most every ``--period`` of sim time (default 1/30 s, a frame at real time): the browser cannot
draw 1 kHz anyway, and the live viewer must not take the CPU the lockstep loop needs.

No usage data leaves the machine: rerun's analytics are turned off (``RERUN_ANALYTICS``) before
rerun is imported, and both servers (gRPC data, web viewer) listen on localhost.
"""

from __future__ import annotations

import argparse
import ctypes
import os
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

os.environ["RERUN_ANALYTICS"] = "0"  # before rerun's import: no usage data sent anywhere

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from bracing_analysis.surfaces import Shape, add_params_file_option, read_scenario
from bracing_core.contact_roles import KEPT_OUT, LINK_PENETRATION_TOPIC, role
from bracing_core.kinematics import LinkPoses
from bracing_core.overrides import SIMULATOR
from bracing_core.params import ConfigError
from bracing_core.stamps import cdr_stamp_seconds, stamp_ns, stamp_seconds
from bracing_core.targets import ACCEPTED
from bracing_core.typestore import (
    CONTACTS,
    CONTROLLER_STATE,
    JOINT_STATE,
    MOTOR_STATE,
    PATH,
    POINT_STAMPED,
    POSE_STAMPED,
    STRING,
    VECTOR3_STAMPED,
    WRENCH_STAMPED,
)
from bracing_view.view_scene import SurfaceSet, penetration_items
from bracing_view.viewurl import GRPC_PORT, WEB_PORT, view_url, wait_for_port
from bracing_view.visuals import Visuals

if TYPE_CHECKING:
    from rosbags.highlevel import AnyReader

    from bracing_analysis.series import BagSeries

DEFAULT_PERIOD_S = 1.0 / 30.0  # [s] of sim time between drawn states: a browser's frame at real time
FORCE_M_PER_N = 0.01  # arrow length per newton [m/N], as the recorder's markers
TIMELINE = "sim_time"

_TYPES = {
    "robot_description": STRING,
    "joint_states": JOINT_STATE,
    "contacts": CONTACTS,
    "controller_state": CONTROLLER_STATE,
    "motor_state": MOTOR_STATE,
    "hand_target": POINT_STAMPED,
    "hand_path": PATH,
    "hand_pose_target": POSE_STAMPED,
    "hand_orientation_error": VECTOR3_STAMPED,
    LINK_PENETRATION_TOPIC: CONTACTS,
}
TARGET_COLOR = [0, 0, 0]  # a target accepted while the run goes: black, as the report's marks
_TARGETS = ("hand_target", "hand_path", "hand_pose_target")
_ACCEPTED = "/" + ACCEPTED  # the controller's echo of a target it follows (bracing_core.targets)


def blueprint() -> rrb.Blueprint:
    """The 3D view on the left, the plots stacked on the right: one laptop screen."""
    plots = rrb.Vertical(
        rrb.TimeSeriesView(origin="/plots/hand_error", name="hand error [mm] vs sim time [s]"),
        rrb.TimeSeriesView(origin="/plots/orientation_error", name="hand orientation error [mrad] vs sim time [s]"),
        rrb.TimeSeriesView(origin="/plots/normal_force", name="normal force f_n, f_nd [N] vs sim time [s]"),
        rrb.TimeSeriesView(origin="/plots/current", name="motor current [A] vs sim time [s]"),
        rrb.TimeSeriesView(origin="/plots/energy", name="energy [J] vs sim time [s]"),
        rrb.TimeSeriesView(origin="/plots/temperature", name="motor temperature [degC] vs sim time [s]"),
    )
    view3d = rrb.Spatial3DView(origin="/world", name="arm, surfaces and contact forces (world, m; 1 cm/N)")
    return rrb.Blueprint(
        rrb.Horizontal(view3d, plots, column_shares=[3, 2]), rrb.TimePanel(expanded=False), collapse_panels=True
    )


def _stamp_s(msg: Any) -> float:
    return stamp_seconds(stamp_ns(msg.header.stamp))


class Feed:
    """Logs the run's messages (already decoded, rosbags' or rclpy's objects) to a rerun recording."""

    def __init__(
        self,
        recording: rr.RecordingStream,
        period_s: float = DEFAULT_PERIOD_S,
        surfaces: Mapping[str, Shape] | None = None,
    ) -> None:
        self.rec = recording
        self.period = period_s
        self.shapes = dict(surfaces or {})  # each contact's surface, if known (a bag's metadata, the scenario)
        self.poses: LinkPoses | None = None
        self.counts: dict[str, int] = {}
        self._last: dict[str, float] = {}
        self.first: dict[str, float] = {}  # per kind, the sim time [s] of the first state drawn
        self._forces: dict[str, np.ndarray] = {}
        self._surfaces = SurfaceSet(self.shapes)
        self.warnings: list[str] = []  # what the viewer could not draw (said once each on stderr)

    period_kinds = frozenset(
        {"joint_states", "contacts", "controller_state", "motor_state", "hand_orientation_error"}
        | {LINK_PENETRATION_TOPIC}
    )

    def wanted(self, kind: str, t: float) -> bool:
        """Whether ``_due`` would draw a message of ``kind`` at ``t`` (without marking it drawn)."""
        last = self._last.get(kind)
        return last is None or t - last >= self.period - 1e-9

    def _due(self, kind: str, t: float) -> bool:
        """Whether a message of ``kind`` at ``t`` is drawn (one per period of sim time)."""
        last = self._last.get(kind)
        if last is not None and t - last < self.period - 1e-9:
            return False
        self._last[kind] = t
        self.first.setdefault(kind, t)
        self.rec.set_time(TIMELINE, duration=t)
        return True

    def _log(self, path: str, item: Any, static: bool = False) -> None:
        self.rec.log(path, item, static=static)
        self.counts[path] = self.counts.get(path, 0) + 1

    def message(self, topic: str, msg: Any) -> None:
        """One message of a resolved or relative topic name (namespace ignored)."""
        # what the controller accepted (never a refused target); a bag from before it said so: as sent
        name = topic.lstrip("/").removesuffix(_ACCEPTED)
        if "contact_wrench/" in name:
            self.wrench(name.rsplit("/", 1)[-1], msg)
            return
        if "brace_target/" in name:
            self._target(f"world/targets/{name.rsplit('/', 1)[-1]}", [msg.point])
            return
        name = name.rsplit("/", 1)[-1]
        handler = getattr(self, name, None)
        if name in _TYPES and handler is not None:
            handler(msg)

    def robot_description(self, msg: Any) -> None:
        if self.poses is not None or not str(msg.data):
            return
        self.poses = LinkPoses(str(msg.data))
        visuals = Visuals(str(msg.data))
        for link, shapes in visuals.links.items():
            for k, (item, origin, scale) in enumerate(shapes):
                self._log(
                    f"world/robot/{link}/visual_{k}",
                    rr.Transform3D(translation=origin[:3], quaternion=rr.Quaternion(xyzw=origin[3:]), scale=scale),
                    True,
                )
                self._log(f"world/robot/{link}/visual_{k}/shape", item, True)
        for warning in visuals.warnings():  # one for the meshes not found, one for those it cannot read
            self.warnings.append(warning)
            print(f"bracing-view: warning: {warning}", file=sys.stderr, flush=True)

    def joint_states(self, msg: Any) -> None:
        if self.poses is None or not self._due("joint_states", _stamp_s(msg)):
            return
        poses = self.poses
        poses.update(poses.configuration(list(msg.name), np.asarray(msg.position, dtype=float)))
        rows = poses.xyzquat(poses.body_ids)
        for link, row in zip(poses.body_names, rows, strict=True):
            self._log(f"world/robot/{link}", rr.Transform3D(translation=row[:3], quaternion=row[3:]))
        strips = [[rows[a, :3], rows[b, :3]] for a, b in poses.segments()]
        self._log("world/skeleton", rr.LineStrips3D(strips, radii=0.012, colors=[70, 110, 200]))
        self._log("world/joints", rr.Points3D(rows[:, :3], radii=0.018, colors=[30, 30, 30]))

    def wrench(self, contact: str, msg: Any) -> None:
        f = msg.wrench.force
        self._forces[contact] = np.array([f.x, f.y, f.z], dtype=float)

    def contacts(self, msg: Any) -> None:
        """Each contact's point and forces: the scenario's under world/contacts, the kept-out frames' and
        links' (``<frame>@<contact>``) under world/kept_out, without a plot; each surface once."""
        if not self._due("contacts", _stamp_s(msg)):
            return
        for c in msg.contacts:
            point = np.array([c.position.x, c.position.y, c.position.z])
            normal = np.array([c.normal.x, c.normal.y, c.normal.z])
            surface = self._surfaces.first(str(c.name), point, float(c.residual), normal)
            if surface is not None:  # drawn once, where its first contact first is
                self._log(*surface, True)
            kept_out = role(str(c.name)) == KEPT_OUT
            base = f"world/{'kept_out' if kept_out else 'contacts'}/{c.name}"
            color = [220, 30, 30] if c.active else [128, 128, 128]
            self._log(f"{base}/point", rr.Points3D([point], radii=0.02, colors=[color]))
            fn = float(c.normal_force) * normal
            force = self._forces.get(c.name, fn)
            friction = force - float(np.dot(force, normal)) * normal
            self._log(
                f"{base}/normal_force", rr.Arrows3D(origins=[point], vectors=[FORCE_M_PER_N * fn], colors=[255, 140, 0])
            )
            self._log(
                f"{base}/friction_force",
                rr.Arrows3D(origins=[point], vectors=[FORCE_M_PER_N * friction], colors=[0, 170, 80]),
            )
            if not kept_out:
                self._log(f"plots/normal_force/{c.name}/f_n", rr.Scalars(float(c.normal_force)))

    def link_penetration(self, msg: Any) -> None:
        """robot.collision_geometry: per surface, the link deepest in it marked while it is inside."""
        if not self._due("link_penetration", _stamp_s(msg)):
            return
        for state in msg.contacts:
            for path, item in penetration_items(state):
                self._log(path, item)

    def controller_state(self, msg: Any) -> None:
        if not self._due("controller_state", _stamp_s(msg)):
            return
        desired = np.array([msg.hand_desired.x, msg.hand_desired.y, msg.hand_desired.z])
        actual = np.array([msg.hand_actual.x, msg.hand_actual.y, msg.hand_actual.z])
        self._log("world/hand/desired", rr.Points3D([desired], radii=0.01, colors=[0, 120, 255]))
        self._log("world/hand/actual", rr.Points3D([actual], radii=0.01, colors=[200, 0, 200]))
        for axis, value in zip("xyz", 1000.0 * (actual - desired), strict=True):
            self._log(f"plots/hand_error/{axis}", rr.Scalars(float(value)))
        for name, fnd in zip(msg.contact_name, msg.desired_normal_force, strict=False):
            self._log(f"plots/normal_force/{name}/f_nd", rr.Scalars(float(fnd)))

    def motor_state(self, msg: Any) -> None:
        if not self._due("motor_state", _stamp_s(msg)):
            return
        for name, current in zip(msg.name, msg.current, strict=False):
            self._log(f"plots/current/{name}", rr.Scalars(float(current)))
        self._log("plots/energy/consumed", rr.Scalars(float(msg.energy_consumed)))
        self._log("plots/energy/copper_loss", rr.Scalars(float(msg.copper_loss)))
        for name, temperature in zip(msg.name, getattr(msg, "temperature", []), strict=False):
            self._log(f"plots/temperature/{name}", rr.Scalars(float(temperature)))

    def hand_target(self, msg: Any) -> None:
        self._target("world/targets/hand", [msg.point])

    def hand_pose_target(self, msg: Any) -> None:
        self._target("world/targets/hand", [msg.pose.position])

    def hand_orientation_error(self, msg: Any) -> None:
        """log(R_d R^T) per world axis [mrad] (the controller publishes it only with an orientation task)."""
        if not self._due("hand_orientation_error", _stamp_s(msg)):
            return
        for axis in "xyz":
            self._log(f"plots/orientation_error/{axis}", rr.Scalars(1000.0 * float(getattr(msg.vector, axis))))

    def hand_path(self, msg: Any) -> None:
        self._target("world/targets/hand", [pose.pose.position for pose in msg.poses])

    def _target(self, path: str, points: Sequence[Any]) -> None:
        """A target sent while the run goes (targets while running), at the sim time of the last state drawn:
        its point, or its path's poses joined."""
        xyz = np.array([[p.x, p.y, p.z] for p in points], dtype=float).reshape(-1, 3)
        if not len(xyz):
            return
        self._log(path, rr.Points3D(xyz, radii=0.012, colors=[TARGET_COLOR]))
        if len(xyz) > 1:
            self._log(f"{path}/path", rr.LineStrips3D([xyz], radii=0.002, colors=[TARGET_COLOR]))

    def drawn(self) -> str:
        """What was drawn of the robot: how many states, from and to which sim time."""
        states = self.counts.get("world/skeleton", 0)
        if not states:
            return "no robot state drawn"
        first, last = self.first["joint_states"], self._last["joint_states"]
        return f"{states} robot states drawn, sim time {first:.3f} to {last:.3f} s"

    def paths(self, desired: np.ndarray, actual: np.ndarray) -> None:
        """The hand's whole desired and actual paths (a bag's: known at once)."""
        self._log("world/hand/desired_path", rr.LineStrips3D([desired], radii=0.003, colors=[0, 120, 255]), True)
        self._log("world/hand/actual_path", rr.LineStrips3D([actual], radii=0.003, colors=[200, 0, 200]), True)


def new_recording(name: str = "bracing") -> rr.RecordingStream:
    recording = rr.RecordingStream(name, make_default=False, make_thread_default=False)
    return recording


def replay_bag(bag: Path, recording: rr.RecordingStream, period_s: float = DEFAULT_PERIOD_S) -> Feed:
    """Every message of a recorded run through a ``Feed`` (the project's typestore; robot first), the bag
    opened once by ``bracing_analysis.bag`` for its series (surfaces, targets, hand paths) and its messages."""
    from bracing_analysis.bag import read_series  # rosbags ~100 ms, bag replay only, where used

    feeds: list[Feed] = []

    def replay(series: BagSeries, reader: AnyReader) -> None:
        feed = Feed(recording, period_s, series.surfaces)
        recording.send_blueprint(blueprint())
        wanted = [c for c in reader.connections if c.msgtype in (*_TYPES.values(), WRENCH_STAMPED)]
        if any(c.topic.endswith(_ACCEPTED) for c in reader.connections) or series.targets_refused:
            wanted = [c for c in wanted if not _sent_target(c.topic)]  # the accepted ones are drawn instead
        described = [c for c in wanted if c.topic.endswith("robot_description")]
        for conn, _, raw in reader.messages(connections=described):
            feed.message(conn.topic, reader.deserialize(raw, conn.msgtype))
        for conn, _, raw in reader.messages(connections=[c for c in wanted if c not in described]):
            feed.message(conn.topic, reader.deserialize(raw, conn.msgtype))
        feeds.append(feed)

    series = read_series(bag, then=replay)
    feed = feeds[0]
    if len(series.hand_desired):
        feed.paths(series.hand_desired, series.hand_actual)
    return feed


def _sent_target(topic: str) -> bool:
    """A target as sent (hand_target, hand_path, brace_target/<contact>), not the controller's echo of one."""
    return not topic.endswith(_ACCEPTED) and ("brace_target/" in topic or topic.rsplit("/", 1)[-1] in _TARGETS)


def write_rrd(bag: Path, rrd: Path, period_s: float = DEFAULT_PERIOD_S) -> dict[str, int]:
    """``run.rrd`` of a recorded run (``bracing-pair --rrd``): the entities' log counts."""
    recording = new_recording()
    recording.save(str(rrd))
    feed = replay_bag(bag, recording, period_s)
    recording.flush()
    recording.disconnect()
    return feed.counts


def serve(recording: rr.RecordingStream, web_port: int, grpc_port: int) -> tuple[str, subprocess.Popen[bytes]]:
    """The web viewer and its gRPC proxy on 127.0.0.1 only, and the recording streamed to it; the URL.

    The SDK's own ``serve_grpc`` / ``serve_web_viewer`` listen on every interface (0.0.0.0) with no
    way to say otherwise, so the wheel's ``rerun`` CLI serves them with ``--bind 127.0.0.1``.
    """
    import rerun_cli  # the wheel's binary itself: its Python launcher would outlive a SIGTERM's target

    binary = Path(rerun_cli.__file__).parent / "rerun"
    rerun_cli_path = str(binary) if binary.is_file() else shutil.which("rerun") or "rerun"
    argv = [rerun_cli_path, "--serve-web", "--bind", "127.0.0.1", "--port", str(grpc_port)]
    argv += ["--web-viewer-port", str(web_port), "--server-memory-limit", "25%", "--hide-welcome-screen"]
    env = dict(os.environ, RERUN_ANALYTICS="0")
    # It gets a SIGTERM from the kernel when this process dies, however it dies: no server outlives the viewer.
    proxy = subprocess.Popen(argv, env=env, stdout=subprocess.DEVNULL, preexec_fn=_term_with_parent)
    uri = f"rerun+http://127.0.0.1:{grpc_port}/proxy"
    url = view_url(web_port, grpc_port)
    _wait_for_port(grpc_port, proxy)
    recording.connect_grpc(uri, default_blueprint=blueprint())
    return url, proxy


def _term_with_parent() -> None:
    pr_set_pdeathsig = 1  # <sys/prctl.h>
    ctypes.CDLL(None, use_errno=True).prctl(pr_set_pdeathsig, int(signal.SIGTERM), 0, 0, 0)


def _wait_for_port(port: int, proxy: subprocess.Popen[bytes], timeout: float = 20.0) -> None:
    if not wait_for_port(port, lambda: proxy.poll() is None, timeout):
        if proxy.poll() is not None:
            raise RuntimeError(f"rerun exited with code {proxy.returncode} (is port {port} taken?)")
        raise RuntimeError(f"rerun did not listen on 127.0.0.1:{port} within {timeout:g} s")


POLL_S = 0.03
"""[s] wall time between the live viewer's drains of its subscriptions. Waking per message (5 topics at
1 kHz in lockstep) cost the lockstep loop half its speed on 2 cores; a drain every 30 ms takes what
queued meanwhile (VIEW_QOS's depth per topic, the rest dropped by DDS: a viewer draws the newest)."""


class Live:
    """The run's topics, subscribed best effort (the viewer never holds the lockstep loop back) and
    drawn every POLL_S. The robot description (latched) is subscribed at construction, before the
    viewer serves; with ``after_stepping`` (bracing-pair) the rest once the simulator's run_status
    says it steps: the nodes wait for the recorder by their subscription counts before the first
    state, and a viewer subscribed by then would count as the recorder (measured: the bag then
    lost the first answer). Without it, everything at once (a viewer joining a running system)."""

    def __init__(self, feed: Feed, after_stepping: bool = False) -> None:
        import rclpy  # imported where used: rclpy ~70 ms, live only (python -X importtime)

        from bracing_core.typestore import bracing_typestore
        from bracing_ros.fastdds import use_fastdds_profile
        from bracing_ros.lifetime import stop_with_parent
        from bracing_ros.qos import DESCRIPTION_QOS, STATUS_QOS, VIEW_QOS
        from bracing_ros.status import STATUS_TOPIC

        stop_with_parent()  # under bracing-pair: a SIGTERM should the pair die
        os.nice(10)  # the lockstep loop comes first (as the recorder)
        self.feed = feed
        self.store = bracing_typestore()
        use_fastdds_profile()  # as the run's processes: loopback only, matched at once
        rclpy.init()
        self.node = node = rclpy.create_node("bracing_view")
        self._fast = VIEW_QOS
        contacts = [str(c) for c in node.declare_parameter("contacts", ["elbow"]).value or []]
        self._types = _rclpy_types()
        self._later = [
            (t + _ACCEPTED if t in _TARGETS else t, ty) for t, ty in _TYPES.items() if t != "robot_description"
        ]
        self._later += [(f"contact_wrench/{c}", WRENCH_STAMPED) for c in contacts]
        self._later += [(f"brace_target/{c}{_ACCEPTED}", POINT_STAMPED) for c in contacts]
        self.topics: dict[Any, tuple[str, str]] = {}
        self._subscribe("robot_description", _TYPES["robot_description"], DESCRIPTION_QOS)
        self.status = None
        if after_stepping:
            from bracing_msgs.msg import RunStatus

            self.status = node.create_subscription(RunStatus, STATUS_TOPIC, lambda _: None, STATUS_QOS, raw=True)
        else:
            self._subscribe_the_rest()

    def _subscribe(self, topic: str, typename: str, qos: Any) -> None:
        # taken by the waiter, never by an executor: the callback is not called
        sub = self.node.create_subscription(self._types[typename], topic, lambda _: None, qos, raw=True)
        self.topics[sub] = (topic, typename)

    def _subscribe_the_rest(self) -> None:
        for topic, typename in self._later:
            self._subscribe(topic, typename, self._fast)
        self._later = []

    def _waiter(self) -> Any:
        from bracing_ros.waiter import SubscriptionWaiter

        return SubscriptionWaiter(self.node, [*self.topics, *([self.status] if self.status is not None else [])])

    def _stepping(self, data: bytes) -> bool:
        """Whether a run_status message (CDR bytes) says the simulator steps (or stepped)."""
        from rclpy.serialization import deserialize_message

        from bracing_msgs.msg import RunStatus
        from bracing_ros.status import Status

        status = Status.of(deserialize_message(data, RunStatus))
        return status.node == SIMULATOR and status.event in ("stepping", "progress", "finished")

    def spin(self, stop_after: float | None) -> None:
        """Draw what arrives until Ctrl-C, the end of the ROS context or ``stop_after`` seconds."""
        import rclpy  # imported where used: rclpy ~70 ms, live only (python -X importtime)
        from rclpy.executors import ExternalShutdownException  # rclpy ~70 ms, live only, where used

        feed, store = self.feed, self.store
        waiter = self._waiter()
        deadline = None if stop_after is None else time.monotonic() + stop_after
        try:
            while rclpy.ok() and (deadline is None or time.monotonic() < deadline):
                batch = waiter.take_all(0.5)
                if self.status is not None and any(sub is self.status and self._stepping(d) for sub, d in batch):
                    self.node.destroy_subscription(self.status)
                    self.status = None
                    self._subscribe_the_rest()
                    waiter = self._waiter()
                batch = [(sub, data) for sub, data in batch if sub in self.topics]
                newest_wrench = {self.topics[sub][0]: k for k, (sub, _) in enumerate(batch)}
                for k, (sub, data) in enumerate(batch):
                    topic, typename = self.topics[sub]
                    # Most states are not drawn: their header stamp (right after the CDR header) says
                    # so before any decoding. Of the wrenches only the newest counts (the next contacts').
                    if topic in feed.period_kinds and not feed.wanted(topic, cdr_stamp_seconds(data)):
                        continue
                    if topic.startswith("contact_wrench/") and newest_wrench[topic] != k:
                        continue
                    feed.message(topic, store.deserialize_cdr(data, typename))
                time.sleep(POLL_S)
        except (KeyboardInterrupt, ExternalShutdownException):
            pass
        finally:
            self.node.destroy_node()
            rclpy.try_shutdown()


def _rclpy_types() -> dict[str, Any]:
    from geometry_msgs.msg import PointStamped, PoseStamped, Vector3Stamped, WrenchStamped
    from nav_msgs.msg import Path as PathMessage
    from sensor_msgs.msg import JointState
    from std_msgs.msg import String

    from bracing_msgs.msg import Contacts, ControllerState, MotorState

    return {
        STRING: String,
        JOINT_STATE: JointState,
        CONTACTS: Contacts,
        CONTROLLER_STATE: ControllerState,
        MOTOR_STATE: MotorState,
        WRENCH_STAMPED: WrenchStamped,
        POINT_STAMPED: PointStamped,
        PATH: PathMessage,
        POSE_STAMPED: PoseStamped,
        VECTOR3_STAMPED: Vector3Stamped,
    }


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="bracing-view", description=__doc__.splitlines()[0])
    parser.add_argument("bag", nargs="?", type=Path, help="a recorded run (bag or run directory); none: live")
    parser.add_argument("--rrd", type=Path, default=None, help="also save the recording to this .rrd file")
    parser.add_argument("--web-port", type=int, default=WEB_PORT)
    parser.add_argument("--grpc-port", type=int, default=GRPC_PORT)
    parser.add_argument("--period", type=float, default=DEFAULT_PERIOD_S, help="sim time between drawn states [s]")
    parser.add_argument("--no-serve", action="store_true", help="only --rrd, no web viewer")
    parser.add_argument(
        "--after-stepping",
        action="store_true",
        help="live: subscribe to the run's data once the simulator steps (bracing-pair: see Live)",
    )
    parser.add_argument("--exit-after", type=float, default=None, help="stop after this many seconds of wall time")
    add_params_file_option(
        parser, "live: the scenario's params file(s), for the contact surfaces' geometry (a bag has them)"
    )
    argv = list(sys.argv[1:] if argv is None else argv)
    ours = argv[: argv.index("--ros-args")] if "--ros-args" in argv else argv  # rclpy reads the rest
    args = parser.parse_args(ours)
    if args.bag is not None and args.no_serve:
        counts = write_rrd(args.bag, args.rrd or Path("run.rrd"), args.period)
        print(f"bracing-view: {sum(counts.values())} logs to {args.rrd or 'run.rrd'}")
        return 0
    try:
        shapes = read_scenario(args.params_files) if args.params_files else None
    except ConfigError as exc:
        print(f"bracing-view: {exc}", file=sys.stderr)
        return 2
    recording = new_recording()
    feed = Feed(recording, args.period, shapes)
    subscribed = Live(feed, args.after_stepping) if args.bag is None else None  # before serving: see Live
    url, proxy = serve(recording, args.web_port, args.grpc_port)
    print(f"bracing-view: open {url}", flush=True)
    try:
        if args.bag is not None:
            replay_bag(args.bag, recording, args.period)
            recording.flush()
            print(f"bracing-view: {args.bag} loaded; Ctrl-C to stop", flush=True)
            end = None if args.exit_after is None else time.monotonic() + args.exit_after
            while (end is None or time.monotonic() < end) and proxy.poll() is None:
                time.sleep(0.2)
        elif subscribed is not None:
            recording.send_blueprint(blueprint())
            subscribed.spin(args.exit_after)
    except KeyboardInterrupt:
        pass
    finally:
        if args.bag is None:
            print(f"bracing-view: {feed.drawn()}", flush=True)
        recording.flush()
        proxy.terminate()
        proxy.wait(10)
    return 0


if __name__ == "__main__":
    sys.exit(main())
