"""bracing-recorder --stay: one bag after another in one process, for runs that reuse their nodes.

Once a bag is closed (a lockstep run's, every expected message in) the recorder waits, subscribed
still, for the next: setting the ``output`` parameter of its node ``bracing_recorder_next_bag`` (a bag
directory that does not exist yet) opens it, with ``params_files``, ``scenario`` and ``expect_states`` as
they are then (set them before, or in the same call). ``output`` is refused while a bag is open. A node
of its own: the recorder's takes its messages itself, without an executor (which would call their
callbacks). Its topics (``--contacts``, ``--ground-truth``, ``--from-batches``) stay those it started
with: a run that records others needs a recorder of its own.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from rcl_interfaces.msg import SetParametersResult
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter

if TYPE_CHECKING:
    from bracing_recorder.recorder import Recorder

OUTPUT = "output"
PARAMS_FILES = "params_files"
SCENARIO = "scenario"
EXPECT_STATES = "expect_states"
NEXT_BAG_NODE = "bracing_recorder_next_bag"
SERVE_PERIOD_S = 0.2
"""[s] wall between two looks at the parameter requests while a bag records: recording comes first."""


@dataclass(frozen=True)
class BagRequest:
    """One bag to record: where, the params files its nodes run with (its metadata), the scenario's name
    and the states of its lockstep run (the bag closes once it has them all)."""

    output: Path
    params_files: tuple[str, ...]
    scenario: str
    expect_states: int


class BagRequests:
    """The parameters that ask for the recorder's next bag (see the module's docstring), on a node of
    their own beside ``recorder``."""

    def __init__(self, recorder: Recorder, first: BagRequest) -> None:
        self.recorder = recorder
        self.bag_open = True
        self.pending: BagRequest | None = None
        self.node = node = Node(NEXT_BAG_NODE, namespace=recorder.get_namespace())
        self._served = time.monotonic()
        node.declare_parameter(OUTPUT, str(first.output))
        node.declare_parameter(PARAMS_FILES, list(first.params_files) or [""])
        node.declare_parameter(SCENARIO, first.scenario)
        node.declare_parameter(EXPECT_STATES, first.expect_states)
        node.add_on_set_parameters_callback(self._on_set)
        self.executor = SingleThreadedExecutor()
        self.executor.add_node(node)

    def _value(self, changes: dict[str, Parameter], name: str) -> object:
        return (changes[name] if name in changes else self.node.get_parameter(name)).value

    def _on_set(self, parameters: list[Parameter]) -> SetParametersResult:
        changes = {p.name: p for p in parameters}
        if OUTPUT not in changes:
            return SetParametersResult(successful=True)  # the next bag's settings, staged
        output = Path(str(changes[OUTPUT].value))
        if self.bag_open or self.pending is not None:
            return SetParametersResult(successful=False, reason="a bag is open: the next opens once it is closed")
        if output.exists():
            return SetParametersResult(successful=False, reason=f"{output} exists already, not overwriting")
        files = tuple(str(f) for f in self._value(changes, PARAMS_FILES) or () if f)  # type: ignore[attr-defined]
        states = self._value(changes, EXPECT_STATES)
        assert isinstance(states, int)
        self.pending = BagRequest(output, files, str(self._value(changes, SCENARIO)), states)
        return SetParametersResult(successful=True)

    def serve(self) -> None:
        """While a bag records: answer what was asked of the parameters (at most every SERVE_PERIOD_S)."""
        now = time.monotonic()
        if now - self._served >= SERVE_PERIOD_S:
            self._served = now
            self.executor.spin_once(timeout_sec=0.0)

    def wait(self, stopped: Callable[[], bool]) -> BagRequest | None:
        """After a bag is closed: the next one asked for, or None once ``stopped``; what comes meanwhile is
        taken and left out (``Recorder.skip``)."""
        self.bag_open = False
        while self.pending is None and not stopped():
            self.executor.spin_once(timeout_sec=0.02)
            self.recorder.skip(0.02)
        request, self.pending = self.pending, None
        self.bag_open = request is not None
        self.recorder.last_receive = time.monotonic()
        return request

    def destroy(self) -> None:
        self.executor.shutdown(timeout_sec=0.0)
        self.node.destroy_node()
