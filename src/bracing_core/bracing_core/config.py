"""Typed configuration of the plant (robot, motors, contacts) and of the simulator.

``SharedConfig`` is what both nodes read from the ``/**`` section of a scenario file;
``Plant`` is the one robot model built from it, used by the simulator and the
controller alike. Everything is validated here, once, with errors naming the parameter.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pinocchio as pin

from bracing_core import schema
from bracing_core.base import (
    BASE_JOINTS,
    TURNING_WHEELS,
    BaseError,
    Wheels,
    chart_urdf,
    passive_padded,
    wheel_problem,
    wheels_of,
)
from bracing_core.collision_shapes import check_measurable, collision_description, kept_out_contacts, shape_error
from bracing_core.contact_config import ContactConfig
from bracing_core.contacts import ContactSet, Surface
from bracing_core.dynamics import ConstrainedDynamics, InputMode, thermal_applies
from bracing_core.meshes import resolved_description
from bracing_core.model import ModelError, RobotModel
from bracing_core.motors import FIELDS as MOTOR_FIELDS
from bracing_core.motors import MotorParams
from bracing_core.params import ConfigError, Params, resolve_file
from bracing_core.schema import Section, Values
from bracing_core.sensing import PlantError, SensorConfig
from bracing_core.simulator import Simulator
from bracing_core.types import Vector

if TYPE_CHECKING:
    from bracing_core.schema.typed_values import SimulatorValues
else:  # the class the schema derives (tools/values_stubs.py declares it to mypy)
    SimulatorValues = schema.NODE_VALUES["simulator"]


def surface_key(surface: Surface) -> tuple[Any, ...]:
    """Equal for the same surface described twice (two contacts on one floor)."""
    numbers = [float(x) for name, value in vars(surface).items() if not name.startswith("_") for x in np.ravel(value)]
    return (surface.kind, *(round(x, 12) for x in numbers))


@dataclass(frozen=True)
class SharedConfig:
    """robot, motors, contacts, input mode: the plant both nodes agree on."""

    urdf: Path
    joint_names: tuple[str, ...]  # the configuration's joint order (motors are listed in it)
    gravity: tuple[float, float, float]
    input_mode: InputMode
    motors: MotorParams  # in joint_names order
    contacts: tuple[ContactConfig, ...]
    locked_joints: tuple[str, ...] = ()
    locked_positions: tuple[float, ...] = ()  # robot.locked_joints order; empty = 0 each
    collision_frames: tuple[str, ...] = ()
    bracing: bool = True
    free_space: bool = False  # the surfaces only watched
    package_paths: tuple[str, ...] = ()  # robot.package_paths: where package://NAME/... meshes are looked up
    torque_limit_from_urdf: bool = False  # motors.torque_limit_from_urdf: each joint's URDF <limit effort>
    collision_links: tuple[str, ...] = ()  # robot.collision_links: links whose shapes are kept out of the surfaces
    collision_geometry: bool = False  # robot.collision_geometry: every link's shapes measured at each state
    penetration_tolerance: float = 0.005  # [m] robot.penetration_tolerance: deeper links are warned about
    base: str = "fixed"  # robot.base: fixed | planar | diff_drive
    wheels: Wheels | None = None  # robot.base: diff_drive's wheels

    @property
    def uses_shapes(self) -> bool:
        """Whether the engine loads the URDF's collision shapes (a measurement, a kept-out link or a contact at
        its link's shapes asks for them)."""
        return (
            self.collision_geometry or bool(self.collision_links) or any(c.point == "geometry" for c in self.contacts)
        )

    @property
    def braced_contacts(self) -> tuple[ContactConfig, ...]:
        """The contacts the controller keeps a force on (none in free space)."""
        return () if self.free_space else tuple(c for c in self.contacts if c.braced)

    @classmethod
    def from_values(cls, values: Values, search_dirs: Sequence[Path] = ()) -> SharedConfig:
        given, robot, given_motors = values.params, values.params.robot, values.params.motors
        urdf = resolve_file(robot.urdf, "robot.urdf", search_dirs)
        gravity = robot.gravity
        try:
            motors = MotorParams(
                **{f: np.array(getattr(given_motors, f)) for f in MOTOR_FIELDS},
                voltage_limit=given_motors.voltage_limit,
                torque_limit=np.array(given_motors.torque_limit, dtype=float),
                thermal=given_motors.thermal,
                ambient_temperature=given_motors.ambient_temperature,
                temperature_coefficient=given_motors.temperature_coefficient,
            )
        except ValueError as exc:
            raise ConfigError(str(exc)) from None
        bracing = given.bracing and not given.free_space
        try:
            contacts = tuple(ContactConfig.from_values(name, own, bracing) for name, own in values.contacts.items())
        except ValueError as exc:
            raise ConfigError(str(exc)) from None
        joint_names = robot.joint_names
        # A locked joint may be listed in robot.joint_names (its entry in every per-joint list then stays,
        # unused) or not (a joint the configuration never drives, such as a gripper's finger: no entry
        # anywhere); whether it is a joint of the model at all, the model says (Plant).
        return cls(
            urdf,
            joint_names,
            (gravity[0], gravity[1], gravity[2]),
            InputMode(given.input_mode),
            motors,
            contacts,
            tuple(robot.locked_joints),
            tuple(robot.locked_positions),
            tuple(robot.collision_frames),
            given.bracing,
            given.free_space,
            package_paths=tuple(robot.package_paths),
            torque_limit_from_urdf=given_motors.torque_limit_from_urdf,
            collision_links=tuple(robot.collision_links),
            collision_geometry=robot.collision_geometry,
            penetration_tolerance=robot.penetration_tolerance,
            base=robot.base,
            wheels=_wheels(robot),
        )


