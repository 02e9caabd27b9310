"""bracing-simulator: publishes the simulated robot, applies motor commands.

Wiring only: ROS parameters -> SimulatorConfig -> the core's Simulator and its stepping policy
(``bracing_core.stepping.SimulatorStepper``: stamp matching, refusal and rollback, the watchdog, the
warnings, the real-time pace); messages in are checked here and handed to it, what it sends goes out
through ``bracing_sim.topics``.
Lockstep (default): publish state k, wait for the command stamped with state k's stamp, step with it
held. Real-time: a wall-clock timer steps with the latest command.
With ``use_sim_time`` it follows its own /clock, each message checked first (``bracing_ros.sim_clock``).
Service ``reset_simulation`` (std_srvs/srv/Empty, as gazebo_ros names it): back to the initial state
(``SimulatorStepper.reset``), answered between steps; the run's start warnings are said again. With
``wait_for_reset`` a lockstep simulator stays at its run's end, and a reset starts the next run: one process
for a sequence of runs (their recorder ``bracing-recorder --stay``). A per-run parameter set while it runs
(``bracing_core.run_parameters``: ``bracing``, ``free_space``) is checked as at start and taken at the next
reset, which builds the run from the parameters as they then are, as a fresh process does; any other change is
refused (it needs a fresh start).
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable
from typing import TypeVar

from rcl_interfaces.msg import SetParametersResult
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.subscription import Subscription
from sensor_msgs.msg import JointState
from std_srvs.srv import Empty

from bracing_core import run_parameters, schema
from bracing_core.config import Plant, SimulatorConfig, build_simulator
from bracing_core.failures import DIVERGED, EXIT_DIVERGED
from bracing_core.meshes import missing_warning
from bracing_core.message_limits import MessageLimits, SizeError
from bracing_core.params import ConfigError
from bracing_core.simulator import DivergenceError, Simulator
from bracing_core.step_timing import WorkTimer
from bracing_core.stepping import SimulatorStepper
from bracing_core.types import Vector
from bracing_msgs.msg import MotorCommand, RunStatus
from bracing_ros import parameters, wire
from bracing_ros.commands import MODE_CODES, CommandError, command_vector, effort_vector
from bracing_ros.matching import wait_until
from bracing_ros.node_failure import PathError, end_run
from bracing_ros.node_log import RosNodeLog
from bracing_ros.node_main import run
from bracing_ros.qos import COMMAND_QOS, SUBSCRIBE_QOS
from bracing_ros.raw_messages import read_joint_state, read_motor_command
from bracing_ros.sim_clock import guard_clock
from bracing_ros.status import StatusPublisher
from bracing_ros.stop_signal import StoppableExecutor, raise_if_requested
from bracing_ros.waiter import SubscriptionWaiter
from bracing_sim.rcl_path import STATE_PATH_LINE, RclCommands, commands_on_rcl
from bracing_sim.topics import SimulatorTopics, topics_key

COMMAND_PATH_WHERE = "the motor_command path (C++ on rcl: CommandPath.wait and take)"
"""Where a failure of the command path on rcl is said to be (``bracing_ros.node_failure``)."""
FLUSH_AT_FAILURE_S = 10.0
"""[s] wall the simulator waits, after a divergence or another failure, for the recorder to acknowledge what it
sent: the last batch and the flow window take milliseconds on an idle machine; a loaded one may need seconds."""


class SimulatorNode(Node):
    def __init__(self, **kwargs: object) -> None:
        super().__init__("bracing_simulator", **kwargs)  # type: ignore[arg-type]
        values = schema.read("simulator", parameters.given_parameters(self))
        self.config = config = SimulatorConfig.from_values(values)
        parameters.declare(self, "simulator", values, checked=True)  # per-run changes: at the next reset
        self.running = run_parameters.per_run_values("simulator", parameters.current_values(self, "simulator"))
        self.plant, self.sim = build_simulator(config)
        self.joint_names = list(self.plant.joint_names)
        self.status = StatusPublisher(self)  # what bracing-pair follows
        self.topics = SimulatorTopics(self, config, self.plant, self.status)
        # Its meshes as file:// paths of the files found here (robot.package_paths): viewers need no package index.
        description, missing_meshes = self.plant.description()
        self.topics.publish_description(description)
        # Both command topics are taken raw: a message's sizes are checked before its elements are decoded.
        self.limits = limits = MessageLimits.of(config)
        self.command_reader = wire.MotorCommandDecoder(self.joint_names, MODE_CODES[config.shared.input_mode], limits)
        self.joint_command_reader = wire.JointStateDecoder(self.joint_names, limits)
        self.command_sub: Subscription | None = None  # motor_command (command_source motor_command)
        if config.command_source == "motor_command":
            self.command_sub = self.create_subscription(
                MotorCommand, "motor_command", self.on_command, SUBSCRIBE_QOS, raw=True
            )
        else:  # joint_commands: ros2_control's JointStateTopicSystem's efforts
            self.create_subscription(
                JointState, config.joint_commands_topic, self.on_joint_command, COMMAND_QOS, raw=True
            )
        self.log = RosNodeLog(self, self.status, config.log_throttle_period)
        guard_clock(self, self.log)  # use_sim_time (its own /clock): a bad one refused, not fatal
        self.core = SimulatorStepper(config, self.plant, self.sim, self.log, self.topics)
        self.command_rcl: RclCommands | None = None  # motor_command taken in C++ (bracing_sim.rcl_path)
        if self.command_sub is not None:
            self.command_rcl = commands_on_rcl(self, self.command_sub)
        if self.topics.state_path is not None:
            self.log.info(STATE_PATH_LINE)
        if config.command_source == "joint_commands":
            loop = f", current loop {config.motor_drive.bandwidth:g} rad/s" if self.core.drive is not None else ""
            self.log.info(
                f"joint_commands: efforts from {config.joint_commands_topic}, "
                f"state also on {config.joint_states_topic}{loop}"
            )
        for line in self.core.start_lines():
            self.log.info(line)
        self.start_warnings = [missing_warning(missing_meshes)] if missing_meshes else []
        self.core.say(self.start_warnings + self.core.watch.start())
        self.create_service(Empty, "reset_simulation", self.on_reset_simulation)
        self.add_on_set_parameters_callback(self.on_set_parameters)
        self.status.say(RunStatus.CONFIGURED, self.sim.time)

    def on_reset_simulation(self, _request: Empty.Request, response: Empty.Response) -> Empty.Response:
        current = parameters.current_values(self, "simulator")
        changed = run_parameters.per_run_values("simulator", current) != self.running
        self.core.reset(self.next_run(current) if changed else None)
        if changed:
            self.running = run_parameters.per_run_values("simulator", current)
            self.config, self.plant, self.sim = self.core.config, self.core.plant, self.core.sim
            for line in self.core.start_lines():
                self.log.info(line)
        self.core.say(self.start_warnings + self.core.watch.start())  # a new run: warned as the first was
        return response

    def next_run(self, params: dict[str, object]) -> tuple[SimulatorConfig, Plant, Simulator]:
        """The configuration, plant and simulator a fresh process started with ``params`` builds (its start
        checked); a ConfigError as that start would print it."""
        params = {**params, "robot.urdf": str(self.config.shared.urdf)}  # as this process resolved it
        config = SimulatorConfig.from_values(run_parameters.next_run_values("simulator", params, []))
        return (config, *build_simulator(config))

    def on_set_parameters(self, changes: list[Parameter]) -> SetParametersResult:
        """A change while running: per-run parameters checked as at start (taken at the next reset), any other
        refused (``bracing_core.run_parameters``)."""
        given = [(change.name, parameters.plain(change.value)) for change in changes]
        reason = run_parameters.refusal("simulator", [name for name, _ in given])
        if reason is None:
            try:
                config, plant, _ = self.next_run(parameters.current_values(self, "simulator") | dict(given))
            except ConfigError as exc:
                reason = str(exc)
            else:
                if topics_key(config, plant) != topics_key(self.config, self.plant):
                    names = ", ".join(name for name, _ in given)
                    reason = f"{names}: changes the simulator's topics: needs a fresh start"
        if reason is not None:
            return SetParametersResult(successful=False, reason=reason)
        self.log.info("from the next run (reset_simulation): " + ", ".join(f"{n} = {v}" for n, v in given))
        return SetParametersResult(successful=True)

    # -- messages in ----------------------------------------------------------------
    def on_joint_command(self, data: bytes) -> None:
        """ros2_control's JointStateTopicSystem's efforts [N m or N, link side] (CDR bytes), checked."""
        topic = self.config.joint_commands_topic
        try:
            msg = read_joint_state(data, self.joint_command_reader)
            u, saturated = effort_vector(msg.name, msg.effort, self.joint_names, self.core.effort_limit, self.limits)
        except (wire.DecodeError, SizeError, CommandError) as exc:
            self.log.limited("error", exc.kind, f"{topic} rejected: {exc}")
            return
        except Exception as exc:  # the last line of defence: no message may stop the simulator
            self.log.limited("error", "internal", f"{topic} rejected: {type(exc).__name__}: {exc}")
            return
        self.core.offer_effort(u, saturated)

    def on_command(self, data: bytes) -> None:
        self.defended(lambda: self.take_command(data))

    def on_read_command(self, stamp_ns: int, command: Vector) -> None:
        """A motor_command the C++ path read (``bracing_sim.rcl_path``): in joint order, finite, within the limits."""
        self.defended(lambda: self.core.offer(stamp_ns, command, False))

    def defended(self, take: Callable[[], None]) -> None:
        """``take`` a motor_command; whatever it raises is said, not raised."""
        try:
            take()
        except Exception as exc:  # the last line of defence: no message may stop the simulator
            self.log.limited("error", "internal", f"motor_command rejected: {type(exc).__name__}: {exc}")

    def take_command(self, data: bytes) -> None:
        """One motor_command (CDR bytes), checked, to the stepping policy."""
        try:
            msg = read_motor_command(data, self.command_reader)
            core = self.core
            u, saturated = command_vector(
                msg.name, msg.value, msg.mode, self.joint_names, core.mode, core.limit, self.limits
            )
        except (wire.DecodeError, SizeError, CommandError) as exc:
            self.log.limited("error", exc.kind, f"motor_command rejected: {exc}")
            return
        self.core.offer(msg.stamp_ns, u, saturated)

    def finish(self) -> None:
        """After the core's ``finish``: every subscriber has every message before this process ends."""
        self.topics.close()
        self.log.info(self.core.progress_line())
        if self.command_rcl is not None:
            self.log.info(self.command_rcl.line())
        self.log.info(f"finished at t = {self.sim.time:.6f} s")
        self.status.say(RunStatus.FINISHED, self.sim.time, self.core.real_time_achieved)
        self.status.flush()  # bracing-pair has it before this process ends


