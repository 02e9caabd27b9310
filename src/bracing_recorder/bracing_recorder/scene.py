"""What a 3D viewer needs to draw a run: link poses (TF) and contact markers, as rosbag2 messages.

No rclpy: the recorder feeds it the CDR bytes it records, and it answers CDR bytes of
``tf2_msgs/msg/TFMessage`` and ``visualization_msgs/msg/MarkerArray`` built with rosbags'
Jazzy typestore.

- Link poses come from the core's kinematics (``bracing_core.kinematics.LinkPoses``), the
  simulator's and the controller's model.
- ``SceneBuilder``: the messages of one recorded state: ``/tf`` (world -> every moving
  link), ``/tf_static`` (world -> the links fixed to the world, once) and
  ``contact_markers`` (per contact: its surface, the contact point and the contact force
  as an arrow of ``FORCE_ARROW_M_PER_N`` metres per newton, from ``contact_wrench/<name>``).
  A plane is drawn as a square patch of it (CUBE); a sphere or a cylinder whose geometry is known
  (``surfaces``: from the scenario) as a SPHERE or a CYLINDER marker, else as its tangent plane.

The messages of one run have one layout (the same frame ids, links, contact names, marker
strings), so bytes are made and read with :mod:`bracing_ros.cdr_template`'s byte templates: the
first message of a layout goes through rosbags' general path (message objects and the
generated (de)serialiser) and its strings and lengths make the template; the following
ones only pack / unpack their numbers. A message of another layout (another contact count
or name, another frame id) takes the general path, so the bytes are always rosbags' own.
"""

from __future__ import annotations

import struct
from collections import Counter
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, ClassVar, NamedTuple

import numpy as np
from numpy.typing import NDArray
from rosbags.interfaces import Nodetype
from rosbags.typesys.store import Typestore

from bracing_analysis.surfaces import Shape, shape_of
from bracing_core import cdr
from bracing_core.contact_roles import KEPT_OUT, role
from bracing_core.kinematics import WORLD_FRAME, LinkPoses, z_to
from bracing_core.stamps import sec_nanosec
from bracing_core.typestore import CONTACTS, MARKER_ARRAY, STRING, TF_MESSAGE, WRENCH_STAMPED
from bracing_ros import cdr_template, wire

FloatArray = NDArray[np.float64]

FORCE_ARROW_M_PER_N = 0.01
"""Length of a force arrow marker per newton of force [m/N] (10 N -> 10 cm)."""

SURFACE_PATCH_M = 2.0
"""Side of the square drawn for a surface [m] (a patch of the tangent plane); a cylinder's drawn length."""

MAX_WAITING_STATES = 100_000
"""JointStates kept while no robot_description has come (a simulator that publishes none)."""

# Marker ids within a contact's namespace.
SURFACE_ID, POINT_ID, FORCE_ID = 0, 1, 2

# The fields of the derived messages filled per message (paths of field names); the rest is fixed for a layout.
TF_VARIES = frozenset({"transforms.header.stamp", "transforms.transform"})
MARKERS_VARIES = frozenset({"markers.header.stamp", "markers.pose", "markers.color", "markers.points"})


@dataclass
class Derived:
    """One message to write: topic key (``tf``, ``tf_static``, ``contact_markers``), stamp, CDR bytes."""

    key: str
    stamp_ns: int
    data: bytes


class _Contact(NamedTuple):
    """What the markers draw of a bracing_msgs/ContactState."""

    name: str
    active: bool
    position: Sequence[float]  # x, y, z [m]
    normal: Sequence[float]
    residual: float


@dataclass(slots=True)
class _StampParts:
    contacts: list[_Contact] | None = None
    forces: dict[str, Sequence[float]] = field(default_factory=dict)  # force x, y, z [N] per contact