def _wheels(robot: Section) -> Wheels | None:
    try:
        return wheels_of(robot)
    except BaseError as exc:
        raise ConfigError(str(exc)) from None


def joint_names_mismatch(actuated: Sequence[str], model: Sequence[str], listed: Sequence[str]) -> str | None:
    """Why robot.joint_names (``listed``; ``actuated``: less the locked joints) cannot be the model's moving
    joints (``model``, the locked ones removed), pointing at the fix; None if they are the same names."""
    if sorted(actuated) == sorted(model) and len(set(actuated)) == len(actuated):
        return None
    problems = []
    twice = sorted({name for name in actuated if actuated.count(name) > 1})
    if twice:
        problems.append(f"{', '.join(map(repr, twice))} listed twice")
    unknown = [name for name in actuated if name not in model]
    if unknown:
        problems.append(
            f"{', '.join(map(repr, unknown))} {'is' if len(unknown) == 1 else 'are'} not a moving joint of it"
        )
    extra = [name for name in model if name not in actuated]
    if extra:
        them = ", ".join(extra)
        problems.append(
            f"it also moves {', '.join(map(repr, extra))}: to hold {'it' if len(extra) == 1 else 'them'} fixed, set "
            f"robot.locked_joints: [{them}] (a locked joint not in robot.joint_names needs no entry in any per-joint "
            "list; robot.locked_positions says where, default 0), or add "
            f"{'it' if len(extra) == 1 else 'them'} to robot.joint_names with a value in every per-joint list"
        )
    return f"robot.joint_names {list(listed)} do not match the model's joints {list(model)}: {'; '.join(problems)}"


def urdf_effort_limits(robot: RobotModel) -> Vector:
    """Each joint's URDF <limit effort> [N m or N], model order; 0 (no limit) where the URDF gives none."""
    effort = np.array(robot.model.effortLimit, dtype=float)
    return np.where(np.isfinite(effort) & (effort < 1e300), np.maximum(effort, 0.0), 0.0)


