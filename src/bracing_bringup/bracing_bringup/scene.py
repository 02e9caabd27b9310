"""What a 3D viewer needs to draw a run: link poses (TF) and contact markers, as rosbag2 messages.

No rclpy: the recorder feeds it the CDR bytes it records, and it answers CDR bytes of
``tf2_msgs/msg/TFMessage`` and ``visualization_msgs/msg/MarkerArray`` built with rosbags'
Jazzy typestore.

- ``LinkPoses``: a pinocchio model built from the URDF text (``/robot_description``) and
  the world pose of every link (every BODY frame) for a JointState.
- ``SceneBuilder``: the messages of one recorded state: ``/tf`` (world -> every moving
  link), ``/tf_static`` (world -> the links fixed to the world, once) and
  ``contact_markers`` (per contact: its surface, the contact point and the contact force
  as an arrow of ``FORCE_ARROW_M_PER_N`` metres per newton, from ``contact_wrench/<name>``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray
from rosbags.typesys.store import Typestore

FloatArray = NDArray[np.float64]

WORLD_FRAME = "world"
"""TF root: the frame of the contact wrenches and of pinocchio's universe."""

FORCE_ARROW_M_PER_N = 0.01
"""Length of a force arrow marker per newton of force [m/N] (10 N -> 10 cm)."""

SURFACE_PATCH_M = 2.0
"""Side of the square drawn for a surface [m] (a patch of the tangent plane)."""

TF_TYPE = "tf2_msgs/msg/TFMessage"
MARKERS_TYPE = "visualization_msgs/msg/MarkerArray"
STRING_TYPE = "std_msgs/msg/String"
JOINT_STATE_TYPE = "sensor_msgs/msg/JointState"
CONTACTS_TYPE = "bracing_msgs/msg/Contacts"
WRENCH_TYPE = "geometry_msgs/msg/WrenchStamped"

MAX_WAITING_STATES = 100_000
"""JointStates kept while no robot_description has come (a simulator that publishes none)."""

# Marker ids within a contact's namespace.
SURFACE_ID, POINT_ID, FORCE_ID = 0, 1, 2


class DescriptionError(ValueError):
    """The robot description is not a URDF pinocchio can read."""


class LinkPoses:
    """World poses of the links of a URDF for named joint positions (pinocchio kinematics)."""

    def __init__(self, urdf_xml: str) -> None:
        try:
            self.model = pin.buildModelFromXML(urdf_xml)
        except (RuntimeError, ValueError) as exc:
            msg = f"robot_description is not a readable URDF: {exc}"
            raise DescriptionError(msg) from exc
        self.data = self.model.createData()
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
        self._slots: dict[str, tuple[int, int]] = {}  # joint name -> (idx_q, nq)
        for jid in range(1, model.njoints):
            self._slots[model.names[jid]] = (model.joints[jid].idx_q, model.joints[jid].nq)

    def configuration(self, names: Sequence[str], positions: Sequence[float] | FloatArray) -> FloatArray:
        """pinocchio's q for JointState-style names and positions (others at neutral)."""
        q = self._neutral.copy()
        for name, value in zip(names, positions, strict=False):
            slot = self._slots.get(name)
            if slot is None:
                continue
            idx, nq = slot
            if nq == 1:
                q[idx] = value
            elif nq == 2:  # continuous joint: (cos, sin) of the angle
                q[idx], q[idx + 1] = np.cos(value), np.sin(value)
        return q

    def update(self, q: FloatArray) -> None:
        pin.framesForwardKinematics(self.model, self.data, q)

    def xyzquat(self, frame_ids: Sequence[int]) -> FloatArray:
        """(len, 7): x, y, z, qx, qy, qz, qw of each frame in the world, after ``update``."""
        out = np.empty((len(frame_ids), 7))
        for row, i in enumerate(frame_ids):
            out[row] = pin.SE3ToXYZQUAT(self.data.oMf[i])
        return out

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


@dataclass
class Derived:
    """One message to write: topic key (``tf``, ``tf_static``, ``contact_markers``), stamp, CDR bytes."""

    key: str
    stamp_ns: int
    data: bytes


@dataclass
class _StampParts:
    contacts: Any = None
    forces: dict[str, FloatArray] = field(default_factory=dict)


