"""A scenario's robot in MuJoCo (the pinned ``mujoco`` wheel): pure numerics, no ROS.

The robot is MuJoCo's own import of the scenario's URDF as our simulator simulates it (each locked
joint a fixed joint at its locked position: ``Plant.description``), without its visual geometry. A
contact at a frame (``point: frame``, the default) is a small sphere at the frame (radius
``CONTACT_RADIUS``, centred on the frame, the contact's friction) against the contact's surface as a
MuJoCo geom, moved out by that radius so that the sphere touches the surface exactly when the frame
point reaches it. A plane becomes a MuJoCo plane, a sphere (outside) a sphere, a cylinder (outside) a
long cylinder; a surface MuJoCo cannot hold from the outside (``inside``) is refused.

The URDF's collision geometry is dropped unless ``robot.collision_geometry`` is on. Then it is kept,
and the same shapes collide as in our engine (``colliding_bodies``): the links of
``robot.collision_links`` and the frame's link of each ``point: geometry`` contact (every link moving
with the frame's joint) against every contact's surface, placed where it is (not moved out); the other
links' shapes collide with nothing (our engine only measures them), so MuJoCo's compiler leaves them out
(``discardvisual``). Robot shapes never
collide with each other (our engine has no self-collision). The contact bits keep the two kinds apart:
frame spheres meet the moved-out surfaces (``SPHERE_BIT``), link shapes the surfaces in place
(``SHAPE_BIT``). A link shape's friction is 0, so that MuJoCo's (the larger of the two geoms') is the
surface's. Link damping is the URDF's (as in
our torque-mode plant: no motors in the loop), gravity the scenario's, the integrator RK4 (as the
bench's MuJoCo reference), the friction cone elliptic (MuJoCo's closest to a Coulomb circle) and the
contacts MuJoCo's soft ones at their default solref/solimp.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np

from bracing_core.config import SimulatorConfig, build_simulator, surface_key
from bracing_core.contacts import Cylinder, Plane, Sphere
from bracing_core.params import ConfigError
from bracing_core.types import Vector

CONTACT_RADIUS = 0.005  # [m] the sphere at each contact frame (the bench's elbow sphere)
SPHERE_BIT = 1  # contype of the frame spheres, conaffinity of the surfaces moved out by CONTACT_RADIUS
SHAPE_BIT = 2  # contype of the colliding link shapes, conaffinity of the surfaces in place
CYLINDER_HALF_LENGTH = 50.0  # [m] an "infinite" cylinder surface, as MuJoCo geoms are bounded


class MujocoModelError(ConfigError):
    """The scenario cannot be put in MuJoCo (a surface it cannot hold, a frame it does not have, a collision
    mesh it cannot read): a configuration error, said before the run starts."""


def bare_urdf(description: str, keep_collision: bool = False) -> str:
    """The URDF without visual elements, and without collision elements unless ``keep_collision`` (then
    its meshes as plain paths, found as the simulator published them: file://), with a <mujoco> extension
    that keeps every link a body of its own (a contact frame may be a fixed link) and mesh paths whole."""
    dropped = "visual" if keep_collision else "visual|collision"
    text = re.sub(rf"<({dropped})\b.*?</\1>", "", description, flags=re.DOTALL)
    text = re.sub(rf"<({dropped})\b[^>]*/>", "", text)
    if keep_collision:
        text = re.sub(r'(filename\s*=\s*["\'])file://', r"\1", text)
    extension = '<mujoco><compiler fusestatic="false" discardvisual="true" balanceinertia="false"'
    extension += ' strippath="false"/></mujoco>' if keep_collision else "/></mujoco>"
    return re.sub(r"(<robot\b[^>]*>)", r"\1" + extension, text, count=1)


def _quat_z_to(normal: Vector) -> list[float]:
    """A unit quaternion (w, x, y, z) turning +z onto ``normal``."""
    quat = np.zeros(4)
    mujoco.mju_quatZ2Vec(quat, np.asarray(normal, dtype=float))
    return quat.tolist()


def _add_surface(spec: mujoco.MjSpec, name: str, surface: object, friction: float, in_place: bool = False) -> None:
    """The surface as a world geom: moved out by CONTACT_RADIUS for the frame spheres, or ``in_place`` (named
    ``shape_surface_<name>``) for the link shapes."""
    geom = spec.worldbody.add_geom(
        name=f"{'shape_' if in_place else ''}surface_{name}", condim=3, friction=[friction, 0.0, 0.0]
    )
    geom.contype, geom.conaffinity = 0, SHAPE_BIT if in_place else SPHERE_BIT
    out = 0.0 if in_place else CONTACT_RADIUS
    if isinstance(surface, Plane):
        geom.type = mujoco.mjtGeom.mjGEOM_PLANE
        geom.size = [0.0, 0.0, 1.0]
        geom.pos = (surface.normal * (surface.offset - out)).tolist()
        geom.quat = _quat_z_to(surface.normal)
    elif isinstance(surface, Sphere) and not surface.inside:
        geom.type = mujoco.mjtGeom.mjGEOM_SPHERE
        geom.size = [surface.radius + out, 0.0, 0.0]
        geom.pos = surface.center.tolist()
    elif isinstance(surface, Cylinder) and not surface.inside:
        geom.type = mujoco.mjtGeom.mjGEOM_CYLINDER
        geom.size = [surface.radius + out, CYLINDER_HALF_LENGTH, 0.0]
        geom.pos = surface.point.tolist()
        geom.quat = _quat_z_to(surface.axis)
    else:
        raise MujocoModelError(f"contacts.{name}: a {type(surface).__name__} from the inside has no MuJoCo geom")


def _add_contact_sphere(spec: mujoco.MjSpec, name: str, frame: str, friction: float) -> None:
    body = spec.body(frame)
    if body is None:
        raise MujocoModelError(f"contacts.{name}.frame: {frame!r} is not a link of the URDF MuJoCo loaded")
    geom = body.add_geom(name=f"contact_{name}", type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[CONTACT_RADIUS, 0, 0])
    geom.contype, geom.conaffinity, geom.condim = SPHERE_BIT, 0, 3
    geom.friction = [friction, 0.0, 0.0]
    geom.mass = 0.0


def _compile(spec: mujoco.MjSpec, collision_geometry: bool) -> mujoco.MjModel:
    """The compiled model; with the URDF's collision shapes, a shape MuJoCo cannot load (a mesh format it has
    no decoder for: it reads STL, OBJ and MSH) is a MujocoModelError naming it."""
    try:
        return spec.compile()
    except ValueError as exc:
        if not collision_geometry:
            raise
        raise MujocoModelError(
            f"robot.collision_geometry: MuJoCo cannot load the URDF's collision shapes ({str(exc).splitlines()[0]}): "
            "give those links an STL or OBJ collision mesh, or set robot.collision_geometry: false for --engine mujoco"
        ) from None


def geometry_contacts(config: SimulatorConfig) -> list[str]:
    """The contacts placed on their frame's link's shapes (``contacts.<name>.point: geometry``)."""
    return [c.name for c in config.shared.contacts if c.point == "geometry"]


def _moving_body(body: Any) -> str:
    """The name of the nearest body up from ``body`` (itself included) that a joint moves, or the world's."""
    while body.name != "world" and not body.joints:
        body = body.parent
    return str(body.name)


