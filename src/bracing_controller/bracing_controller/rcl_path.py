"""The controller's per-state path on rcl (``bracing_rcl``, C++): when the node takes it, and what the node does
around each state it answers (the bookkeeping of ``ControllerNode.answer``'s Python path).

The lockstep loop takes it when the run needs nothing it leaves out: no force or temperature measurement (force
feedback, thermal compensation), no orientation task (its orientation_error topic), no base following cmd_vel
(and not effort_forward, which has a loop of its own); ``BRACING_CONTROLLER_PATH=python`` keeps the Python path.
It waits for the states itself (rcl_wait, without the GIL), so a state is taken as soon as it lands, and returns
to the node's loop every ``STATES_PER_SERVE`` states, when another subscription has a message, or after
``WAIT_NS`` of quiet; the per-state bookkeeping (record batch, ack window, null-space watch) follows for those
states then. Per state
it answers alone only what needs the law alone (``StateAnswerer.law_only``, no target waiting to be
applied); any other state, and one it does not read or that the check refuses, it hands to the Python path as
its bytes. Both paths make the same check (the engine's ``state_refusal``), run the same law and write the same
bytes (the templates of ``bracing_ros.wire``).
"""

from __future__ import annotations

import time
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np
from rclpy.executors import ExternalShutdownException
from rclpy.signals import SignalHandlerGuardCondition

from bracing_core.step_timing import WorkTimer
from bracing_core.types import Vector
from bracing_rcl import ControllerPath, Layout, Outcome, Status
from bracing_ros import stop_signal
from bracing_ros.cdr_template import Template
from bracing_ros.node_failure import PathError
from bracing_ros.rcl_choice import python_only_reasons

if TYPE_CHECKING:
    from rclpy.context import Context
    from rclpy.publisher import Publisher
    from rclpy.subscription import Subscription

    from bracing_controller.targets import TargetTopics
    from bracing_core.answering import StateAnswerer
    from bracing_core.node_log import NodeLog
    from bracing_ros import wire
    from bracing_ros.ack_window import AckWindow
    from bracing_ros.record_batch import RecordBatchPublisher


class AnsweringNode(Protocol):
    """What the C++ path uses of the controller node (``bracing_controller.node.ControllerNode``)."""

    core: StateAnswerer
    target_topics: TargetTopics
    batch: RecordBatchPublisher
    flow: AckWindow
    command_pub: Publisher
    state_pub: Publisher
    state_reader: wire.JointStateDecoder
    command_wire: wire.MotorCommandEncoder
    state_wire: wire.ControllerStateEncoder

    @property
    def context(self) -> Context: ...
    @property
    def log(self) -> NodeLog: ...  # read-only: the node's is a NodeLog's subclass
    def on_state(self, data: bytes) -> None: ...


PATH_ENV = "BRACING_CONTROLLER_PATH"
"""The environment variable that chooses the controller's per-state path: "rcl" (the default) or "python"."""
PATH_WHERE = "the per-state path (C++ on rcl: ControllerPath.serve; joint_states in, motor_command out)"
"""Where a failure of the C++ path is said to be (``bracing_ros.node_failure``)."""
WAIT_NS = 100_000_000
"""[ns] the longest wait for a state before the node's loop runs (its batch flushed, its executor spun)."""
STATES_PER_SERVE = 10
"""The most states answered in C++ before their bookkeeping in Python: short enough that it fits in the
simulator's turn (~10 x 4 us), long enough that the loop is not woken in Python on every state."""


def python_only(core: StateAnswerer, effort_forward: bool, orientation: bool) -> str | None:
    """Why the run needs the Python path for every state (None: the rcl path can take it); ``effort_forward``,
    ``orientation``: whether the node runs effort_forward, an orientation task."""
    own = {
        "effort_forward": effort_forward,
        "force or temperature measurements": core.measurements is not None,
        "an orientation task": orientation,
        "base_command cmd_vel": core.base_drive is not None,
    }
    return python_only_reasons(PATH_ENV, own, core.limits, len(core.joint_names))


def layout(template: Template) -> Layout:
    """A message template as the C++ path takes it."""
    return Layout(*template.layout())


