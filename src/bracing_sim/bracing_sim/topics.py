"""The simulator's topics out: its publishers, and what a step sends on them (the stepping policy's
``StepOutlet``: ``bracing_core.stepping``). Messages travel as CDR bytes built by ``wire`` (rclpy's
message classes cost more than the DDS write)."""

from __future__ import annotations

from collections.abc import Callable
from functools import partial

import numpy as np
from geometry_msgs.msg import WrenchStamped
from nav_msgs.msg import Odometry
from rclpy.node import Node
from rclpy.publisher import Publisher
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import String

from bracing_core.config import Plant, SimulatorConfig
from bracing_core.link_penetration import TOPIC as LINK_PENETRATION_TOPIC
from bracing_core.link_penetration import LinkDepth
from bracing_core.mobile_base import (
    ODOM_FRAME,
    ODOM_TOPIC,
    BaseOdometry,
    base_indices,
    braked_pose,
    odometry,
    root_link,
)
from bracing_core.sensing import GROUND_TRUTH
from bracing_core.stepping import StateOut, StepOut
from bracing_msgs.msg import Contacts, MotorState, RunStatus
from bracing_ros import report_encoders, wire
from bracing_ros.ack_window import AckWindow
from bracing_ros.matching import create_waking_publisher
from bracing_ros.qos import COMMAND_QOS, DESCRIPTION_QOS, STREAM_QOS
from bracing_ros.record_batch import RecordBatchPublisher
from bracing_ros.status import StatusPublisher
from bracing_sim.rcl_path import reports_on_rcl, state_on_rcl


def topics_key(config: SimulatorConfig, plant: Plant) -> tuple[object, ...]:
    """What ``SimulatorTopics`` and the node's command readers build from a configuration: two configurations with
    the same key need the same publishers, encoders and C++ paths (a per-run parameter may change nothing else)."""
    contacts = tuple((c.name, c.frame) for c in plant.contact_set.contacts)
    robot, shared = plant.robot, config.shared
    return (
        tuple(plant.joint_names),
        tuple(c.name for c in shared.contacts),
        contacts,
        config.sensors.exact,
        shared.collision_geometry,
        shared.base,
        tuple(robot.locked_joints),
        tuple(robot.locked_positions),
        config.command_source,
        config.joint_states_topic,
        config.joint_commands_topic,
        config.record_batch,
        plant.thermal,
        plant.mode,
        plant.command_limit.tobytes(),
        config.max_message_elements,
        config.max_name_length,
    )