class SceneBuilder:
    """Turns recorded JointStates, Contacts and WrenchStampeds into /tf and contact_markers.

    Feed it every recorded message (``description``, ``joint_state``, ``contacts``,
    ``wrench``); each call returns the derived messages that became complete. JointStates
    that come before the robot description wait for it; a state's markers wait for its
    Contacts and the WrenchStamped of every contact in ``wrench_contacts``.
    """

    def __init__(self, typestore: Typestore, wrench_contacts: Sequence[str] = ()) -> None:
        self.store = typestore
        self.wrench_contacts = list(wrench_contacts)
        self.poses: LinkPoses | None = None
        self._waiting_states: list[tuple[int, bytes]] = []
        self._parts: dict[int, _StampParts] = {}
        self._tf: Any = None
        self._tf_header: Any = None
        self._markers = _MarkerTemplates(typestore)

    # -- inputs -------------------------------------------------------------------------
    def description(self, data: bytes) -> list[Derived]:
        """The recorded std_msgs/String robot_description: /tf_static, then every waiting /tf."""
        if self.poses is not None:
            return []  # the first description wins; a republished one is the same robot
        urdf = str(self._read(data, STRING_TYPE).data)
        self.poses = LinkPoses(urdf)
        self._tf, self._tf_header = self._tf_template(self.poses.moving_names)
        out = [Derived("tf_static", 0, self._static_message(self.poses))]
        waiting, self._waiting_states = self._waiting_states, []
        out += [self._tf_message(stamp, data) for stamp, data in waiting]
        return out

    def joint_state(self, stamp_ns: int, data: bytes) -> list[Derived]:
        if self.poses is None:
            if len(self._waiting_states) < MAX_WAITING_STATES:  # no description yet (an old simulator?)
                self._waiting_states.append((stamp_ns, data))
            return []
        return [self._tf_message(stamp_ns, data)]

    def contacts(self, stamp_ns: int, data: bytes) -> list[Derived]:
        self._part(stamp_ns).contacts = self._read(data, CONTACTS_TYPE)
        return self._markers_if_complete(stamp_ns)

    def wrench(self, contact: str, stamp_ns: int, data: bytes) -> list[Derived]:
        force = self._read(data, WRENCH_TYPE).wrench.force
        self._part(stamp_ns).forces[contact] = np.array([force.x, force.y, force.z])
        return self._markers_if_complete(stamp_ns)

    def _read(self, data: bytes, type_name: str) -> Any:
        return self.store.deserialize_cdr(data, type_name)

    @property
    def waiting(self) -> int:
        """States and marker stamps still incomplete (lost inputs or no description)."""
        return len(self._waiting_states) + len(self._parts)

    # -- TF -------------------------------------------------------------------------------
    def _tf_template(self, children: Sequence[str]) -> tuple[Any, Any]:
        """A TFMessage whose fields are overwritten per state (building it anew costs more than the FK)."""
        t = self.store.types
        header = _header(t, WORLD_FRAME)
        transforms = [_transform(t, header, child) for child in children]
        return t["tf2_msgs/msg/TFMessage"](transforms=transforms), header

    def _static_message(self, poses: LinkPoses) -> bytes:
        message, _ = self._tf_template(poses.static_names)
        poses.update(poses.configuration([], []))
        _fill(message.transforms, poses.xyzquat(poses.static_ids))
        return bytes(self.store.serialize_cdr(message, TF_TYPE))

    def _tf_message(self, stamp_ns: int, data: bytes) -> Derived:
        assert self.poses is not None
        state = self._read(data, JOINT_STATE_TYPE)
        poses = self.poses
        poses.update(poses.configuration(state.name, state.position))
        stamp = self._tf_header.stamp
        stamp.sec, stamp.nanosec = divmod(stamp_ns, 1_000_000_000)
        _fill(self._tf.transforms, poses.xyzquat(poses.moving_ids))
        return Derived("tf", stamp_ns, bytes(self.store.serialize_cdr(self._tf, TF_TYPE)))

    # -- markers --------------------------------------------------------------------------
    def _part(self, stamp_ns: int) -> _StampParts:
        part = self._parts.get(stamp_ns)
        if part is None:
            part = self._parts[stamp_ns] = _StampParts()
        return part

    def _markers_if_complete(self, stamp_ns: int) -> list[Derived]:
        part = self._parts[stamp_ns]
        if part.contacts is None or any(name not in part.forces for name in self.wrench_contacts):
            return []
        del self._parts[stamp_ns]
        if not part.contacts.contacts:
            return []  # a run without contacts has nothing to mark
        message = self._markers.message(stamp_ns, part.contacts.contacts, part.forces)
        return [Derived("contact_markers", stamp_ns, bytes(self.store.serialize_cdr(message, MARKERS_TYPE)))]


def _header(t: dict[str, Any], frame: str) -> Any:
    return t["std_msgs/msg/Header"](stamp=t["builtin_interfaces/msg/Time"](sec=0, nanosec=0), frame_id=frame)


