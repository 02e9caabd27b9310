"""The ROS 2 glue both bracing nodes (and the recorder) share: QoS profiles (``qos``), flow control
(``ack_window``), waiting for matches (``matching``) and on subscriptions (``waiter``), raw messages
(``raw_messages``), rate-limited logs (``rate_log``), the node runner (``node_main``), typed parameters
from the schema (``parameters``), message bytes from the .msg definitions (``wire``, ``typestore``) and
command checks (``commands``)."""