def wait_for_peers(node: SimulatorNode, executor: SingleThreadedExecutor) -> None:
    """Before the first state, in turn: lockstep, the controller (min_subscribers of joint_states, and its
    motor_command writer, or its first answer may be lost to this reader) and, if asked, the recorder on
    every topic (AckWindow keeps it lossless from then on); bracing-pair on run_status (a run that ended
    before its subscriber matched would end unheard: 1 of 12 runs of 0.01 s); joint_commands, the
    ros2_control side (a JointStateTopicSystem subscribes and publishes from its start)."""
    cfg, sub = node.config, node.command_sub
    waits: list[tuple[Callable[[], bool], str]] = []
    if cfg.stepping == "lockstep":
        waits.append((
            lambda: node.topics.joint_pub.get_subscription_count() >= cfg.min_subscribers
            and (cfg.min_subscribers == 0 or sub is None or sub.get_publisher_count() >= 1),
            f"lockstep: waiting for {cfg.min_subscribers} subscriber(s) of joint_states and a publisher of "
            "motor_command (start the controller)",
        ))  # fmt: skip
        if cfg.wait_for_recorder:
            waits.append((
                lambda: all(pub.get_subscription_count() >= 1 for pub in node.topics.recorder_pubs),
                "waiting for the recorder to subscribe to every topic",
            ))  # fmt: skip
    wanted = cfg.min_status_subscribers
    waits.append((
        lambda: node.status.subscribers() >= wanted, f"waiting for {wanted} subscriber(s) of run_status (bracing-pair)"
    ))  # fmt: skip
    if node.topics.joint_command_pubs:
        waits.append((
            lambda: node.topics.joint_command_pubs[0].get_subscription_count() >= cfg.min_subscribers
            and node.count_publishers(cfg.joint_commands_topic) >= 1,
            f"waiting for {cfg.min_subscribers} subscriber(s) of {cfg.joint_states_topic} and a publisher of "
            f"{cfg.joint_commands_topic} (start the ros2_control side)",
        ))  # fmt: skip
    for ready, message in waits:
        wait_until(node, executor, ready, message)