class Plant:
    """The robot model, motors (model joint order) and contacts built from a SharedConfig.

    One implementation for simulator and controller: both build their plant here.
    ``contact_set`` is the simulator's (every contact, and each collision frame against each
    surface); ``braced_set`` the controller's (the contacts it keeps a force on).
    """

    def __init__(self, config: SharedConfig, slip_epsilon: float, mass_scale: float = 1.0) -> None:
        try:
            if config.wheels is not None:  # before the model: the wheels' names as the URDF has them
                problem = wheel_problem(config.wheels, config.urdf, config.joint_names, config.locked_joints)
                if problem:
                    raise ConfigError(problem)
            self.robot = RobotModel.from_urdf(
                config.urdf,
                config.gravity,
                config.locked_joints,
                config.locked_positions,
                mass_scale,
                config.base,
                config.wheels,
            )
            # A differential drive's base joints have no motor: the wheels roll them (RobotModel.wheels).
            self.passive = BASE_JOINTS if self.robot.wheels is not None else ()
            if self.passive and config.input_mode is InputMode.VOLTAGE:
                raise ConfigError(TURNING_WHEELS)
            # Index array taking configuration-ordered data to model order (locked joints dropped).
            actuated = [name for name in config.joint_names if name not in config.locked_joints]
            moving = [name for name in self.robot.joint_names if name not in self.passive]
            mismatch = joint_names_mismatch(actuated, moving, config.joint_names)
            if mismatch:
                raise ConfigError(mismatch)
            if not self.passive:
                order = self.robot.joint_permutation(actuated)
        except ModelError as exc:
            raise ConfigError(str(exc)) from None
        if self.passive:  # the passive joints read the padding slot after the configured values
            slot = {name: k for k, name in enumerate(config.joint_names)}
            self.order = np.array([slot.get(name, len(slot)) for name in self.robot.joint_names], dtype=int)
        else:
            self.order = np.array([config.joint_names.index(actuated[k]) for k in order], dtype=int)
        for contact in config.contacts:
            self.frame_id(contact.frame, f"contacts.{contact.name}.frame")
        for frame in config.collision_frames:
            self.frame_id(frame, "robot.collision_frames")
        for link in config.collision_links:
            self.frame_id(link, "robot.collision_links")
        self.config = config
        if config.uses_shapes:
            check_measurable(config)
            self.robot.collision_description = collision_description(config)
        self.joint_names = self.robot.joint_names  # model order: the order of every message
        self.motors = (passive_padded(config.motors) if self.passive else config.motors).selected(self.order)
        if config.torque_limit_from_urdf:
            self.motors = dataclasses.replace(self.motors, torque_limit=urdf_effort_limits(self.robot))
        self._check_transmissions()
        self.mode = config.input_mode
        enforced = not config.free_space
        kept_out = kept_out_contacts(config, self.distinct_surfaces(), surface_key, enforced)
        contacts = [c.contact(enforced) for c in config.contacts] + kept_out
        try:
            self.contact_set = ContactSet(self.robot, contacts, slip_epsilon)
        except ValueError as exc:
            raise ConfigError(str(exc)) from None
        self.braced_set = ContactSet(self.robot, [c.contact() for c in config.braced_contacts], slip_epsilon)

    def _check_transmissions(self) -> None:
        """A prismatic joint needs a transmission radius (its motor turns a wheel or pinion); a revolute none."""
        for name, prismatic, radius in zip(
            self.joint_names, self.robot.prismatic, self.motors.transmission_radius, strict=True
        ):
            if name in self.passive:
                continue
            if prismatic and not radius > 0.0:
                raise ConfigError(
                    f"motors.transmission_radius: joint {name!r} is prismatic, so its motor drives it through a wheel "
                    "or pinion: give its radius rho [m] (> 0)"
                )
            if not prismatic and radius > 0.0:
                raise ConfigError(f"motors.transmission_radius: joint {name!r} is revolute: its radius must be 0")

    def distinct_surfaces(self) -> list[ContactConfig]:
        """The first contact on each distinct surface (two contacts on one floor: one floor)."""
        owners: dict[tuple[Any, ...], ContactConfig] = {}
        for contact in self.config.contacts:
            owners.setdefault(surface_key(contact.surface), contact)
        return list(owners.values())

    def frame_id(self, name: str, parameter: str) -> int:
        """The model frame ``name``; a ConfigError naming ``parameter`` if there is none."""
        try:
            return self.robot.frame_id(name)
        except ModelError as exc:
            raise ConfigError(f"{parameter}: {exc}") from None

    def description(self) -> tuple[str, list[str]]:
        """What the simulator publishes on ``robot_description``: the robot as simulated
        (``RobotModel.description``) with each mesh it finds as a ``file://`` path, and the mesh filenames
        it cannot find (``meshes.resolved_description``; robot.package_paths from the URDF's directory)."""
        here = self.config.urdf.parent
        dirs = [here / Path(entry).expanduser() for entry in self.config.package_paths]
        text = self.robot.description()
        if self.config.base != "fixed":
            # A mobile base as joints of the text (the chart's odom root, base_x, base_y, base_yaw): every viewer
            # that poses links from joint_states (the recorder's /tf, bracing-view, the animation,
            # robot_state_publisher) then draws the base where odom has it.
            text = chart_urdf(text, self.config.base, str(self.config.urdf))
        return resolved_description(text, dirs, here)

    @property
    def thermal(self) -> bool:
        """The windings' temperatures are modelled (voltage input and motors.thermal)."""
        return thermal_applies(self.motors, self.mode)

    @property
    def command_limit(self) -> Vector:
        """Each joint's |command| saturation in its input mode (model order; 0: none): motors.voltage_limit [V]
        in voltage mode, motors.torque_limit (or the URDF's efforts) [N m or N] in torque mode."""
        if self.mode is InputMode.VOLTAGE:
            return np.full(self.robot.nv, self.motors.voltage_limit)
        return np.array(self.motors.torque_limit, dtype=float)

    def to_model_order(self, values: Sequence[float]) -> np.ndarray:
        """Per-joint values in robot.joint_names order -> model order (locked joints dropped)."""
        if self.passive:  # a passive joint's value: 0 (the base's start at the odom origin, no gain, no motor)
            return np.append(np.asarray(values, dtype=float), 0.0)[self.order]
        return np.asarray(values, dtype=float)[self.order]

    def dynamics(self, baumgarte: float = 0.0) -> ConstrainedDynamics:
        """The model of the contact set; a ConfigError for the engine's refusal of the links' shapes (a mesh it
        cannot read, a contact at its link's shapes whose link has none)."""
        try:
            return ConstrainedDynamics(self.robot, self.motors, self.contact_set, self.mode, baumgarte)
        except ValueError as exc:
            if not self.config.uses_shapes:
                raise
            raise ConfigError(shape_error(self.config, str(exc))) from None