class SceneBuilder:
    """Turns recorded JointStates, Contacts and WrenchStampeds into /tf and contact_markers.

    Feed it every recorded message (``description``, ``joint_state``, ``contacts``,
    ``wrench``); each call returns the derived messages that became complete. JointStates
    that come before the robot description wait for it; a state's markers wait for its
    Contacts and the WrenchStamped of every contact in ``wrench_contacts``.

    ``general`` counts the messages (by kind: ``tf``, ``contact_markers``, ``contacts``,
    ``wrench``) that took rosbags' general path rather than a byte template: the first of
    each, and every one of a layout other than the first's.
    """

    def __init__(
        self, typestore: Typestore, wrench_contacts: Sequence[str] = (), surfaces: Mapping[str, Shape] | None = None
    ) -> None:
        self.store = typestore
        self.wrench_contacts = list(wrench_contacts)
        self._wrench_set = frozenset(self.wrench_contacts)
        self.poses: LinkPoses | None = None
        self.general: Counter[str] = Counter()
        self._waiting_states: list[tuple[int, bytes]] = []
        self._parts: dict[int, _StampParts] = {}
        self._tf: Any = None
        self._tf_header: Any = None
        self._tf_bytes = _Layout(typestore, TF_MESSAGE, TF_VARIES)
        self._markers = _MarkerTemplates(typestore, surfaces or {})
        self._marker_bytes = _Layout(typestore, MARKER_ARRAY, MARKERS_VARIES)
        self._states: wire.JointStateDecoder | None = None  # for the first JointState's names
        self._contacts_reader: _ContactsReader | None = None  # for the first Contacts' layout
        self._wrench_reader: _Reader | None = None  # for the first WrenchStamped's layout

    # -- inputs -------------------------------------------------------------------------
    def description(self, data: bytes) -> list[Derived]:
        """The recorded std_msgs/String robot_description: /tf_static, then every waiting /tf."""
        if self.poses is not None:
            return []  # the first description wins; a republished one is the same robot
        urdf = str(self._read(data, STRING).data)
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
        part = self._part(stamp_ns)
        part.contacts = self._read_contacts(data)
        return self._markers_if_complete(stamp_ns, part)

    def wrench(self, contact: str, stamp_ns: int, data: bytes) -> list[Derived]:
        part = self._part(stamp_ns)
        part.forces[contact] = self._read_force(data)
        return self._markers_if_complete(stamp_ns, part)

    def _read(self, data: bytes, type_name: str) -> Any:
        return self.store.deserialize_cdr(data, type_name)

    def _read_joint_state(self, data: bytes) -> wire.JointStateData:
        """Names and positions: wire's decoder of the first JointState's names (itself falling back to rosbags)."""
        if self._states is None:
            state = wire.decode_joint_state(data)
            self._states = wire.JointStateDecoder(state.name)
            return state
        return self._states.decode(data)

    def _read_contacts(self, data: bytes) -> list[_Contact]:
        reader = self._contacts_reader
        if reader is not None:
            contacts = reader.read(data)
            if contacts is not None:
                return contacts
        message = self._read(data, CONTACTS)
        self.general["contacts"] += 1
        if reader is None:
            self._contacts_reader = _ContactsReader(self.store, message)
        return [
            _Contact(
                str(c.name),
                bool(c.active),
                (c.position.x, c.position.y, c.position.z),
                (c.normal.x, c.normal.y, c.normal.z),
                float(c.residual),
            )
            for c in message.contacts
        ]

    def _read_force(self, data: bytes) -> Sequence[float]:
        reader = self._wrench_reader
        if reader is not None:
            values = reader.read(data)
            if values is not None:
                return values[reader.slots["wrench"][0]][:3]  # wrench: force x, y, z, torque x, y, z
        message = self._read(data, WRENCH_STAMPED)
        self.general["wrench"] += 1
        if reader is None:
            self._wrench_reader = _Reader(self.store, WRENCH_STAMPED, message)
        force = message.wrench.force
        return (force.x, force.y, force.z)

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
        return t[TF_MESSAGE](transforms=transforms), header

    def _static_message(self, poses: LinkPoses) -> bytes:
        message, _ = self._tf_template(poses.static_names)
        poses.update(poses.configuration([], []))
        _fill(message.transforms, poses.xyzquat(poses.static_ids).tolist())
        return bytes(self.store.serialize_cdr(message, TF_MESSAGE))

    def _tf_message(self, stamp_ns: int, data: bytes) -> Derived:
        assert self.poses is not None
        state = self._read_joint_state(data)
        poses = self.poses
        poses.update(poses.configuration(state.name, state.position))
        rows = poses.xyzquat(poses.moving_ids).tolist()
        stamp = sec_nanosec(stamp_ns)
        values = [slot for row in rows for slot in (stamp, row)]  # per transform: header.stamp, transform
        out = self._tf_bytes.fast((), values)
        if out is None:
            self._tf_header.stamp.sec, self._tf_header.stamp.nanosec = stamp
            _fill(self._tf.transforms, rows)
            out = self._tf_bytes.general((), self._tf, values)
            self.general["tf"] += 1
        return Derived("tf", stamp_ns, out)

    # -- markers --------------------------------------------------------------------------
    def _part(self, stamp_ns: int) -> _StampParts:
        part = self._parts.get(stamp_ns)
        if part is None:
            part = self._parts[stamp_ns] = _StampParts()
        return part

    def _markers_if_complete(self, stamp_ns: int, part: _StampParts) -> list[Derived]:
        contacts, forces = part.contacts, part.forces
        if contacts is None or not self._wrench_set <= forces.keys():
            return []
        del self._parts[stamp_ns]
        if not contacts:
            return []  # a run without contacts has nothing to mark
        stamp = sec_nanosec(stamp_ns)
        draw = self._markers.draw
        drawn = [draw(c, forces.get(c.name)) for c in contacts]
        layout = tuple([(c.name, len(markers)) for c, markers in zip(contacts, drawn, strict=True)])
        # per marker: header.stamp, pose, color, points
        values = [slot for markers in drawn for marker in markers for slot in (stamp, *marker)]
        out = self._marker_bytes.fast(layout, values)
        if out is None:
            message = self._markers.message(stamp, contacts, drawn)
            out = self._marker_bytes.general(layout, message, values)
            self.general["contact_markers"] += 1
        return [Derived("contact_markers", stamp_ns, out)]


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