def _shape_bodies(spec: mujoco.MjSpec, name: str, parameter: str, rigid: bool) -> list[str]:
    """Link ``name``, or (``rigid``) every link moving with it: the bodies whose shapes collide for it."""
    body = spec.body(name)
    if body is None:
        raise MujocoModelError(f"{parameter}: {name!r} is not a link of the URDF MuJoCo loaded")
    if not rigid:
        return [name]
    own = _moving_body(body)
    return [str(b.name) for b in spec.bodies if _moving_body(b) == own]


def colliding_bodies(spec: mujoco.MjSpec, config: SimulatorConfig, geometry: Sequence[str]) -> dict[str, list[str]]:
    """Whose URDF shapes collide, and the bodies of each: every link of robot.collision_links (its own), and
    the frame of each contact of ``geometry`` (every link moving with the frame's joint, as the engine
    takes a frame's link)."""
    out = {name: _shape_bodies(spec, name, "robot.collision_links", False) for name in config.shared.collision_links}
    for c in config.shared.contacts:
        if c.name in geometry:
            out[c.name] = _shape_bodies(spec, c.frame, f"contacts.{c.name}.frame", True)
    return out


def _keep_collision_geometry(spec: mujoco.MjSpec, colliding: dict[str, list[str]]) -> None:
    """The URDF's shapes (every geom so far): on SHAPE_BIT those of the ``colliding`` bodies, on no bit the
    rest (measured by the engine, never collided: ``discardvisual`` drops them); friction 0 (the surface's
    counts), condim 3. They add no mass: each link's <inertial> sets it (MuJoCo's inertiafromgeom auto)."""
    bodies = {body for group in colliding.values() for body in group}
    for geom in spec.geoms:
        geom.contype = SHAPE_BIT if geom.parent.name in bodies else 0
        geom.conaffinity, geom.condim, geom.friction = 0, 3, [0.0, 0.0, 0.0]