@dataclass(frozen=True)
class SimulatorConfig(SimulatorValues):
    """The simulator node's configuration: its typed values (a field per parameter of ``schema.SIMULATOR`` and
    the shared ones, units and meaning there; ``motor_drive.*``: the current loop, ``bracing_core.drive``), the
    plant error with its URDF resolved, the sensors, and the shared plant built from them."""

    plant_error: PlantError
    sensors: SensorConfig
    shared: SharedConfig

    @classmethod
    def from_params(cls, params: Params, search_dirs: Sequence[Path] = ()) -> SimulatorConfig:
        """Validated against ``schema.SIMULATOR`` (and the shared parameters)."""
        return cls.from_values(schema.read("simulator", params), search_dirs)

    @classmethod
    def from_values(cls, values: Values[SimulatorValues], search_dirs: Sequence[Path] = ()) -> SimulatorConfig:
        given = values.params
        if given.command_source == "joint_commands" and given.stepping == "lockstep":
            raise ConfigError(
                "command_source: joint_commands does not lockstep (a ros2_control loop never waits for a simulator): "
                "set stepping to real_time or free_run"
            )
        error = given.plant_error
        urdf = str(resolve_file(error.urdf, "plant_error.urdf", search_dirs)) if error.urdf else error.urdf
        derived = {
            "plant_error": PlantError(**schema.fields_of(error) | {"urdf": urdf}),
            "sensors": SensorConfig.from_values(values),
            "shared": SharedConfig.from_values(values, search_dirs),
        }
        return cls(**schema.fields_of(given) | derived)