def spin_lockstep(node: SimulatorNode, executor: SingleThreadedExecutor) -> None:
    since = time.monotonic()
    wait_for_peers(node, executor)  # the publishers' matched events wake the executor at once
    node.log.info(f"lockstep: stepping (subscribers matched in {time.monotonic() - since:.3f} s)")
    first = True
    while True:
        node.status.say(RunStatus.STEPPING, node.sim.time)
        step_run(node, executor, first)
        first = False
        if not node.config.wait_for_reset:
            return
        node.log.info("wait_for_reset: the run is over; reset_simulation starts the next")
        while node.core.done():  # a reset sends the initial state again: the next run has begun
            raise_if_requested()
            executor.spin_once(timeout_sec=0.1)


T = TypeVar("T")


def on_rcl_path(call: Callable[[], T]) -> T:
    """``call`` on the C++ path; a failure of it (rcl's: the node's handlers raise nothing, ``defended``) as a
    PathError, a stop as itself."""
    try:
        return call()
    except ExternalShutdownException:
        raise
    except Exception as exc:
        raise PathError(COMMAND_PATH_WHERE, exc) from exc


def step_run(node: SimulatorNode, executor: SingleThreadedExecutor, first: bool) -> None:
    """One lockstep run to its end (the final state's reports, FINISHED), from its initial state: sent here
    if ``first``, else by the reset that began the run."""
    assert node.command_sub is not None  # lockstep: motor_command (joint_commands does not lockstep)
    waiter, core, work = SubscriptionWaiter(node, node.command_sub), node.core, WorkTimer()

    def receive(timeout_s: float) -> None:
        rcl = node.command_rcl
        work.pause()  # waiting for the controller is not this node's work
        if rcl is None:
            ready = waiter.wait(timeout_s)
            work.resume()
            for _, msg in waiter.take_ready(ready):
                node.on_command(msg)
            return
        came = on_rcl_path(lambda: rcl.wait(timeout_s))
        work.resume()
        if came:
            on_rcl_path(rcl.take_queued)

    node.topics.state_out = work.mark  # the controller's wait ends there; the step's reports follow
    if first:
        core.send_state()
        node.topics.sent()
    while not core.done():
        work.begin()
        if node.sim.steps_taken % 100 == 0:
            executor.spin_once(timeout_sec=0.0)  # parameter services and the like
        core.step_lockstep(receive)
        work.end(node.topics.batch.take_written())
    core.finish_lockstep(receive)  # the answer to the final state, for its reports
    if (line := work.line()) is not None:
        node.log.info(line)  # make bench's pair_step_breakdown_us
    node.finish()