class SimulatorTopics:
    """The simulator node's publishers and encoders; a ``StepOutlet``."""

    def __init__(self, node: Node, config: SimulatorConfig, plant: Plant, status: StatusPublisher) -> None:
        joint_names = list(plant.joint_names)
        self.state_out: Callable[[], None] | None = None  # called once a state is out (lockstep's timing)
        publisher = partial(create_waking_publisher, node)  # the lockstep wait wakes on each match
        self.joint_pub = publisher(JointState, "joint_states", STREAM_QOS)
        self.contacts_pub = publisher(Contacts, "contacts", STREAM_QOS)
        self.motor_pub = publisher(MotorState, "motor_state", STREAM_QOS)
        self.clock_pub = publisher(Clock, "/clock", STREAM_QOS)
        # A wrench topic per configured contact (the contact set lists them first); the contacts a
        # collision frame adds are reported in `contacts` only.
        self.wrench_pubs = [
            publisher(WrenchStamped, f"contact_wrench/{c.name}", STREAM_QOS) for c in config.shared.contacts
        ]
        # The URDF loaded, as simulated (each locked joint a fixed joint at its locked position; the
        # URDF itself when none is locked), latched: robot_state_publisher, RViz, Foxglove and the
        # recorder get it whenever they join, and with joint_states (the moving joints) pose the
        # links where the simulator has them.
        self.description_pub = publisher(String, "robot_description", DESCRIPTION_QOS)
        # With sensors that are not exact (sensors.*) what the controller receives is measured; the truth goes out too.
        self.truth_pubs: list[Publisher] = []
        if not config.sensors.exact:
            self.truth_pubs = [
                publisher(JointState, GROUND_TRUTH + "joint_states", STREAM_QOS),
                publisher(MotorState, GROUND_TRUTH + "motor_state", STREAM_QOS),
            ]
        # robot.collision_geometry: the link deepest into each surface, at each state
        self.link_pubs: list[Publisher] = []
        if config.shared.collision_geometry:
            self.link_pubs = [publisher(Contacts, LINK_PENETRATION_TOPIC, STREAM_QOS)]
        # A mobile base (base_x, base_y, base_yaw among the joints): odom, as diff_drive_controller publishes it,
        # on every state as the other per-state topics (recorded, in record_batch too).
        self.base = base_indices(joint_names)
        self.braked = braked_pose(plant.robot.locked_joints, plant.robot.locked_positions)  # a base held in place
        self.odom_pubs: list[Publisher] = []
        self.root_link = ""
        if self.base is not None or (config.shared.base != "fixed" and self.braked is not None):
            self.root_link = root_link(plant.robot.model)
            self.odom_pubs = [publisher(Odometry, ODOM_TOPIC, STREAM_QOS)]
            self.odom_wire = wire.OdometryEncoder(ODOM_FRAME, self.root_link)
        self.joint_command_pubs: list[Publisher] = []  # joint_commands: the ros2_control side's state topic
        if config.command_source == "joint_commands":
            self.joint_command_pubs = [node.create_publisher(JointState, config.joint_states_topic, COMMAND_QOS)]
        contacts = plant.contact_set.contacts
        self.joint_wire, self.clock_wire = wire.JointStateEncoder(joint_names), report_encoders.ClockEncoder()
        self.wrench_wire = report_encoders.WrenchStampedEncoder("world")
        self.contacts_wire = report_encoders.ContactsEncoder([c.name for c in contacts], [c.frame for c in contacts])
        self.motor_wire = report_encoders.MotorStateEncoder(joint_names)
        # robot_description too: a short run could otherwise end before the recorder has it.
        self.data_pubs = [self.joint_pub, self.contacts_pub, self.motor_pub, self.clock_pub, *self.wrench_pubs]
        self.data_pubs += [self.description_pub, *self.truth_pubs, *self.link_pubs, *self.odom_pubs]
        self.flow = AckWindow(node, self.data_pubs, STREAM_QOS.depth)
        # record_batch: the per-state messages also reach the recorder in batches (it subscribes to those
        # and robot_description only); otherwise it subscribes to every topic.
        per_state = [self.joint_pub, *self.truth_pubs, self.clock_pub, *self.wrench_pubs, self.contacts_pub]
        per_state += self.link_pubs
        per_state += self.odom_pubs
        self.batch = RecordBatchPublisher(node, [*per_state, self.motor_pub], config.record_batch)
        batched = self.batch.publisher
        self.recorder_pubs = self.data_pubs if batched is None else [batched, self.description_pub]
        self.status = status  # what bracing-pair follows (not a data topic: not in data_pubs)
        # joint_states and /clock written in C++ on rcl when a state is those two alone (bracing_sim.rcl_path)
        self.state_path = state_on_rcl(self, config, len(joint_names), batched is not None)
        # and then the step's reports (motor_state's temperatures: one per joint with the thermal model)
        temperatures = len(joint_names) if plant.thermal else 0
        self.report_path = None if self.state_path is None else reports_on_rcl(self, temperatures, batched is not None)

    def publish_description(self, description: str) -> None:
        self.description_pub.publish(String(data=description))

    def publish_state(self, state: StateOut) -> None:
        t_ns = state.t_ns
        if self.state_path is not None:
            sent = self.state_path.publish(t_ns, state.position, state.velocity, state.effort)
            self.batch.written(sent.written_s)
            if sent.joint_state is not None and sent.clock is not None:
                self.batch.keep(self.joint_pub, sent.joint_state)
                self.batch.keep(self.clock_pub, sent.clock)
            if self.state_out is not None:
                self.state_out()
            return
        send, truth = self.batch.publish, self.joint_wire.encode(t_ns, state.position, state.velocity, state.effort)
        if state.measured is None:
            send(self.joint_pub, truth)
        else:
            send(self.joint_pub, self.joint_wire.encode(t_ns, *state.measured, state.effort))
            send(self.truth_pubs[0], truth)
        for pub in self.joint_command_pubs:  # the ros2_control face: the full truth, as a robot's driver gives it
            pub.publish(truth)
        send(self.clock_pub, self.clock_wire.encode(t_ns))
        if state.links is not None and self.link_pubs:
            send(self.link_pubs[0], self.link_message(t_ns, state.links))
        if self.base is not None:
            self.publish_odometry(t_ns, odometry(state.position, state.velocity, self.base))
        elif self.odom_pubs and self.braked is not None:
            self.publish_odometry(t_ns, self.braked)
        if self.state_out is not None:
            self.state_out()

    def link_message(self, t_ns: int, links: list[LinkDepth]) -> bytes:
        """link_penetration: per surface the link deepest into it (or nearest), no force."""
        zero = np.zeros(3)
        reports = [
            report_encoders.ContactReport(d.active, d.position, d.normal, 0.0, 0.0, zero, d.residual) for d in links
        ]
        return self.contacts_wire.encode(t_ns, reports, [(d.name, d.link) for d in links])

    def publish_odometry(self, t_ns: int, base: BaseOdometry) -> None:
        """odom (nav_msgs/Odometry: the pose in the plane, the twist in the root link's frame, covariances zero:
        the simulated pose is exact), at the state's stamp."""
        data = self.odom_wire.encode(t_ns, (base.x, base.y), base.quaternion, (base.forward, base.left), base.yaw_rate)
        self.batch.publish(self.odom_pubs[0], data)

    def publish_step(self, step: StepOut) -> None:
        if self.report_path is not None:
            self.publish_step_on_rcl(step)
        else:
            self.publish_step_in_python(step)
        self.batch.state_done()  # a full batch goes out while the controller works on the state

    def publish_step_in_python(self, step: StepOut) -> None:
        """The step's reports encoded here (``report_encoders``) and published, each into the batch."""
        t_ns, d, send = step.t_ns, step.forces, self.batch.publish
        for pub, force in zip(self.wrench_pubs, step.wrenches, strict=True):
            send(pub, self.wrench_wire.encode(t_ns, force))  # at the contact point: no moment
        reports = [
            report_encoders.ContactReport(
                active=bool(step.active[j]),
                position=d.positions[j],
                normal=d.normals[j],
                normal_force=float(d.normal_force[j]),
                friction_force=float(d.friction_force[j]),
                slip_velocity=d.slip_velocity[j],
                residual=float(d.residual[j]),
            )
            for j in range(d.contact_count)
        ]
        send(self.contacts_pub, self.contacts_wire.encode(t_ns, reports))
        motor = (step.voltage, step.current, step.power, step.energies, step.temperature)
        send(self.motor_pub, self.motor_wire.encode(t_ns, *motor))
        if self.truth_pubs:
            truth = (step.voltage, step.true_current, step.power, step.energies, step.temperature)
            send(self.truth_pubs[1], self.motor_wire.encode(t_ns, *truth))

    def publish_step_on_rcl(self, step: StepOut) -> None:
        """The step's reports written and published in C++ (``report_path``), their bytes kept in the batch in
        the Python path's order."""
        assert self.report_path is not None
        d = step.forces
        contacts = (d.positions, d.normals, d.normal_force, d.friction_force, d.slip_velocity, d.residual)
        motors = (step.voltage, step.current, step.power, step.temperature)
        sent = self.report_path.publish(step.t_ns, step.wrenches, step.active, *contacts, *motors, step.energies)
        self.batch.written(sent.written_s)
        if sent.wrenches is not None and sent.contacts is not None and sent.motor_state is not None:
            for pub, data in zip(self.wrench_pubs, sent.wrenches, strict=True):
                self.batch.keep(pub, data)
            self.batch.keep(self.contacts_pub, sent.contacts)
            self.batch.keep(self.motor_pub, sent.motor_state)

    def sent(self) -> None:
        self.flow.sent()

    def close(self, timeout_sec: float | None = None) -> bool:
        """Everything sent (the last batch too) acknowledged by every subscriber; whether it was in time."""
        batched = self.batch.close(timeout_sec)
        return self.flow.wait(timeout_sec) and batched

    def progress(self, t: float) -> None:
        self.status.say(RunStatus.PROGRESS, t)