def with_plant_error(shared: SharedConfig, error: PlantError) -> SharedConfig:
    """``shared`` as the simulated plant has it (``shared`` itself without error: every number as it was);
    the link masses are scaled where the model is built (``Plant``'s ``mass_scale``)."""
    if error.none:
        return shared
    m = shared.motors
    motors = dataclasses.replace(
        m,
        torque_constant=m.torque_constant * error.torque_constant_scale,
        resistance=m.resistance * error.resistance_scale,
        inductance=m.inductance * error.inductance_scale,
        rotor_inertia=m.rotor_inertia * error.rotor_inertia_scale,
    )
    contacts = tuple(dataclasses.replace(c, friction=c.friction * error.friction_scale) for c in shared.contacts)
    urdf = Path(error.urdf) if error.urdf else shared.urdf
    return dataclasses.replace(shared, urdf=urdf, motors=motors, contacts=contacts)


def build_simulator(config: SimulatorConfig) -> tuple[Plant, Simulator]:
    """The plant and a simulator at the configured start (moved onto the contacts first if
    ``project_initial_position``); refuses an infeasible start."""
    plant = Plant(
        with_plant_error(config.shared, config.plant_error), config.slip_epsilon, config.plant_error.mass_scale
    )
    q0 = plant.to_model_order(config.initial_position)
    dq0 = plant.to_model_order(config.initial_velocity)
    if config.project_initial_position:
        q0 = project_initial_position(plant, q0)
    try:
        substeps = max(config.substeps, circuit_substeps(plant, q0, config.step))
        simulator = Simulator(plant.dynamics(config.baumgarte), config.step, q0, dq0, substeps)
    except ValueError as exc:
        raise ConfigError(str(exc)) from None
    simulator.engine.steady_start = config.initial_current == "steady"
    check_start(plant, simulator, config.contact_tolerance)
    return plant, simulator


RK4_ACCURATE_STEP = 0.5
"""h |lambda| of a sub-step on the fastest electromechanical mode when the step alone would exceed
STIFF_STEP. Classic RK4 is stable to 2.79 there, but accurate only well below: on a gear-100 arm with
L / R = 0.2 ms, 1 s of the loop at h |lambda| = 2, 1 and 0.5 is 8.5e-4, 5.1e-5 and 3.9e-7 rad (0.76,
0.77 and 0.0009 N) off the 128-sub-step run."""
STIFF_STEP = 1.0
"""h |lambda| up to which a step needs no sub-step of its own: the shipped scenarios' motors reach 0.0035
(the paper's: 0.12, its gear damping on a light joint) to 0.73 (the 7-link arms'), validated at one
sub-step, so their arithmetic stays as it was."""


def circuit_substeps(plant: Plant, q0: Vector, step: float) -> int:
    """The RK4 sub-steps per ``step`` [s] the motors' circuits need (voltage input; 1 in torque input).

    The fastest motion of the motors in the loop is the linear electromechanical system at the start,
    with the contacts ignored (they only remove directions):

        d/dt [dq; i] = [[-Mc^-1 Dc, Mc^-1 K_m], [-K_m / L, -R / L]] [dq; i]

    Its fastest eigenvalue is the circuit's own R / L (the paper's motors: 3.5 /s) or, for a geared
    motor with a small L, the coupled electromechanical mode: the back-EMF's damping K_m^2 / R on a light
    joint (a gear-100 servo on the paper arm: ~5000 /s) is mechanical, so no exact or implicit treatment
    of the circuit alone removes it. Where the step alone has h |lambda| above STIFF_STEP, sub-steps of
    h |lambda| <= RK4_ACCURATE_STEP keep classic RK4 stable and accurate; below it one sub-step, as every
    shipped scenario had (bit for bit). ``substeps`` larger than this is kept.
    """
    if plant.mode is not InputMode.VOLTAGE:
        return 1
    fastest = electromechanical_rate(plant, q0)
    if step * fastest <= STIFF_STEP:
        return 1
    return math.ceil(step * fastest / RK4_ACCURATE_STEP)


def electromechanical_rate(plant: Plant, q0: Vector) -> float:
    """[1/s] the fastest eigenvalue's magnitude of the motors' linear electromechanical system at ``q0``
    (``circuit_substeps``)."""
    motors, robot = plant.motors, plant.robot
    inertia = pin.crba(robot.model, robot.data, np.asarray(q0, dtype=float))
    inertia = np.triu(inertia) + np.triu(inertia, 1).T + np.diag(motors.reflected_inertia)
    inverse = np.linalg.inv(inertia)
    k_m, damping = motors.reflected_constant, robot.damping + motors.reflected_damping
    system = np.block(
        [
            [-inverse * damping, inverse * k_m],
            [np.diag(-k_m / motors.inductance), np.diag(-motors.resistance / motors.inductance)],
        ]
    )
    return float(np.max(np.abs(np.linalg.eigvals(system))))