def _fill(transforms: Sequence[Any], rows: list[list[float]]) -> None:
    for transform, row in zip(transforms, rows, strict=True):
        tr, rot = transform.transform.translation, transform.transform.rotation
        tr.x, tr.y, tr.z, rot.x, rot.y, rot.z, rot.w = row


_Drawn = tuple[list[float], tuple[float, float, float, float], list[float]]
"""A marker's numbers: pose (x, y, z, qx, qy, qz, qw), color (RGBA), points (x, y, z of each)."""

_IDENTITY_ROTATION = [0.0, 0.0, 0.0, 1.0]
_IDENTITY_POSE = [0.0, 0.0, 0.0, *_IDENTITY_ROTATION]


class _MarkerTemplates:
    """Per contact: surface (a plane's patch: CUBE; a sphere: SPHERE; a cylinder: CYLINDER), contact
    point (SPHERE) and force (ARROW), reused per state."""

    COLORS: ClassVar[dict[int, tuple[float, float, float, float]]] = {  # RGBA
        SURFACE_ID: (0.55, 0.55, 0.6, 0.6),
        POINT_ID: (0.85, 0.1, 0.1, 1.0),
        FORCE_ID: (1.0, 0.55, 0.0, 1.0),
    }
    INACTIVE = (0.5, 0.5, 0.5, 1.0)

    def __init__(self, store: Typestore, surfaces: Mapping[str, Shape]) -> None:
        self.t = store.types
        self._surfaces = surfaces
        self._per_contact: dict[str, list[Any]] = {}
        self._anchor: dict[str, tuple[float, float, float]] = {}  # first contact point on its surface [m]
        self._turn: dict[str, tuple[Sequence[float], list[float]]] = {}  # last normal and its z_to
        self._solid: dict[str, list[float]] = {}  # a sphere's or cylinder's marker pose
        self._shapes: dict[str, Shape | None] = {}  # _curved's answers

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
            shape = self._curved(name)
            if shape is None:
                surface = self._marker(name, SURFACE_ID, marker_types.CUBE, (SURFACE_PATCH_M, SURFACE_PATCH_M, 0.002))
            else:  # SPHERE and CYLINDER take their diameter as x and y scale (a cylinder's length as z)
                diameter = 2.0 * shape.radius
                if shape.kind == "sphere":
                    surface = self._marker(name, SURFACE_ID, marker_types.SPHERE, (diameter, diameter, diameter))
                else:
                    scale = (diameter, diameter, SURFACE_PATCH_M)
                    surface = self._marker(name, SURFACE_ID, marker_types.CYLINDER, scale)
            point = self._marker(name, POINT_ID, marker_types.SPHERE, (0.04, 0.04, 0.04))
            # ARROW with two points: shaft diameter, head diameter, head length [m].
            arrow = self._marker(name, FORCE_ID, marker_types.ARROW, (0.012, 0.03, 0.03))
            point_type = self.t["geometry_msgs/msg/Point"]
            arrow.points = [point_type(x=0.0, y=0.0, z=0.0), point_type(x=0.0, y=0.0, z=0.0)]
            # A kept-out frame's or link's surface is its owner's, drawn with the owner: no patch of its own.
            kept_out = role(name) == KEPT_OUT
            markers = self._per_contact[name] = [point, arrow] if kept_out else [surface, point, arrow]
        return markers

    def draw(self, c: _Contact, force: Sequence[float] | None) -> list[_Drawn]:
        """The numbers of a contact's markers: surface (not for a kept-out frame or link: its owner's is
        drawn), point, and the force arrow if ``force`` is known.

        Three-vectors in plain floats: numpy's ufuncs round each operation the same way, at
        several times the cost on three elements (its dot product may round its sum otherwise).
        """
        px, py, pz = position = list(c.position)
        markers: list[_Drawn] = [] if role(c.name) == KEPT_OUT else [(self._surface(c), self.COLORS[SURFACE_ID], [])]
        markers.append((position + _IDENTITY_ROTATION, self.COLORS[POINT_ID] if c.active else self.INACTIVE, []))
        if force is not None:
            fx, fy, fz = force
            k = FORCE_ARROW_M_PER_N
            markers.append((_IDENTITY_POSE, self.COLORS[FORCE_ID], [px, py, pz, px + k * fx, py + k * fy, pz + k * fz]))
        return markers

    def _surface(self, c: _Contact) -> list[float]:
        """The pose of a contact's surface marker."""
        px, py, pz = c.position
        nx, ny, nz = c.normal
        residual = float(c.residual)
        sx, sy, sz = on_surface = (px - residual * nx, py - residual * ny, pz - residual * nz)  # onto its surface
        shape = self._curved(c.name)
        if shape is not None:  # the whole surface, where it is: its pose never changes
            return self._solid_pose(c.name, shape, on_surface)
        # The patch is the tangent plane, centred where the contact first was: a fixed floor for a plane.
        ax, ay, az = self._anchor.setdefault(c.name, on_surface)
        height = (ax - sx) * nx + (ay - sy) * ny + (az - sz) * nz
        centre = [ax - height * nx, ay - height * ny, az - height * nz]
        last = self._turn.get(c.name)
        if last is None or last[0] != c.normal:  # z_to of a new normal (a plane's stays)
            last = self._turn[c.name] = (c.normal, z_to(np.array(c.normal)).tolist())
        return centre + last[1]

    def _curved(self, name: str) -> Shape | None:
        """The sphere or cylinder ``name`` is on, if its geometry is known (None: a plane, or unknown)."""
        if name not in self._shapes:  # asked per state: looked up once
            shape = shape_of(self._surfaces, name)
            self._shapes[name] = shape if shape is not None and shape.curved and shape.radius > 0.0 else None
        return self._shapes[name]

    def _solid_pose(self, name: str, shape: Shape, on_surface: Sequence[float]) -> list[float]:
        """Pose (x, y, z, qx, qy, qz, qw) of a sphere's marker (at its centre) or a cylinder's (its
        axis along the marker's z, centred where the axis passes nearest the contact's first point):
        made at the first state, the same ever after."""
        pose = self._solid.get(name)
        if pose is None:
            if shape.kind == "sphere":
                pose = [*shape.center, *_IDENTITY_ROTATION]
            else:
                point, axis = np.array(shape.point), np.array(shape.axis)
                centre = point + float(np.dot(np.asarray(on_surface) - point, axis)) * axis
                pose = [*centre.tolist(), *z_to(axis).tolist()]
            self._solid[name] = pose
        return pose

    def message(self, stamp: tuple[int, int], contacts: Sequence[_Contact], drawn: Sequence[list[_Drawn]]) -> Any:
        """The MarkerArray of the contacts' markers (``drawn``: ``draw`` of each) as message objects."""
        out = []
        for c, markers in zip(contacts, drawn, strict=True):
            for marker, (pose, color, points) in zip(self._templates(c.name), markers, strict=False):
                marker.header.stamp.sec, marker.header.stamp.nanosec = stamp
                position, orientation = marker.pose.position, marker.pose.orientation
                position.x, position.y, position.z, orientation.x, orientation.y, orientation.z, orientation.w = pose
                marker.color.r, marker.color.g, marker.color.b, marker.color.a = color
                for k, point in enumerate(marker.points):
                    point.x, point.y, point.z = points[3 * k : 3 * k + 3]
                out.append(marker)
        return self.t[MARKER_ARRAY](markers=out)