def _transform(t: dict[str, Any], header: Any, child: str) -> Any:
    return t["geometry_msgs/msg/TransformStamped"](
        header=header,
        child_frame_id=child,
        transform=t["geometry_msgs/msg/Transform"](
            translation=t["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0),
            rotation=t["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
        ),
    )


def _fill(transforms: Sequence[Any], rows: FloatArray) -> None:
    for transform, row in zip(transforms, rows.tolist(), strict=True):
        tr, rot = transform.transform.translation, transform.transform.rotation
        tr.x, tr.y, tr.z, rot.x, rot.y, rot.z, rot.w = row


def z_to(normal: FloatArray) -> FloatArray:
    """Quaternion (x, y, z, w) turning +z onto ``normal`` (a marker's axis onto the surface normal)."""
    quat = pin.Quaternion.FromTwoVectors(np.array([0.0, 0.0, 1.0]), np.asarray(normal, dtype=float))
    return np.asarray(quat.coeffs(), dtype=float)


class _MarkerTemplates:
    """Per contact: surface patch (CUBE), contact point (SPHERE) and force (ARROW), reused per state."""

    COLORS: ClassVar[dict[int, tuple[float, float, float, float]]] = {  # RGBA
        SURFACE_ID: (0.55, 0.55, 0.6, 0.6),
        POINT_ID: (0.85, 0.1, 0.1, 1.0),
        FORCE_ID: (1.0, 0.55, 0.0, 1.0),
    }
    INACTIVE = (0.5, 0.5, 0.5, 1.0)

    def __init__(self, store: Typestore) -> None:
        self.t = store.types
        self._per_contact: dict[str, list[Any]] = {}
        self._anchor: dict[str, FloatArray] = {}  # first contact point on its surface [m]

    def _marker(self, ns: str, marker_id: int, kind: int, scale: tuple[float, float, float]) -> Any:
        t = self.t
        header = _header(t, WORLD_FRAME)
        r, g, b, a = self.COLORS[marker_id]
        return t["visualization_msgs/msg/Marker"](
            header=header,
            ns=ns,
            id=marker_id,
            type=kind,
            action=0,  # ADD (replaces the marker of the same ns and id)
            pose=t["geometry_msgs/msg/Pose"](
                position=t["geometry_msgs/msg/Point"](x=0.0, y=0.0, z=0.0),
                orientation=t["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
            ),
            scale=t["geometry_msgs/msg/Vector3"](x=scale[0], y=scale[1], z=scale[2]),
            color=t["std_msgs/msg/ColorRGBA"](r=r, g=g, b=b, a=a),
            lifetime=t["builtin_interfaces/msg/Duration"](sec=0, nanosec=0),  # until replaced
            frame_locked=False,
            points=[],
            colors=[],
            texture_resource="",
            texture=t["sensor_msgs/msg/CompressedImage"](
                header=_header(t, ""),
                format="",
                data=np.zeros(0, dtype=np.uint8),
            ),
            uv_coordinates=[],
            text="",
            mesh_resource="",
            mesh_file=t["visualization_msgs/msg/MeshFile"](filename="", data=np.zeros(0, dtype=np.uint8)),
            mesh_use_embedded_materials=False,
        )

    def _templates(self, name: str) -> list[Any]:
        markers = self._per_contact.get(name)
        if markers is None:
            marker_types: Any = self.t["visualization_msgs/msg/Marker"]
            surface = self._marker(name, SURFACE_ID, marker_types.CUBE, (SURFACE_PATCH_M, SURFACE_PATCH_M, 0.002))
            point = self._marker(name, POINT_ID, marker_types.SPHERE, (0.04, 0.04, 0.04))
            # ARROW with two points: shaft diameter, head diameter, head length [m].
            arrow = self._marker(name, FORCE_ID, marker_types.ARROW, (0.012, 0.03, 0.03))
            point_type = self.t["geometry_msgs/msg/Point"]
            arrow.points = [point_type(x=0.0, y=0.0, z=0.0), point_type(x=0.0, y=0.0, z=0.0)]
            markers = self._per_contact[name] = [surface, point, arrow]
        return markers

    def message(self, stamp_ns: int, contacts: Sequence[Any], forces: dict[str, FloatArray]) -> Any:
        sec, nanosec = divmod(stamp_ns, 1_000_000_000)
        out = []
        for c in contacts:
            name = str(c.name)
            surface, point, arrow = self._templates(name)
            p = np.array([c.position.x, c.position.y, c.position.z])
            n = np.array([c.normal.x, c.normal.y, c.normal.z])
            on_surface = p - float(c.residual) * n  # the contact point moved onto its surface
            # The patch is the tangent plane, centred where the contact first was: a fixed floor for a plane.
            anchor = self._anchor.setdefault(name, on_surface)
            centre = anchor - float(np.dot(anchor - on_surface, n)) * n
            _set_pose(surface, centre, z_to(n))
            _set_pose(point, p, None)
            color = self.COLORS[POINT_ID] if c.active else self.INACTIVE
            point.color.r, point.color.g, point.color.b, point.color.a = color
            markers = [surface, point]
            force = forces.get(name)
            if force is not None:
                start, end = arrow.points
                start.x, start.y, start.z = p.tolist()
                end.x, end.y, end.z = (p + FORCE_ARROW_M_PER_N * force).tolist()
                markers.append(arrow)
            for marker in markers:
                marker.header.stamp.sec, marker.header.stamp.nanosec = sec, nanosec
            out += markers
        return self.t["visualization_msgs/msg/MarkerArray"](markers=out)


def _set_pose(marker: Any, position: FloatArray, quat: FloatArray | None) -> None:
    pos = marker.pose.position
    pos.x, pos.y, pos.z = position.tolist()
    if quat is not None:
        rot = marker.pose.orientation
        rot.x, rot.y, rot.z, rot.w = quat.tolist()