def _add_surfaces_in_place(spec: mujoco.MjSpec, config: SimulatorConfig) -> dict[str, str]:
    """Each distinct surface once, in place, named after its first contact; {contact: that geom's name}."""
    owners: dict[tuple[Any, ...], Any] = {}
    out = {}
    for c in config.shared.contacts:
        owner = owners.setdefault(surface_key(c.surface), c)
        if owner is c:
            _add_surface(spec, c.name, c.surface, c.friction, in_place=True)
        out[c.name] = f"shape_surface_{owner.name}"
    return out


@dataclass
class MujocoRobot:
    """MuJoCo's model and data of a scenario, the joints' addresses in ``joint_names`` order and, per
    contact (``contacts``' order), the robot geoms that are it (its sphere, or its link's shapes) and the
    surface geom they must touch (-1: any)."""

    model: mujoco.MjModel
    data: mujoco.MjData
    joint_names: list[str]
    qpos: np.ndarray  # qpos address of each joint (joint_names order)
    dof: np.ndarray  # dof address of each joint
    contacts: list[str]
    robot_geoms: list[frozenset[int]]  # per contact: its sphere's geom id, or its link's shapes'
    surface_geoms: np.ndarray  # per contact: the surface geom its shapes meet; -1 (a sphere): any
    description: str  # the URDF as simulated (locked joints fixed): robot_description
    max_penetration: float = 0.0  # [m] the deepest MuJoCo penetration of any contact or colliding link so far

    @property
    def version(self) -> str:
        return str(mujoco.__version__)

    @classmethod
    def build(cls, config: SimulatorConfig, geometry: Sequence[str] | None = None) -> MujocoRobot:
        """The scenario in MuJoCo; ``geometry``: the contacts on their link's shapes (default: those of
        ``point: geometry``), with robot.collision_geometry on."""
        plant, sim = build_simulator(config)  # the URDF as simulated, the (projected) start
        description = plant.description()[0]
        shared = config.shared
        spec = mujoco.MjSpec.from_string(bare_urdf(description, shared.collision_geometry))
        spec.option.timestep = config.step
        spec.option.gravity = list(shared.gravity)
        spec.option.integrator = mujoco.mjtIntegrator.mjINT_RK4
        spec.option.cone = mujoco.mjtCone.mjCONE_ELLIPTIC
        contacts = [c for c in shared.contacts if not shared.free_space]
        on_shapes = list(geometry_contacts(config) if geometry is None else geometry)
        on_shapes = on_shapes if shared.collision_geometry else []
        colliding, in_place = {}, {}
        if shared.collision_geometry:
            colliding = colliding_bodies(spec, config, on_shapes)
            _keep_collision_geometry(spec, colliding)
            in_place = _add_surfaces_in_place(spec, config) if contacts else {}
        for c in contacts:
            if c.name not in on_shapes:
                _add_surface(spec, c.name, c.surface, c.friction)
                _add_contact_sphere(spec, c.name, c.frame, c.friction)
        model = _compile(spec, shared.collision_geometry)
        names = list(shared.joint_names)
        ids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, n) for n in names]
        damping = dict(zip(plant.joint_names, plant.robot.damping, strict=True))
        model.dof_damping[model.jnt_dofadr[ids]] = [damping[n] for n in names]
        data = mujoco.MjData(model)
        robot_geoms, surfaces = [], []
        for c in contacts:
            if c.name in on_shapes:
                robot_geoms.append(_geoms_of(model, colliding[c.name]))
                surfaces.append(mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, in_place[c.name]))
            else:
                robot_geoms.append(frozenset({mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, f"contact_{c.name}")}))
                surfaces.append(-1)
        addresses = (model.jnt_qposadr[ids], model.jnt_dofadr[ids])
        robot = cls(
            model, data, names, *addresses, [c.name for c in contacts], robot_geoms, np.array(surfaces), description
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
        if self.data.ncon:  # every MuJoCo contact is a contact's or a colliding link's
            deepest = -min(float(self.data.contact[i].dist) for i in range(self.data.ncon))
            self.max_penetration = max(self.max_penetration, deepest, 0.0)

    def state(self) -> tuple[Vector, Vector]:
        """(position, velocity) in joint_names order."""
        return self.data.qpos[self.qpos].copy(), self.data.qvel[self.dof].copy()

    def _touches(self, contact: Any, k: int) -> int:
        """+1 if MuJoCo contact ``contact`` is robot contact ``k``'s with its geom second, -1 first, 0 not its."""
        surface = int(self.surface_geoms[k])
        for own, other, sign in ((contact.geom2, contact.geom1, 1), (contact.geom1, contact.geom2, -1)):
            if own in self.robot_geoms[k] and (surface < 0 or other == surface):
                return sign
        return 0

    def contact_forces(self) -> np.ndarray:
        """(contacts, 3): each contact's total contact force on the robot [N], world axes (its sphere's, or its
        link's shapes' on its surface), from mj_contactForce (contact frame) rotated to world; the sign per
        which geom the robot's is."""
        forces = np.zeros((len(self.contacts), 3))
        local = np.zeros(6)
        for i in range(self.data.ncon):
            contact = self.data.contact[i]
            for k in range(len(self.contacts)):
                sign = self._touches(contact, k)
                if sign:
                    mujoco.mj_contactForce(self.model, self.data, i, local)
                    forces[k] += sign * (contact.frame.reshape(3, 3).T @ local[:3])  # of geom1 on geom2
        return forces

    def contact_points(self) -> np.ndarray:
        """(contacts, 3): where each contact is now [m, world]: a frame contact's sphere centre (its frame); a
        contact on its link's shapes, the mean of its MuJoCo contacts' points weighted by their normal forces
        (each midway through its penetration, about 0.03 mm from either surface at rest); NaN where such a
        contact touches nothing."""
        points = np.full((len(self.contacts), 3), np.nan)
        weights = np.zeros(len(self.contacts))
        sums = np.zeros((len(self.contacts), 3))
        local = np.zeros(6)
        for k, geoms in enumerate(self.robot_geoms):
            if self.surface_geoms[k] < 0:
                points[k] = self.data.geom_xpos[next(iter(geoms))]
        on_shapes = [k for k in range(len(self.contacts)) if self.surface_geoms[k] >= 0]
        for i in range(self.data.ncon):
            contact = self.data.contact[i]
            for k in on_shapes:
                if self._touches(contact, k):
                    mujoco.mj_contactForce(self.model, self.data, i, local)
                    weights[k] += abs(local[0])
                    sums[k] += abs(local[0]) * contact.pos
        touching = (self.surface_geoms >= 0) & (weights > 0.0)
        points[touching] = sums[touching] / weights[touching, None]
        return points

    def penetration(self) -> np.ndarray:
        """Each contact's deepest MuJoCo penetration now [m] (0: none): -dist of its contacts."""
        depth = np.zeros(len(self.contacts))
        for i in range(self.data.ncon):
            contact = self.data.contact[i]
            for k in range(len(self.contacts)):
                if self._touches(contact, k):
                    depth[k] = max(depth[k], -float(contact.dist))
        return depth


def _geoms_of(model: mujoco.MjModel, bodies: Sequence[str]) -> frozenset[int]:
    """The colliding shapes (SHAPE_BIT) of these bodies."""
    ids = {mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name) for name in bodies}
    return frozenset(g for g in range(model.ngeom) if model.geom_bodyid[g] in ids and model.geom_contype[g] & SHAPE_BIT)