# ----------------------------------------------------------------------------- byte templates
#
# scene per state: 139 us -> 28 us (a recorded 10 s paper run, 10001 states and 1 contact, replayed through a
# SceneBuilder: CPU time, best of 3; 23 us once the first messages have made the templates, in the 2-core
# development machine's quiet moments). Before, rosbags' (de)serialisers took ~90 us of it (JointState 13, Contacts 11,
# WrenchStamped 7, TFMessage 16, MarkerArray 42); now /tf ~12 us (JointState 3, pinocchio 5, bytes 2) and markers
# ~10 us (Contacts and WrenchStamped 3, geometry 1, bytes 2, the rest bookkeeping).


class _Layout:
    """The bytes of messages of one layout: rosbags' serialiser for its first, then a wire template.

    The template is made from the first message serialised (its strings and lengths; the
    fields of ``varies`` filled per message) and kept only if it gives that message's bytes.
    A message of another layout (``key``) is serialised by rosbags.
    """

    def __init__(self, store: Typestore, typename: str, varies: frozenset[str]) -> None:
        self.store, self.typename, self.varies = store, typename, varies
        self.key: object = None
        self.template: cdr_template.Template | None = None
        self._tried = False

    def fast(self, key: object, values: Sequence[Sequence[float | int]]) -> bytes | None:
        """The message of layout ``key`` with slot k holding ``values[k]``, or None if it has no template."""
        if self.template is None or key != self.key:
            return None
        return self.template.fill(*values)

    def general(self, key: object, message: Any, values: Sequence[Sequence[float | int]]) -> bytes:
        """``message`` (holding ``values``) serialised by rosbags; the first one makes the template."""
        data = bytes(self.store.serialize_cdr(message, self.typename))
        if not self._tried:
            self._tried, self.key = True, key
            try:
                template, _ = cdr_template.message_template(
                    self.typename, message, lambda path, _: path in self.varies, self.store
                )
                if template.fill(*values) == data:
                    self.template = template
            except (ValueError, TypeError, AttributeError, struct.error):
                pass  # a layout the templates do not cover: rosbags for every message
        return data