class RclPath:
    """The node's joint_states answered by ``bracing_rcl.ControllerPath`` (see the module docstring): it waits
    for them too, on a wait set of its own with ``others`` (the loop's other subscriptions, taken by the node)."""

    def __init__(self, node: AnsweringNode, state_sub: Subscription, others: list[Subscription]) -> None:
        self.node = node
        self.others = others
        self.interrupt = SignalHandlerGuardCondition(context=node.context)  # a stop signal ends a wait
        context: Any = node.context.handle  # rclpy's stubs know no pointer (its rcl_context_t*)
        self.path = ControllerPath(
            node.core.law.c_api(),
            context.pointer,
            state_sub.handle.pointer,
            [sub.handle.pointer for sub in others],
            self.interrupt.handle.pointer,
            node.command_pub.handle.pointer,
            node.state_pub.handle.pointer,
            layout(node.state_reader.template),
            layout(node.command_wire.template),
            layout(node.state_wire.template),
            keep_bytes=node.batch.publisher is not None,  # record_batch: the answer's bytes into the batch
        )
        self.answered = 0  # states the C++ path answered
        self.handed_over = 0  # states it took and the Python path handled
        self.landed: list[float] = []  # [s] each state's time from its reception (DDS) to its take

    def line(self) -> str:
        """The log line of what each path did, and how soon a state was taken once it had landed."""
        line = f"per-state path: {self.answered} states answered in C++ on rcl, {self.handed_over} by the Python path"
        landed = np.asarray([s for s in self.landed if s >= 0.0]) * 1e6
        if len(landed):
            p50, p99 = np.percentile(landed, [50, 99])
            line += f"; taken after landing [us]: p50 {p50:.1f}, p99 {p99:.1f}, max {landed.max():.1f}"
        return line

    def serve(self, work: WorkTimer, limit: int) -> tuple[int, list[Subscription]]:
        """Wait for joint_states (up to ``WAIT_NS``) and answer them as they come, here or on the Python path, up
        to ``limit`` or until another subscription has a message; (states taken, the other subscriptions ready).

        Each state's work is timed from its take to the C++ path's return to its wait; the last one's also holds
        this bookkeeping of all of them (what delays the next take)."""
        node, core = self.node, self.node.core
        alone = core.law_only and not node.target_topics.pending  # only Python changes either
        with stop_signal.held:  # an answer published is kept for the recorder, even as the run stops
            try:
                served = self.path.serve(core.previous_ns, alone, min(limit, STATES_PER_SERVE), WAIT_NS)
            except Exception as exc:  # rcl's failure (a RuntimeError), said with where by the node
                raise PathError(PATH_WHERE, exc) from exc
            returned = time.perf_counter()
            outcomes = served.outcomes
            for outcome in outcomes:
                if outcome.status == Status.answered:
                    self.answered += 1
                    self.keep(outcome)
        if not node.context.ok():
            raise ExternalShutdownException()
        for k, outcome in enumerate(outcomes):
            self.landed.append(outcome.landed_s)
            work.begin(outcome.taken_at)
            if outcome.status == Status.python:
                self.handed_over += 1
                node.on_state(outcome.data or b"")
            else:
                self.settle(outcome, work)
            end: float | None = outcome.done_at  # then straight back to the C++ wait, for all but the last
            if k == len(outcomes) - 1:  # this bookkeeping of all of them, not the wait after it
                end = outcome.done_at + time.perf_counter() - returned if outcome.status == Status.answered else None
            work.end(outcome.written_s + node.batch.take_written(), end)
        return len(outcomes), [self.others[k] for k in served.others_ready]

    def keep(self, outcome: Outcome) -> None:
        """An answer's bytes into the record batch (record_batch), as ``ControllerNode.send`` keeps them."""
        if outcome.command is not None and outcome.state is not None:
            self.node.batch.keep(self.node.command_pub, outcome.command)
            self.node.batch.keep(self.node.state_pub, outcome.state)

    def settle(self, outcome: Outcome, work: WorkTimer) -> None:
        """After the C++ path's law: an answer out (its bookkeeping, as ``ControllerNode.send``'s), or the law's
        failure said."""
        node, core, stamp_ns = self.node, self.node.core, outcome.stamp_ns
        if outcome.status == Status.answered:
            work.mark(outcome.command_out_at)
            core.answered(stamp_ns, outcome.damped, lambda: watched(outcome))
            node.flow.sent()
            node.batch.state_done()
            core.previous_ns = stamp_ns
        elif outcome.status == Status.law_failed:
            core.law_failed(stamp_ns, outcome.message)
        elif outcome.status == Status.not_finite:
            core.output_not_finite(stamp_ns)
        else:  # the law raised something else: as ControllerNode.on_state's last line of defence says it
            node.log.limited("error", "internal", f"joint_states ignored: {outcome.message}")


def watched(outcome: Outcome) -> tuple[Vector, Vector, Vector]:
    """What the null-space watch looks at of an answer: the hand's desired and actual position, dq."""
    return np.array(outcome.hand_desired), np.array(outcome.hand_actual), np.array(outcome.dq)
