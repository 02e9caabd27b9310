"""A node's per-step messages to the recorder in batches (``record_batch``, ``bracing_msgs/RecordBatch``).

Each message still goes out on its own topic, to whoever subscribes (the controller, RViz, a
viewer); a copy of its bytes waits in a ``bracing_core.record_batch.BatchPacker`` and reaches the
recorder (``bracing-recorder --from-batches``) with the others of its batch: one DDS delivery per
``states_per_batch`` states instead of one per message (why: ``bracing_core.record_batch``).
"""

from __future__ import annotations

import time
from collections.abc import Sequence

from rclpy.node import Node
from rclpy.publisher import Publisher

from bracing_core.record_batch import BatchPacker
from bracing_msgs.msg import RecordBatch
from bracing_ros.ack_window import AckWindow
from bracing_ros.matching import create_waking_publisher
from bracing_ros.qos import RECORD_BATCH_QOS
from bracing_ros.report_encoders import RecordBatchEncoder

RECORD_BATCH_TOPIC = "record_batch"


class RecordBatchPublisher:
    """A node's per-state publishers: each message out on its own topic and, with ``states_per_batch`` > 0,
    the same bytes to the recorder in batches (0: off, each message goes out on its topic only)."""

    def __init__(self, node: Node, publishers: Sequence[Publisher], states_per_batch: int) -> None:
        self.publisher: Publisher | None = None  # record_batch's, while batching
        self.written_s = 0.0  # [s] in rclpy's publish since the last take_written (make bench's breakdown)
        self._packer: BatchPacker | None = None
        if not states_per_batch:
            return
        self._index = {id(pub): k for k, pub in enumerate(publishers)}
        self._packer = BatchPacker([pub.topic_name for pub in publishers], states_per_batch)
        self._wire = RecordBatchEncoder(node.get_fully_qualified_name())
        self.publisher = create_waking_publisher(node, RecordBatch, RECORD_BATCH_TOPIC, RECORD_BATCH_QOS)
        self.flow = AckWindow(node, [self.publisher], RECORD_BATCH_QOS.depth)

    def publish(self, publisher: Publisher, data: bytes) -> None:
        """``data`` (CDR bytes) out on ``publisher``, and into the batch."""
        self._write(publisher, data)
        if self._packer is not None:
            self._packer.add(self._index[id(publisher)], data)

    def keep(self, publisher: Publisher, data: bytes) -> None:
        """``data`` (CDR bytes), published on ``publisher`` elsewhere (bracing_rcl's C++): into the batch only."""
        if self._packer is not None:
            self._packer.add(self._index[id(publisher)], data)

    def state_done(self) -> None:
        """A state's messages are all in: the batch goes out once it holds ``states_per_batch``."""
        if self._packer is not None and self._packer.state_done():
            self.flush()

    def flush(self) -> None:
        """The waiting messages out now (a node that stops or pauses), if there are any."""
        if self._packer is None or self.publisher is None or not len(self._packer):
            return
        batch = self._packer.take()
        data = self._wire.encode(batch.sequence, batch.topics, batch.topic_of, batch.end, batch.data)
        # the batches acknowledged so far end the window early: its blocking wait (up to a heartbeat period,
        # the lockstep loop stalled meanwhile) is left for a recorder that really falls behind
        self.flow.confirm()
        self._write(self.publisher, data)
        self.flow.sent()

    def _write(self, publisher: Publisher, data: bytes) -> None:
        """rclpy's publish, its time counted in ``written_s``."""
        start = time.perf_counter()
        publisher.publish(data)
        self.written_s += time.perf_counter() - start

    def written(self, seconds: float) -> None:
        """``seconds`` in a publish made elsewhere (bracing_rcl's C++), counted in ``written_s``."""
        self.written_s += seconds

    def take_written(self) -> float:
        """The time [s] spent in rclpy's publish (the DDS writes) since the last call."""
        written, self.written_s = self.written_s, 0.0
        return written

    def close(self, timeout_sec: float | None = None) -> bool:
        """Flush, then wait until the recorder has acknowledged every batch; whether it has (True when off)."""
        if self._packer is None:
            return True
        self.flush()
        return self.flow.wait(timeout_sec)