def spin_real_time(node: SimulatorNode, executor: SingleThreadedExecutor) -> None:
    wait_for_peers(node, executor)
    core = node.core
    period = core.period
    node.log.info("free run: stepping as fast as it can" if period is None else "real-time: stepping")
    node.status.say(RunStatus.STEPPING, node.sim.time)
    core.start_real_time()
    if period is None:  # as fast as it can; /clock tells use_sim_time nodes the time
        while not core.done():
            executor.spin_once(timeout_sec=0.0)
            core.tick()
    else:
        node.create_timer(period, core.tick)
        while not core.done():
            executor.spin_once(timeout_sec=0.1)
    core.finish_real_time()
    node.finish()


def spin(node: SimulatorNode) -> int:
    executor = StoppableExecutor()
    executor.add_node(node)
    try:
        if node.config.stepping == "lockstep":
            spin_lockstep(node, executor)
        else:
            spin_real_time(node, executor)
    except DivergenceError as exc:
        node.get_logger().fatal(f"simulation diverged at t = {node.sim.time:.6f} s: {exc}")
        print(f"{DIVERGED}{node.sim.time:.6f} s: {exc}", file=sys.stderr, flush=True)
        flush_at_failure(node)
        return EXIT_DIVERGED
    except KeyboardInterrupt:  # stopped mid-run: what was sent still reaches the recorder, if it can soon
        node.topics.close(timeout_sec=2.0)
    except ExternalShutdownException:
        pass
    except Exception as exc:  # the C++ path's (an rcl error) or the loop's: said, flushed, exit 1
        return end_run(node.get_logger(), exc, lambda: flush_at_failure(node), f" at t = {node.sim.time:.6f} s")
    return 0


def flush_at_failure(node: SimulatorNode) -> None:
    """After a failure: every state up to it reaches the recorder (the last batch too), the moment to see; and
    run_status's STEPPING and warnings (bracing-pair keeps the bag by them)."""
    node.topics.close(timeout_sec=FLUSH_AT_FAILURE_S)
    node.status.flush(FLUSH_AT_FAILURE_S)


def main(args: list[str] | None = None) -> int:
    code = run(SimulatorNode, spin, args)  # type: ignore[arg-type]
    sys.exit(code)


if __name__ == "__main__":
    main()
