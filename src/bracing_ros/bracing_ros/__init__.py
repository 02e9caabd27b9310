"""The ROS 2 glue both bracing nodes (and the recorder) share: QoS, flow control, waits and the
node runner (``common``), typed parameters from the schema (``parameters``), message bytes from
the .msg definitions (``wire``, ``typestore``) and command checks (``commands``)."""
