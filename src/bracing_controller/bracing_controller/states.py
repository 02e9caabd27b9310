"""joint_states as the law needs them: (q, dq) in the law's joint order, matched by name, or StateError."""

from __future__ import annotations

import numpy as np

from bracing_core.types import Vector
from bracing_ros import wire

STAMP_RANGE_NS = (-(2**31) * 1_000_000_000, 2**31 * 1_000_000_000)


class StateError(ValueError):
    """A joint_states message the controller cannot use."""


def joint_vectors(msg: wire.JointStateData, joint_names: list[str]) -> tuple[Vector, Vector]:
    """(q, dq) in ``joint_names`` order from a JointState matched by name."""
    names = msg.name
    if len(msg.position) != len(names) or len(msg.velocity) != len(names):
        raise StateError(f"{len(names)} names, {len(msg.position)} positions, {len(msg.velocity)} velocities")
    if names == joint_names:  # the simulator's order: nothing to match
        q, dq = msg.position, msg.velocity
    else:
        if len(set(names)) != len(names):
            raise StateError("duplicate joint names")
        index = {name: k for k, name in enumerate(names)}
        missing = [j for j in joint_names if j not in index]
        if missing:
            raise StateError(f"missing joints {missing}")
        order = [index[j] for j in joint_names]
        q, dq = msg.position[order], msg.velocity[order]
    if not (np.isfinite(q).all() and np.isfinite(dq).all()):
        raise StateError("non-finite position or velocity")
    if not STAMP_RANGE_NS[0] <= msg.stamp_ns < STAMP_RANGE_NS[1]:  # a nanosec field >= 1e9 can push it out
        raise StateError(f"stamp {msg.stamp_ns} ns cannot be answered (builtin_interfaces/Time: int32 seconds)")
    return q, dq