UNILATERAL_PROJECTION_M = 0.05
"""A braced unilateral contact that starts at most this far above its surface [m] is put on it by
``project_initial_position``: a posture measured or guessed by hand is off by millimetres to
centimetres, and the controller braces the contact, so it is meant to be on it. Further up, the
start is in the air on purpose (a drop onto the surface): left as given."""


def projected_contacts(plant: Plant, metric: ConstrainedDynamics, q0: Vector) -> list[int]:
    """The contacts (rows of ``plant.contact_set``) ``project_initial_position`` puts on their surfaces
    at ``q0``: every bilateral one, and every braced unilateral one that starts through its surface, on
    it (kept there while the others move the arm), or above it by at most ``UNILATERAL_PROJECTION_M``.
    An obstacle (no desired_normal_force) and a collision frame are left alone: nothing asks them to
    touch, and one that starts through its surface is refused by ``check_start``. ``metric``: the
    plant's dynamics, for the residuals."""
    contacts = plant.contact_set.contacts
    braced = {c.name for c in plant.config.braced_contacts}
    rows = [j for j, c in enumerate(contacts) if not c.unilateral]
    candidates = [j for j, c in enumerate(contacts) if c.unilateral and c.enforced and c.name in braced]
    if not candidates:
        return rows  # the paper's case: bilateral contacts only, as before
    residual = metric.terms(q0, np.zeros(plant.robot.nv)).residual
    return sorted(rows + [j for j in candidates if residual[j] <= UNILATERAL_PROJECTION_M])


def project_initial_position(plant: Plant, q0: Vector) -> Vector:
    """The posture nearest ``q0`` (joint-space metric M) where the contacts of ``projected_contacts``
    hold: every bilateral one, and each braced unilateral one that starts through, on or just above
    its surface (``UNILATERAL_PROJECTION_M``)."""
    # in the metric of M (torque mode: no rotor inertia), whatever the input mode
    metric = ConstrainedDynamics(plant.robot, plant.motors, plant.contact_set, InputMode.TORQUE)
    try:
        return metric.project(q0, projected_contacts(plant, metric, q0))
    except ValueError as exc:
        raise ConfigError(f"project_initial_position: {exc}") from None


def check_start(plant: Plant, simulator: Simulator, tolerance: float) -> None:
    """A start state must satisfy every held contact (|C| <= tolerance; a unilateral one may also
    start above its surface, released), and every contact must be able to push: a frame that no
    joint can move along the surface normal (n^T J = 0) gives a singular system. The error names
    every contact that is off."""
    contacts = plant.contact_set.contacts
    if not contacts:
        return
    terms = simulator.dynamics.terms(simulator.position, simulator.velocity)
    enforced = np.array([c.enforced for c in contacts])
    for contact, row, held in zip(contacts, terms.normal_jacobian, enforced, strict=True):
        if held and not contact.unilateral and float(np.linalg.norm(row)) < 1e-9:
            raise ConfigError(
                f"contacts.{contact.name}: no joint moves frame {contact.frame!r} along the surface normal "
                f"at the start (n^T J = 0), so the contact cannot hold a force; check contacts.{contact.name}"
            )
    unilateral = np.array([c.unilateral for c in contacts])
    released = ~enforced | (unilateral & (terms.residual > tolerance))  # in flight, or only watched
    off = [
        f"contact {c.name!r} (frame {c.frame!r}) is {residual:+.6g} m off its {c.surface.kind}"
        for c, residual, free in zip(contacts, terms.residual, released, strict=True)
        if abs(residual) > tolerance and not free
    ]
    if off:
        raise ConfigError(
            f"infeasible start: {'; '.join(off)} (tolerance {tolerance:g} m; negative: through it); change "
            "initial_position or the surface, or set project_initial_position"
        )
    if released.any():
        simulator.set_active(~released)
