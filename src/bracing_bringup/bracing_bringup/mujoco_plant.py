"""A scenario's robot in MuJoCo (the pinned ``mujoco`` wheel): pure numerics, no ROS.

The robot is MuJoCo's own import of the scenario's URDF as our simulator simulates it (each locked
joint a fixed joint at its locked position: ``Plant.description``), without its visual and collision
geometry: the only collisions are a small sphere at each contact frame (radius ``CONTACT_RADIUS``,
centred on the frame, the contact's friction) against the scenario's surfaces as MuJoCo geoms, moved
out by that radius so that the sphere touches a surface exactly when the frame point reaches it. A
plane becomes a MuJoCo plane, a sphere (outside) a sphere, a cylinder (outside) a long cylinder; a
surface MuJoCo cannot hold from the outside (``inside``) is refused. Link damping is the URDF's (as in
our torque-mode plant: no motors in the loop), gravity the scenario's, the integrator RK4 (as the
bench's MuJoCo reference), the friction cone elliptic (MuJoCo's closest to a Coulomb circle) and the
contacts MuJoCo's soft ones at their default solref/solimp.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import mujoco
import numpy as np

from bracing_core.config import SimulatorConfig, build_simulator
from bracing_core.contacts import Cylinder, Plane, Sphere
from bracing_core.types import Vector

CONTACT_RADIUS = 0.005  # [m] the sphere at each contact frame (the bench's elbow sphere)
CYLINDER_HALF_LENGTH = 50.0  # [m] an "infinite" cylinder surface, as MuJoCo geoms are bounded


class MujocoModelError(ValueError):
    """The scenario cannot be put in MuJoCo (a surface it cannot hold, a frame it does not have)."""


def bare_urdf(description: str) -> str:
    """The URDF without visual and collision elements (the contact spheres are the only collisions) and
    a <mujoco> extension that keeps every link a body of its own (a contact frame may be a fixed link)."""
    text = re.sub(r"<(visual|collision)\b.*?</\1>", "", description, flags=re.DOTALL)
    text = re.sub(r"<(visual|collision)\b[^>]*/>", "", text)
    extension = '<mujoco><compiler fusestatic="false" discardvisual="true" balanceinertia="false"/></mujoco>'
    return re.sub(r"(<robot\b[^>]*>)", r"\1" + extension, text, count=1)


def _quat_z_to(normal: Vector) -> list[float]:
    """A unit quaternion (w, x, y, z) turning +z onto ``normal``."""
    quat = np.zeros(4)
    mujoco.mju_quatZ2Vec(quat, np.asarray(normal, dtype=float))
    return quat.tolist()


def _add_surface(spec: mujoco.MjSpec, name: str, surface: object, friction: float) -> None:
    """The surface as a world geom, moved out by CONTACT_RADIUS."""
    geom = spec.worldbody.add_geom(name=f"surface_{name}", condim=3, friction=[friction, 0.0, 0.0])
    geom.contype, geom.conaffinity = 0, 1
    if isinstance(surface, Plane):
        geom.type = mujoco.mjtGeom.mjGEOM_PLANE
        geom.size = [0.0, 0.0, 1.0]
        geom.pos = (surface.normal * (surface.offset - CONTACT_RADIUS)).tolist()
        geom.quat = _quat_z_to(surface.normal)
    elif isinstance(surface, Sphere) and not surface.inside:
        geom.type = mujoco.mjtGeom.mjGEOM_SPHERE
        geom.size = [surface.radius + CONTACT_RADIUS, 0.0, 0.0]
        geom.pos = surface.center.tolist()
    elif isinstance(surface, Cylinder) and not surface.inside:
        geom.type = mujoco.mjtGeom.mjGEOM_CYLINDER
        geom.size = [surface.radius + CONTACT_RADIUS, CYLINDER_HALF_LENGTH, 0.0]
        geom.pos = surface.point.tolist()
        geom.quat = _quat_z_to(surface.axis)
    else:
        raise MujocoModelError(f"contacts.{name}: a {type(surface).__name__} from the inside has no MuJoCo geom")


def _add_contact_sphere(spec: mujoco.MjSpec, name: str, frame: str, friction: float) -> None:
    body = spec.body(frame)
    if body is None:
        raise MujocoModelError(f"contacts.{name}.frame: {frame!r} is not a link of the URDF MuJoCo loaded")
    geom = body.add_geom(name=f"contact_{name}", type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[CONTACT_RADIUS, 0, 0])
    geom.contype, geom.conaffinity, geom.condim = 1, 0, 3
    geom.friction = [friction, 0.0, 0.0]
    geom.mass = 0.0


@dataclass
class MujocoRobot:
    """MuJoCo's model and data of a scenario, the joints' addresses in ``joint_names`` order and each
    contact's sphere geom (``contacts``' order)."""

    model: mujoco.MjModel
    data: mujoco.MjData
    joint_names: list[str]
    qpos: np.ndarray  # qpos address of each joint (joint_names order)
    dof: np.ndarray  # dof address of each joint
    contacts: list[str]
    spheres: np.ndarray  # geom id of each contact's sphere
    description: str  # the URDF as simulated (locked joints fixed): robot_description
    max_penetration: float = 0.0  # [m] the deepest MuJoCo penetration of any contact sphere so far

    @property
    def version(self) -> str:
        return str(mujoco.__version__)

    @classmethod
    def build(cls, config: SimulatorConfig) -> MujocoRobot:
        plant, sim = build_simulator(config)  # the URDF as simulated, the (projected) start
        description = plant.description()[0]
        spec = mujoco.MjSpec.from_string(bare_urdf(description))
        spec.option.timestep = config.step
        spec.option.gravity = list(config.shared.gravity)
        spec.option.integrator = mujoco.mjtIntegrator.mjINT_RK4
        spec.option.cone = mujoco.mjtCone.mjCONE_ELLIPTIC
        contacts = [c for c in config.shared.contacts if not config.shared.free_space]
        for c in contacts:
            _add_surface(spec, c.name, c.surface, c.friction)
            _add_contact_sphere(spec, c.name, c.frame, c.friction)
        model = spec.compile()
        names = list(config.shared.joint_names)
        ids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, n) for n in names]
        damping = dict(zip(plant.joint_names, plant.robot.damping, strict=True))
        model.dof_damping[model.jnt_dofadr[ids]] = [damping[n] for n in names]
        data = mujoco.MjData(model)
        spheres = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, f"contact_{c.name}") for c in contacts]
        addresses = (model.jnt_qposadr[ids], model.jnt_dofadr[ids])
        robot = cls(
            model, data, names, *addresses, [c.name for c in contacts], np.array(spheres, dtype=int), description
        )
        position = dict(zip(plant.joint_names, sim.position, strict=True))
        data.qpos[robot.qpos] = [position[n] for n in names]
        mujoco.mj_forward(model, data)
        return robot

    @property
    def time(self) -> float:
        return float(self.data.time)

    def step(self, effort: Vector) -> None:
        """One MuJoCo step with ``effort`` [N m or N] on the joints (joint_names order)."""
        self.data.qfrc_applied[:] = 0.0
        self.data.qfrc_applied[self.dof] = effort
        mujoco.mj_step(self.model, self.data)
        if self.data.ncon:
            self.max_penetration = max(self.max_penetration, float(np.max(self.penetration(), initial=0.0)))

    def state(self) -> tuple[Vector, Vector]:
        """(position, velocity) in joint_names order."""
        return self.data.qpos[self.qpos].copy(), self.data.qvel[self.dof].copy()

    def contact_forces(self) -> np.ndarray:
        """(contacts, 3): each contact sphere's total contact force on the robot [N], world axes, from
        mj_contactForce (contact frame) rotated to world; the sign per which geom the robot's is."""
        forces = np.zeros((len(self.contacts), 3))
        local = np.zeros(6)
        for i in range(self.data.ncon):
            contact = self.data.contact[i]
            for k, geom in enumerate(self.spheres):
                if geom not in (contact.geom1, contact.geom2):
                    continue
                mujoco.mj_contactForce(self.model, self.data, i, local)
                world = contact.frame.reshape(3, 3).T @ local[:3]  # force of geom1 on geom2
                forces[k] += world if contact.geom2 == geom else -world
        return forces

    def penetration(self) -> np.ndarray:
        """Each contact's deepest MuJoCo penetration now [m] (0: none): -dist of its contacts."""
        depth = np.zeros(len(self.contacts))
        for i in range(self.data.ncon):
            contact = self.data.contact[i]
            for k, geom in enumerate(self.spheres):
                if geom in (contact.geom1, contact.geom2):
                    depth[k] = max(depth[k], -float(contact.dist))
        return depth
