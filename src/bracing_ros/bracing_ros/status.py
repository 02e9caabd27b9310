"""run_status: what each process of a run is doing, as ROS messages (``bracing_msgs/RunStatus``).

The simulator, the controller and the recorder say each moment of their run here (configured,
ready, stepping, progress, finished, bag closed); bracing-pair supervises a run and builds its
timeline from these messages (``StatusWatcher``), never from log text. The simulator also says each
warning about its run here (``warn``, also in its log): the recorder keeps those in the bag, and the
summary (bracing-pair's and bracing-report's alike) takes them from there. The topic is reliable and
transient local, so a watcher that joins late gets every process's history, and a process waits
until its last status is acknowledged before it exits (``StatusPublisher.flush``).
"""

from __future__ import annotations

import math
import os
import threading
import time
from collections.abc import Callable, Mapping
from typing import NamedTuple

import rclpy
from rclpy.duration import Duration
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions

from bracing_msgs.msg import RunStatus
from bracing_ros.fastdds import PROFILE_ENV, RANGE_ENV, SKIP_ENV, use_fastdds_profile
from bracing_ros.matching import create_waking_publisher
from bracing_ros.qos import STATUS_QOS

STATUS_TOPIC = "run_status"
EVENT_NAMES = {
    RunStatus.CONFIGURED: "configured",
    RunStatus.READY: "ready",
    RunStatus.STEPPING: "stepping",
    RunStatus.PROGRESS: "progress",
    RunStatus.FINISHED: "finished",
    RunStatus.BAG_CLOSED: "bag closed",
    RunStatus.WARNING: "warning",
}


class Status(NamedTuple):
    """A run_status message as plain values (what a watcher hands on)."""

    node: str
    event: str  # EVENT_NAMES' words: configured, ready, stepping, progress, finished, bag closed, warning
    wall_time_s: float  # [s] since the epoch
    sim_time: float  # [s], NaN where none
    real_time_factor: float  # NaN but in a real-time run's FINISHED
    text: str = ""  # a warning's

    @classmethod
    def of(cls, msg: RunStatus) -> Status:
        wall = msg.wall_time.sec + 1e-9 * msg.wall_time.nanosec
        event = EVENT_NAMES.get(msg.event, str(msg.event))
        return cls(msg.node, event, wall, msg.sim_time, msg.real_time_factor, msg.text)


class StatusPublisher:
    """A node's side of run_status."""

    def __init__(self, node: Node) -> None:
        self._name = node.get_name()
        self._publisher = create_waking_publisher(node, RunStatus, STATUS_TOPIC, STATUS_QOS)  # see subscribers()

    def say(self, event: int, sim_time: float = math.nan, real_time_factor: float = math.nan, text: str = "") -> None:
        msg = RunStatus(
            node=self._name, event=event, sim_time=float(sim_time), real_time_factor=real_time_factor, text=text
        )
        msg.wall_time.sec, nanosec = divmod(time.time_ns(), 10**9)
        msg.wall_time.nanosec = nanosec
        self._publisher.publish(msg)

    def warn(self, text: str, sim_time: float) -> None:
        """A warning about the run at ``sim_time`` [s] (the recorder keeps it for the summary)."""
        self.say(RunStatus.WARNING, sim_time, text=text)

    def subscribers(self) -> int:
        """How many subscribers have matched run_status (a match wakes ``matching.wait_until``)."""
        return int(self._publisher.get_subscription_count())

    def flush(self, timeout_s: float = 5.0) -> bool:
        """Wait until every subscriber has acknowledged what was said (a process about to exit)."""
        return bool(self._publisher.wait_for_all_acked(Duration(seconds=timeout_s)))


class StatusWatcher:
    """Follows run_status in ROS domain ``domain_id`` from a thread of this process (its own rclpy
    context), calling ``on_status`` with each message as it comes. ``environment``: the run's
    processes' (discovery range, network or not), which this participant takes as they do."""

    def __init__(self, domain_id: int, on_status: Callable[[Status], None], environment: Mapping[str, str]) -> None:
        self._domain_id = domain_id
        self._on_status = on_status
        self._environment = dict(environment)
        self._context = rclpy.Context()
        self._stopping = threading.Event()
        self._thread = threading.Thread(target=self._spin, name="run-status", daemon=True)
        self.node: Node | None = None  # once ``ready``: its node (services may be called through it from any thread)
        self.ready = threading.Event()

    def start(self) -> StatusWatcher:
        self._thread.start()
        return self

    def _spin(self) -> None:
        # The middleware reads its settings from the environment when its participant starts, at
        # the context's first node (rmw_fastrtps): this process's own are the run's for that
        # moment only (its next run may differ). Measured: set around rclpy.init alone, the
        # participant took Fast DDS's defaults (every interface, multicast), not the run's profile.
        saved = {key: os.environ.get(key) for key in self._environment}
        os.environ.update(self._environment)
        profile = {key: os.environ.get(key) for key in (PROFILE_ENV, RANGE_ENV, SKIP_ENV)}  # use_fastdds_profile's
        use_fastdds_profile()
        try:
            rclpy.init(context=self._context, domain_id=self._domain_id, signal_handler_options=_NO_SIGNALS)
            # A listener only: no parameter services, no /rosout (fewer endpoints for every process to match).
            node = Node("bracing_pair", context=self._context, start_parameter_services=False, enable_rosout=False)
        finally:
            for key, value in {**profile, **saved}.items():
                if value is None:
                    os.environ.pop(key, None)
                else:
                    os.environ[key] = value
        node.create_subscription(RunStatus, STATUS_TOPIC, lambda msg: self._on_status(Status.of(msg)), STATUS_QOS)
        executor = SingleThreadedExecutor(context=self._context)
        executor.add_node(node)
        self.node = node
        self.ready.set()
        try:
            while self._context.ok() and not self._stopping.is_set():
                executor.spin_once(timeout_sec=0.1)
        except ExternalShutdownException:
            pass
        finally:
            # rclpy's own order, all in this thread: the executor, the node, then the context. A node
            # destroyed after another thread shut its context down waited for good inside rclpy
            # (destroy_when_not_in_use, holding the GIL: bracing-pair hung at a run's end, measured).
            executor.shutdown()
            node.destroy_node()
            self._context.try_shutdown()

    def stop(self) -> None:
        self._stopping.set()
        self._thread.join(timeout=5.0)
        if self._thread.is_alive():  # not seen: the loop ends within its 0.1 s wait
            self._context.try_shutdown()


_NO_SIGNALS = SignalHandlerOptions.NO  # Ctrl-C is bracing-pair's: it stops the run itself
