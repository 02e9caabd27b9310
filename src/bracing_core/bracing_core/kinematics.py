"""The world pose of every link of a robot description, for named joint positions: the one
kinematics behind /tf, the recorder's markers, the viewer and the animation (no rclpy).

``LinkPoses`` is the core's robot model (``bracing_core.model.RobotModel``) of the URDF text
(``/robot_description``), read with pinocchio's frame kinematics. The simulator publishes the
robot as simulated (``model.simulated_urdf``: a locked joint is a fixed joint at its locked
position), so its JointStates name every joint that moves and the poses are the simulator's.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from bracing_core.model import ModelError, RobotModel

FloatArray = NDArray[np.float64]

WORLD_FRAME = "world"
"""TF root: the frame of the contact wrenches and of pinocchio's universe."""


class DescriptionError(ValueError):
    """The robot description is not a URDF the core's robot model takes."""


class LinkPoses:
    """World poses of the links of a URDF for named joint positions: the core's ``RobotModel``
    (the simulator's and the controller's model) of the text, read with pinocchio's frame kinematics.

    Hand it the text the simulator publishes (``robot_description``: its locked joints are
    fixed joints there); a joint a JointState does not name is at its neutral position.
    """

    def __init__(self, urdf_xml: str) -> None:
        try:
            self.robot = RobotModel.from_xml(urdf_xml, "robot_description")
        except ModelError as exc:
            msg = f"robot_description is not a usable URDF: {exc}"
            raise DescriptionError(msg) from exc
        self.model = self.robot.model
        self.data = self.robot.data
        model = self.model
        bodies = [i for i, f in enumerate(model.frames) if f.type == pin.FrameType.BODY and f.name != WORLD_FRAME]
        self.body_ids = bodies
        self.body_names = [model.frames[i].name for i in bodies]
        # Links on joint 0 (the universe) never move: /tf_static; the rest: /tf.
        self.static_ids = [i for i in bodies if model.frames[i].parentJoint == 0]
        self.moving_ids = [i for i in bodies if model.frames[i].parentJoint != 0]
        self.static_names = [model.frames[i].name for i in self.static_ids]
        self.moving_names = [model.frames[i].name for i in self.moving_ids]
        self._neutral = pin.neutral(model)
        # RobotModel holds 1-dof joints only (nq == nv): a joint's position is one entry of q.
        self._slots = {name: int(model.joints[jid].idx_q) for jid, name in enumerate(model.names) if jid}
        # The last names whose joints are distinct: their q indices.
        self._direct: tuple[tuple[str, ...], NDArray[np.intp]] = ((), np.zeros(0, dtype=np.intp))

    def configuration(self, names: Sequence[str], positions: Sequence[float] | FloatArray) -> FloatArray:
        """pinocchio's q for JointState-style names and positions (others at neutral, unknown names ignored)."""
        q = self._neutral.copy()
        key = tuple(names)
        if key == self._direct[0] and len(positions) == len(key):  # a state like the last: one assignment
            q[self._direct[1]] = positions
            return q
        slots = [self._slots.get(name) for name in key]
        if key and None not in slots and len(set(key)) == len(key):
            self._direct = key, np.array(slots, dtype=np.intp)
        for slot, value in zip(slots, positions, strict=False):
            if slot is not None:
                q[slot] = value
        return q

    def update(self, q: FloatArray) -> None:
        pin.framesForwardKinematics(self.model, self.data, q)

    def xyzquat(self, frame_ids: Sequence[int]) -> FloatArray:
        """(len, 7): x, y, z, qx, qy, qz, qw of each frame in the world, after ``update``."""
        # updateFramePlacement answers oMf[i] (recomputed from the joint's placement, the same product) in a
        # fraction of the time data.oMf[i] takes.
        model, data, placement, xyzquat = self.model, self.data, pin.updateFramePlacement, pin.SE3ToXYZQUAT
        return np.array([xyzquat(placement(model, data, i)) for i in frame_ids], dtype=float).reshape(-1, 7)

    def positions(self, q: FloatArray) -> FloatArray:
        """(bodies, 3): world position of every link (``body_names`` order)."""
        self.update(q)
        return np.array([self.data.oMf[i].translation for i in self.body_ids])

    def segments(self) -> list[tuple[int, int]]:
        """(parent, child) rows of ``body_names``: each link drawn from its parent link's origin."""
        index = {fid: row for row, fid in enumerate(self.body_ids)}
        frames = self.model.frames
        pairs = []
        for row, fid in enumerate(self.body_ids):
            parent = frames[fid].parentFrame
            while parent != 0 and frames[parent].type != pin.FrameType.BODY:
                parent = frames[parent].parentFrame  # past the joint frame to the parent link
            if parent in index and parent != fid:
                pairs.append((index[parent], row))
        return pairs


def z_to(normal: FloatArray) -> FloatArray:
    """Quaternion (x, y, z, w) turning +z onto ``normal`` (a marker's axis onto the surface normal)."""
    quat = pin.Quaternion.FromTwoVectors(np.array([0.0, 0.0, 1.0]), np.asarray(normal, dtype=float))
    return np.asarray(quat.coeffs(), dtype=float)