class _Reader:
    """The numbers of messages laid out like a first one (its strings and lengths), by a wire template.

    ``read`` answers the values of the number fields (``slots``: field path -> their slot
    indices, in definition order), or None for a message of another layout.
    """

    def __init__(self, store: Typestore, typename: str, message: Any) -> None:
        self.slots: dict[str, list[int]] = {}
        self.template: cdr_template.Template | None = None
        try:
            self.template, paths = cdr_template.message_template(
                typename, message, lambda _, desc: _read_per_message(store, desc), store
            )
        except (ValueError, TypeError, AttributeError, struct.error):
            return  # a layout the templates do not cover: rosbags for every message
        for k, path in enumerate(paths):
            self.slots.setdefault(path, []).append(k)

    def read(self, data: bytes) -> list[tuple[Any, ...]] | None:
        return None if self.template is None else self.template.read(data)


class _ContactsReader:
    """bracing_msgs/Contacts with the first message's contacts (names, frames) and frame id."""

    def __init__(self, store: Typestore, message: Any) -> None:
        self._reader = _Reader(store, CONTACTS, message)
        slot = self._reader.slots.get
        self._contacts: list[tuple[str, int, int, int, int]] = []  # name, then the slots of what _Contact holds
        if self._reader.template is not None:
            names = [str(c.name) for c in message.contacts]
            fields = ("active", "position", "normal", "residual")
            self._contacts = list(zip(names, *(slot(f"contacts.{f}", []) for f in fields), strict=True))

    def read(self, data: bytes) -> list[_Contact] | None:
        values = self._reader.read(data)
        if values is None:
            return None
        return [
            _Contact(name, values[active][0], values[position], values[normal], values[residual][0])
            for name, active, position, normal, residual in self._contacts
        ]


def _read_per_message(store: Typestore, desc: Any) -> bool:
    """A reader's slot: numbers (a sequence of numbers too, its length fixed by the first message)."""
    kind, arg = desc
    if kind == Nodetype.SEQUENCE:
        return arg[0][0] == Nodetype.BASE and cdr.numbers_only(store, arg[0])
    return cdr.numbers_only(store, desc)
