"""The robot model: a pinocchio model loaded from URDF, shared by simulator and controller.

``RobotModel.compute(q, dq)`` runs one pinocchio pass (``computeAllTerms``) and places
the frames; ``frame_position`` / ``frame_jacobian`` and ``ContactSet.evaluate`` then read
that pass without recomputing kinematics.

``RobotModel.with_armature(J_m)`` gives an independent copy (own pinocchio Model and Data)
whose ``model.armature`` holds a diagonal rotor inertia, so that pinocchio's ``crba`` /
``computeAllTerms`` return M + J_m directly and ``pinocchio.cholesky`` factorises it; the
simulator's dynamics and the controller each keep such a copy, so their passes do not
disturb the shared model's Data.

Locked joints (``robot.locked_joints``) leave the model through pinocchio's
``buildReducedModel``; ``simulated_urdf`` writes the same robot back as URDF text (each locked
joint a fixed joint at its locked position): what the simulator publishes on
``robot_description``, so that every viewer (robot_state_publisher, RViz, Foxglove, the
recorder's /tf, bracing-view, the animation) poses the robot that was simulated from that
description and the JointStates, which carry the moving joints only.
``RobotModel.from_xml`` loads such a text (the viewers' kinematics).
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pinocchio as pin

from bracing_core.base import BASE_JOINTS, BaseError, Wheels, axle_problem, braked, chart_urdf
from bracing_core.types import Vector

_WORLD = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED


class ModelError(ValueError):
    """A robot description that cannot be used (missing file, unknown frame, bad joints)."""


class RobotModel:
    """Kinematics and dynamics of a fixed-base chain of 1-dof revolute/prismatic joints.

    Joint order is pinocchio's (the URDF tree order); ``joint_names`` gives it.
    Link-side viscous friction D comes from the URDF ``<dynamics damping>``.
    """

    def __init__(
        self,
        model: pin.Model,
        source: str = "<model>",
        locked_joints: Sequence[str] = (),
        locked_positions: Sequence[float] = (),
    ) -> None:
        if model.nq != model.nv:
            joints = [
                f"{model.names[j]!r} ({model.joints[j].shortname()})"
                for j in range(1, model.njoints)
                if model.nqs[j] != model.nvs[j] or model.nvs[j] != 1
            ]
            raise ModelError(
                f"{source}: only 1-dof joints are supported (revolute, continuous, prismatic; a planar root joint), "
                f"not {', '.join(joints)}: make {'it' if len(joints) == 1 else 'them'} fixed in the URDF"
            )
        if model.nv == 0:
            raise ModelError(f"{source}: the model has no moving joints")
        for joint in range(1, model.njoints):
            mass = float(model.inertias[joint].mass)
            if not mass > 0.0 and not (mass == 0.0 and _massless_allowed(model, joint)):  # also catches NaN
                links = [f.name for f in model.frames if f.parentJoint == joint and f.type == pin.FrameType.BODY]
                raise ModelError(
                    f"{source}: link {links[0] if links else model.names[joint]!r} (moved by {model.names[joint]!r}) "
                    f"has mass {mass} kg; every moving link needs a positive mass (a massless carriage only behind "
                    "a prismatic joint or base_yaw)"
                )
        self.model = model
        self.data = model.createData()
        self.source = source
        # The text pinocchio read when it is not the file's own (``base.chart_urdf`` rewrote it): what the
        # engine builds the same model from; "" = the file at urdf_path as it is.
        self.urdf_xml = ""
        self.base = "fixed"
        # robot.base: diff_drive's wheels (None: none); the engine's rolling rows hold them to the ground
        self.wheels: Wheels | None = None
        # What the engine rebuilds the same model from (bracing_engine.Robot): the URDF, gravity and
        # the locked joints with their positions (0 each if none are given).
        self.urdf_path = source
        self.gravity: Vector = np.array(model.gravity.linear, dtype=float)
        self.locked_joints = tuple(locked_joints)
        self.locked_positions = tuple(float(v) for v in locked_positions) or (0.0,) * len(self.locked_joints)
        self.mass_scale = 1.0  # every moving link's mass and inertia times this (from_urdf's mass_scale)
        self.joint_names: tuple[str, ...] = tuple(model.names[j] for j in range(1, model.njoints))
        self.damping: Vector = np.array(model.damping, dtype=float)
        # Prismatic joints move in metres (a force drives them); the rest rotate.
        self.prismatic = np.array(
            [model.joints[j].shortname().startswith("JointModelP") for j in range(1, model.njoints)]
        )
        # The URDF's position limits (pinocchio reads <limit lower upper>).
        self.lower_limits: Vector = np.array(model.lowerPositionLimit, dtype=float)
        self.upper_limits: Vector = np.array(model.upperPositionLimit, dtype=float)

    @classmethod
    def from_urdf(
        cls,
        path: str | Path,
        gravity: Sequence[float] = (0.0, 0.0, -9.81),
        locked_joints: Sequence[str] = (),
        locked_positions: Sequence[float] = (),
        mass_scale: float = 1.0,
        base: str = "fixed",
        wheels: Wheels | None = None,
    ) -> RobotModel:
        """The URDF's model; ``locked_joints`` are held at ``locked_positions`` (default 0) and removed
        with pinocchio's ``buildReducedModel`` (their links ride along, rigidly); every moving link's mass
        and rotational inertia times ``mass_scale`` (a plant's model error; the engine does the same);
        ``base`` (robot.base) and the URDF's continuous joints as ``base.chart_urdf`` reads them; ``wheels``
        (robot.base: diff_drive) roll without slipping, or, both locked (a braked base), hold the base where
        it is locked too (base_x, base_y, base_yaw added to the locked joints, at 0 unless listed)."""
        path = Path(path)
        if not path.is_file():
            raise ModelError(f"robot.urdf: file not found: {path}")
        try:
            model = pin.buildModelFromUrdf(str(path))
        except Exception as exc:  # pinocchio raises plain RuntimeError/ValueError on bad XML
            raise ModelError(f"robot.urdf: pinocchio cannot load {path}: {exc}") from exc
        try:
            text = path.read_text(encoding="utf-8")
            charted = chart_urdf(text, base, f"robot.urdf {path}")
            if charted is not text:  # continuous joints or a planar base: the chart's text (base.py)
                model = pin.buildModelFromXML(charted)
        except (OSError, UnicodeDecodeError, BaseError) as exc:
            raise ModelError(str(exc)) from None
        if wheels is not None:
            problem = axle_problem(model, wheels)
            if problem:
                raise ModelError(problem)
            try:
                wheels, locked_joints, locked_positions = braked(wheels, locked_joints, locked_positions)
            except BaseError as exc:
                raise ModelError(str(exc)) from None
        robot = cls._built(model, str(path), gravity, locked_joints, locked_positions)
        robot.urdf_xml = "" if charted is text else charted
        robot.base, robot.wheels = base, wheels
        if mass_scale != 1.0:
            for k, inertia in enumerate(robot.model.inertias):
                robot.model.inertias[k] = pin.Inertia(
                    mass_scale * inertia.mass, inertia.lever, mass_scale * inertia.inertia
                )
            robot.data = robot.model.createData()
            robot.mass_scale = float(mass_scale)
        return robot

    @classmethod
    def from_xml(
        cls,
        urdf_xml: str,
        source: str = "robot_description",
        gravity: Sequence[float] = (0.0, 0.0, -9.81),
        locked_joints: Sequence[str] = (),
        locked_positions: Sequence[float] = (),
        base: str = "fixed",
    ) -> RobotModel:
        """``from_urdf`` of URDF text (e.g. a recorded ``robot_description``); ``source`` names it in errors.

        The model's ``urdf_path`` is then ``source``, not a file: such a model is for kinematics
        (the viewers'), not for rebuilding in the engine.
        """
        try:
            model = pin.buildModelFromXML(chart_urdf(urdf_xml, base, source))
        except BaseError as exc:
            raise ModelError(str(exc)) from None
        except Exception as exc:  # pinocchio raises plain RuntimeError/ValueError on bad XML
            raise ModelError(f"{source}: pinocchio cannot read the URDF: {exc}") from exc
        robot = cls._built(model, source, gravity, locked_joints, locked_positions)
        robot.base = base
        return robot

    @classmethod
    def _built(
        cls,
        model: pin.Model,
        source: str,
        gravity: Sequence[float],
        locked_joints: Sequence[str],
        locked_positions: Sequence[float],
    ) -> RobotModel:
        gravity_vector = np.asarray(gravity, dtype=float)
        if gravity_vector.shape != (3,) or not np.all(np.isfinite(gravity_vector)):
            raise ModelError(f"robot.gravity: expected 3 finite numbers, got {list(gravity)}")
        model.gravity.linear = gravity_vector
        if locked_joints:
            model = _reduced(model, locked_joints, locked_positions, source)
        return cls(model, source, locked_joints, locked_positions)

    def with_armature(self, armature: Vector) -> RobotModel:
        """A copy (own pinocchio Model and Data) whose joint-space inertia is M + diag(armature).

        ``armature`` is per joint in model order (e.g. the reflected rotor inertia J_m).
        Everything else (frames, gravity, damping, joint order) is the same as this model's.
        """
        values = np.asarray(armature, dtype=float)
        if values.shape != (self.nv,) or not np.all(np.isfinite(values)) or np.any(values < 0.0):
            raise ModelError(f"armature: expected {self.nv} finite values >= 0, got {np.ravel(values).tolist()}")
        model = self.model.copy()
        model.armature[:] = model.armature + values
        robot = RobotModel(model, self.source, self.locked_joints, self.locked_positions)
        robot.mass_scale, robot.urdf_xml, robot.base, robot.wheels = (
            self.mass_scale,
            self.urdf_xml,
            self.base,
            self.wheels,
        )
        return robot

    def description(self) -> str:
        """The URDF text of this robot as simulated (``simulated_urdf`` of its file and locked joints):
        what the simulator publishes on ``robot_description``."""
        try:
            text = Path(self.urdf_path).read_text(encoding="utf-8")
        except OSError as exc:
            raise ModelError(f"robot.urdf: cannot read {self.urdf_path}: {exc}") from exc
        return simulated_urdf(text, self.locked_joints, self.locked_positions)

    @property
    def nv(self) -> int:
        return int(self.model.nv)

    def frame_id(self, name: str) -> int:
        if not self.model.existFrame(name):
            frames = sorted({f.name for f in self.model.frames})
            raise ModelError(f"unknown frame {name!r} in {self.source}; frames: {', '.join(frames)}")
        return int(self.model.getFrameId(name))

    def joint_permutation(self, names: Sequence[str]) -> np.ndarray:
        """Index array p with ``names[p[k]] == joint_names[k]``: reorders per-name data to model order."""
        if sorted(names) != sorted(self.joint_names) or len(set(names)) != len(names):
            raise ModelError(f"joint names {list(names)} do not match the model's joints {list(self.joint_names)}")
        position = {name: k for k, name in enumerate(names)}
        return np.array([position[name] for name in self.joint_names], dtype=int)

    # -- one pass ------------------------------------------------------------------
    def compute(self, q: Vector, dq: Vector) -> None:
        """M, h + g, Jacobians, frame placements and drift accelerations at (q, dq)."""
        pin.computeAllTerms(self.model, self.data, q, dq)
        pin.updateFramePlacements(self.model, self.data)

    # -- reads of the last pass -------------------------------------------------------
    def frame_position(self, frame: int) -> Vector:
        return np.asarray(self.data.oMf[frame].translation)

    def frame_jacobian(self, frame: int) -> Vector:
        """3 x n translational Jacobian of the frame origin, world axes."""
        return np.asarray(pin.getFrameJacobian(self.model, self.data, frame, _WORLD)[:3])

    # -- energies (for diagnostics and tests) ---------------------------------------
    def kinetic_energy(self, q: Vector, dq: Vector) -> float:
        return float(pin.computeKineticEnergy(self.model, self.data, q, dq))

    def potential_energy(self, q: Vector) -> float:
        return float(pin.computePotentialEnergy(self.model, self.data, q))


def simulated_urdf(urdf_xml: str, locked_joints: Sequence[str] = (), locked_positions: Sequence[float] = ()) -> str:
    """The URDF text of the robot as simulated: each locked joint a fixed joint at its locked position.

    ``urdf_xml`` unchanged when nothing is locked. A locked joint's ``<origin>`` becomes its
    origin composed with the joint's own motion at its position (``locked_positions``, 0 each
    if empty: the engine's ``buildReducedModel`` reference), computed by pinocchio's joint
    model, so the text's kinematics are the reduced model's; its ``<axis>``, ``<limit>``,
    ``<dynamics>``, ``<mimic>``, ``<calibration>`` and ``<safety_controller>`` go (a fixed
    joint has none). Links, visuals, inertias and every other joint stay as written.
    """
    if not locked_joints:
        return urdf_xml
    source = "robot.urdf"
    try:
        model = pin.buildModelFromXML(chart_urdf(urdf_xml, "fixed", source))  # a continuous joint: its angle
        root = ET.fromstring(urdf_xml, parser=ET.XMLParser(target=ET.TreeBuilder(insert_comments=True)))
    except Exception as exc:  # pinocchio: RuntimeError/ValueError; ElementTree: ParseError; BaseError
        raise ModelError(f"{source}: cannot read the URDF: {exc}") from exc
    # A locked base joint is none of the text's: the base's pose is the odom transform's, not the URDF's.
    kept = [
        (n, v)
        for n, v in zip(locked_joints, list(locked_positions) or [0.0] * len(locked_joints), strict=True)
        if n not in BASE_JOINTS
    ]
    if not kept:
        return urdf_xml
    locked_joints, locked_positions = [n for n, _ in kept], [v for _, v in kept]
    ids, reference = _locked_reference(model, locked_joints, locked_positions, source)
    elements = {element.get("name"): element for element in root.findall("joint")}
    for name, joint in zip(locked_joints, ids, strict=True):
        element = elements.get(name)
        if element is None:  # pinocchio found it, so only a joint outside <robot>'s children
            raise ModelError(f"robot.locked_joints: no <joint name={name!r}> directly under <robot> in {source}")
        jmodel = model.joints[joint]
        jdata = jmodel.createData()
        jmodel.calc(jdata, reference)
        placed = _origin(element) * jdata.M  # parent link -> child link at the locked position
        kind, value = element.get("type"), float(reference[model.idx_qs[joint]])
        element.set("type", "fixed")
        closing = element[-1].tail if len(element) else None  # the whitespace before </joint>
        for child in list(element):
            if child.tag in {"origin", "axis", "limit", "dynamics", "mimic", "calibration", "safety_controller"}:
                element.remove(child)
        note = ET.Comment(f" locked (robot.locked_joints): a {kind} joint held at {value!r} ")
        origin = ET.Element(
            "origin", xyz=_numbers(placed.translation), rpy=_numbers(pin.rpy.matrixToRpy(placed.rotation))
        )
        note.tail = origin.tail = element.text or "\n"
        element[:0] = [note, origin]
        element[-1].tail = closing or element[-1].tail
    return '<?xml version="1.0"?>\n' + ET.tostring(root, encoding="unicode") + "\n"


def _massless_allowed(model: pin.Model, joint: int) -> bool:
    """A massless link that its joint may move: a prismatic carriage (base_x's and base_y's, a hand-built
    stand-in's) or the link under base_yaw (a URDF's massless root), where the joint still moves inertia
    further out (its diagonal of M at the neutral posture > 0; else M would be singular). Elsewhere a
    massless moving link is a slip in the URDF."""
    prismatic = model.joints[joint].shortname().startswith("JointModelP")
    if not prismatic and model.names[joint] != BASE_JOINTS[2]:
        return False
    inertia = pin.crba(model, model.createData(), pin.neutral(model))
    index = int(model.idx_vs[joint])
    return bool(inertia[index, index] > 0.0)


def _origin(joint: ET.Element) -> pin.SE3:
    """A URDF joint's ``<origin xyz rpy>`` (identity parts where absent), as urdfdom reads it."""
    origin = joint.find("origin")
    xyz = (origin.get("xyz") if origin is not None else None) or "0 0 0"
    rpy = (origin.get("rpy") if origin is not None else None) or "0 0 0"
    rotation = pin.rpy.rpyToMatrix(np.array([float(v) for v in rpy.split()]))
    return pin.SE3(rotation, np.array([float(v) for v in xyz.split()]))


def _numbers(values: Vector) -> str:
    """Shortest text that reads back as the same floats (repr), so the text is as exact as the model."""
    return " ".join(repr(float(v)) for v in values)


def _locked_reference(
    model: pin.Model, locked: Sequence[str], positions: Sequence[float], source: str
) -> tuple[list[int], Vector]:
    """The joint ids of ``locked`` and a configuration holding them at ``positions`` (0 each if empty)."""
    values = list(positions) or [0.0] * len(locked)
    reference = pin.neutral(model)
    ids = []
    for name, value in zip(locked, values, strict=True):
        if not model.existJointName(name):
            raise ModelError(f"robot.locked_joints: {name!r} is not a joint of {source}")
        joint = model.getJointId(name)
        if model.nqs[joint] != 1 or model.nvs[joint] != 1:
            raise ModelError(
                f"robot.locked_joints: {name!r} is a {model.joints[joint].shortname()} joint "
                f"(nq={model.nqs[joint]}, nv={model.nvs[joint]}), not a 1-dof one: only revolute, continuous and "
                "prismatic joints (and base_x, base_y, base_yaw) lock; make it fixed in the URDF"
            )
        reference[model.idx_qs[joint]] = value
        ids.append(joint)
    if len(ids) == model.njoints - 1:
        raise ModelError("robot.locked_joints: every joint is locked; nothing would move")
    return ids, reference


def _reduced(model: pin.Model, locked: Sequence[str], positions: Sequence[float], source: str) -> pin.Model:
    """``model`` with the joints ``locked`` fixed at ``positions`` (0 each if empty)."""
    ids, reference = _locked_reference(model, locked, positions, source)
    return pin.buildReducedModel(model, ids, reference)
