"""Every parameter of both nodes, described once, as data.

A :class:`Param` is a name, a type, a default, a unit, a description and its bounds (or
choices, or length). From these tables everything else is derived: the nodes declare typed
ROS parameters with a ``ParameterDescriptor`` (``bracing_ros.parameters``), :func:`read`
validates a flat parameter dict into typed values for the configuration classes
(``bracing_core.config``), and ``tools/docs_reference.py`` writes the docs site's reference.

Scenario files have a ``/**`` section read by both nodes (:data:`SHARED`, and the per-contact
fields :data:`CONTACT` under ``contacts.<name>.``) and one section per node
(:data:`SIMULATOR`, :data:`CONTROLLER`). ``tunable`` parameters can be set while the
controller runs; every other parameter is read-only once a node has started.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from enum import Enum
from typing import Any

from bracing_core.motors import AMBIENT_TEMPERATURE, COPPER_TEMPERATURE_COEFFICIENT, HEAT_CAPACITY, THERMAL_RESISTANCE
from bracing_core.numbers import number
from bracing_core.params import ConfigError, Params


class Kind(str, Enum):  # noqa: UP042 (values are ROS parameter type names)
    DOUBLE = "double"
    INTEGER = "integer"
    BOOL = "bool"
    STRING = "string"
    DOUBLE_ARRAY = "double_array"
    STRING_ARRAY = "string_array"


@dataclass(frozen=True)
class PerJoint:
    """A default of one ``value`` per joint of robot.joint_names."""

    value: float


REQUIRED = None  # a Param without a default must be given


class _Absent:
    """The default of a parameter that may be left out, and means something by its absence."""

    def __repr__(self) -> str:
        return "ABSENT"


ABSENT = _Absent()  # read as None when not given (e.g. no desired_normal_force: an obstacle)


@dataclass(frozen=True)
class Param:
    name: str  # flat ROS name; for CONTACT fields, the part after contacts.<name>.
    kind: Kind
    default: Any  # REQUIRED, a value, or PerJoint
    description: str
    unit: str = ""
    minimum: float | None = None  # inclusive (arrays: every value)
    positive: bool = False  # > 0 (arrays: every value)
    choices: tuple[str, ...] = ()
    # a DOUBLE_ARRAY that also takes one of these words instead of numbers (contacts.<name>.point: a cylinder's
    # axis point, or where a plane's or sphere's contact point is)
    words: tuple[str, ...] = ()
    length: int | str | None = None  # a count, or the list parameter whose length it must match
    may_be_empty: bool = False  # with a length: an empty list is allowed too (and means a default)
    required_if: tuple[str, str] | None = None  # REQUIRED only when parameter [0] equals [1]
    tunable: bool = False  # the controller accepts a new value while it runs
    nodes: tuple[str, ...] = ("simulator", "controller")  # CONTACT fields: who uses it

    @property
    def required(self) -> bool:
        return self.default is REQUIRED and self.required_if is None

    def default_text(self) -> str:
        if self.default is REQUIRED:
            if self.required_if is None:
                return "required"
            return f"required if {self.required_if[0]} is {self.required_if[1]}"
        if isinstance(self.default, PerJoint):
            return f"{self.default.value:g} per joint"
        if self.default is ABSENT:
            return "none"
        if isinstance(self.default, bool):
            return str(self.default).lower()
        if isinstance(self.default, (list, tuple)):
            # As it is written in a scenario file: a bare y would be read as true (YAML 1.1, rcl).
            return "[" + ", ".join(f'"{v}"' if isinstance(v, str) else str(v) for v in self.default) + "]"
        return repr(self.default) if isinstance(self.default, str) else f"{self.default:g}"

    def bounds_text(self) -> str:
        parts = []
        if self.words:
            parts.append(" | ".join(self.words) + " | 3 numbers")
        if self.choices:
            parts.append(" | ".join(self.choices))
        if self.positive:
            parts.append("> 0")
        if self.minimum is not None:
            parts.append(f">= {self.minimum:g}")
        if isinstance(self.length, int):
            parts.append(f"{self.length} values" + (" or empty" if self.may_be_empty else ""))
        elif isinstance(self.length, str):
            parts.append(f"one per {self.length}" + (" or empty" if self.may_be_empty else ""))
        return ", ".join(parts)


def trajectory_params(
    prefix: str, default_type: str, what: str, nodes: tuple[str, ...] = ("simulator", "controller")
) -> tuple[Param, ...]:
    """The parameters of a task's desired path under ``prefix`` (the hand's and each brace's)."""
    kind = prefix + "type"
    return (
        Param(kind, Kind.STRING, default_type, what, choices=("hold", "circle", "waypoints"), nodes=nodes),
        Param(
            prefix + "center",
            Kind.DOUBLE_ARRAY,
            REQUIRED,
            "circle center",
            "m",
            length=3,
            required_if=(kind, "circle"),
            nodes=nodes,
        ),
        Param(
            prefix + "radius",
            Kind.DOUBLE,
            REQUIRED,
            "circle radius",
            "m",
            minimum=0.0,
            required_if=(kind, "circle"),
            nodes=nodes,
        ),
        Param(prefix + "period", Kind.DOUBLE, 10.0, "circle: time of one turn", "s", positive=True, nodes=nodes),
        Param(
            prefix + "direction",
            Kind.DOUBLE,
            1.0,
            "circle: +1 counter-clockwise in the plane, -1 clockwise (the paper: -1)",
            nodes=nodes,
        ),
        Param(prefix + "phase", Kind.DOUBLE, 0.0, "circle: angle at t = 0", "rad", nodes=nodes),
        Param(
            prefix + "plane",
            Kind.STRING_ARRAY,
            ["y", "z"],
            "circle: its plane, the world axes of cos and sin",
            length=2,
            nodes=nodes,
        ),
        Param(
            prefix + "waypoints",
            Kind.DOUBLE_ARRAY,
            REQUIRED,
            "waypoints: [x1, y1, z1, x2, y2, z2, ...], visited in order from the first measured position, "
            "rest to rest, each segment a minimum-jerk (quintic) profile; then held",
            "m",
            required_if=(kind, "waypoints"),
            nodes=nodes,
        ),
        Param(
            prefix + "segment_time",
            Kind.DOUBLE,
            1.0,
            "waypoints: duration of each segment",
            "s",
            positive=True,
            nodes=nodes,
        ),
        Param(
            prefix + "start_ramp",
            Kind.DOUBLE,
            0.0,
            "> 0: the reference starts where the task point is, at rest: over this T the path's time runs as "
            "tau = T (x^3 - x^4 / 2), x = t / T (then t - T / 2: the path runs T / 2 late) and the offset from "
            "the first measured position to the path's start fades on a minimum-jerk profile, so the law's first "
            "steps ask for no jump (the kick of a voltage-input start); 0: the path as given",
            "s",
            minimum=0.0,
            nodes=nodes,
        ),
    )


_MOTOR = "one per joint, in robot.joint_names order"
SHARED: tuple[Param, ...] = (
    Param(
        "robot.urdf",
        Kind.STRING,
        REQUIRED,
        "URDF of the robot (pinocchio loads it; link damping D from "
        "<dynamics damping>); a relative name is looked up in the working directory, next to the scenario "
        "file, $BRACING_ROOT/config and share/bracing_bringup/config; package://NAME/... in package NAME (the ament "
        "index, ROS_PACKAGE_PATH, the Python environment's cmeel prefix: example-robot-data's robots)",
    ),
    Param(
        "robot.joint_names",
        Kind.STRING_ARRAY,
        REQUIRED,
        "the actuated joints: the order of every per-joint list in the configuration (a locked joint listed here "
        "counts too, its values unused)",
    ),
    Param("robot.gravity", Kind.DOUBLE_ARRAY, [0.0, 0.0, -9.81], "gravity, world frame", "m/s^2", length=3),
    Param(
        "robot.locked_joints",
        Kind.STRING_ARRAY,
        [],
        "joints of the model held fixed (pinocchio's reduced model): no motor, not in the messages; one not in "
        "robot.joint_names needs no entry in any per-joint list (a gripper's fingers)",
    ),
    Param(
        "robot.locked_positions",
        Kind.DOUBLE_ARRAY,
        [],
        "where each locked joint is held, robot.locked_joints order; empty = 0 each",
        "rad or m",
        length="robot.locked_joints",
        may_be_empty=True,
    ),
    Param(
        "robot.collision_frames",
        Kind.STRING_ARRAY,
        [],
        "frames kept on the free side of every contact's surface (unilateral, inelastic touchdown)",
    ),
    Param(
        "robot.collision_links",
        Kind.STRING_ARRAY,
        [],
        "links whose URDF <collision> shapes are kept on the free side of every contact's surface (unilateral, "
        "inelastic touchdown, the surface's friction), as robot.collision_frames keeps frames: a link that touches "
        "is a contact named <link>@<contact>, with its force",
    ),
    Param(
        "robot.collision_geometry",
        Kind.BOOL,
        False,
        "measure every link's URDF <collision> shapes (box, cylinder, sphere, mesh: coal) against every contact "
        "surface at each state: link_penetration topic, summary link_penetration_max_m, a warning per link deeper "
        "than robot.penetration_tolerance; bracing-pair --engine mujoco then keeps them (those of "
        "robot.collision_links and of point: geometry contacts collide)",
    ),
    Param(
        "robot.penetration_tolerance",
        Kind.DOUBLE,
        0.005,
        "a link's shapes deeper than this inside a contact's surface are warned about (robot.collision_geometry)",
        "m",
        minimum=0.0,
    ),
    Param(
        "robot.package_paths",
        Kind.STRING_ARRAY,
        [],
        "directories in which a package://NAME/... mesh path of the URDF is looked up (DIR/NAME/...), after the "
        "ament index and ROS_PACKAGE_PATH (and before the Python environment's cmeel prefix); a relative one is "
        "taken from the URDF's directory. Meshes found are "
        "published on robot_description as file:// paths; those not found are named in one warning",
    ),
    Param(
        "robot.base",
        Kind.STRING,
        "fixed",
        "fixed: the URDF's root is the world; planar: a planar root joint whose three velocities are the joints "
        "base_x, base_y [m] (the root's world-frame position) and base_yaw [rad] (listed, driven and locked like "
        "any joint; a URDF planar joint at the root is read the same way); diff_drive: the planar root without "
        "actuators of its own, moved by the wheels rolling without slipping (robot.left_wheel_names, ...)",
        choices=("fixed", "planar", "diff_drive"),
    ),
    Param(
        "robot.left_wheel_names",
        Kind.STRING_ARRAY,
        [],
        "robot.base: diff_drive: the left wheel's joint (continuous or revolute; one per side; diff_drive_controller's "
        "name)",
    ),
    Param(
        "robot.right_wheel_names",
        Kind.STRING_ARRAY,
        [],
        "robot.base: diff_drive: the right wheel's joint, as robot.left_wheel_names",
    ),
    Param(
        "robot.wheel_radius",
        Kind.DOUBLE,
        0.0,
        "robot.base: diff_drive: the wheels' radius, > 0 (diff_drive_controller's name); unused otherwise",
        "m",
    ),
    Param(
        "robot.wheel_separation",
        Kind.DOUBLE,
        0.0,
        "robot.base: diff_drive: the distance between the wheels' centres, > 0, as the URDF has them "
        "(diff_drive_controller's name); unused otherwise",
        "m",
    ),
    Param(
        "input_mode",
        Kind.STRING,
        "voltage",
        "what the controller sends: motor voltages (eq. 41, motors in the loop) or link torques (eq. 38, direct drive)",
        choices=("voltage", "torque"),
    ),
    Param(
        "motors.torque_constant",
        Kind.DOUBLE_ARRAY,
        REQUIRED,
        f"K = K_T = K_E, {_MOTOR}",
        "V s/rad",
        positive=True,
        length="robot.joint_names",
    ),
    Param(
        "motors.resistance",
        Kind.DOUBLE_ARRAY,
        REQUIRED,
        f"armature resistance R, {_MOTOR}",
        "ohm",
        positive=True,
        length="robot.joint_names",
    ),
    Param(
        "motors.inductance",
        Kind.DOUBLE_ARRAY,
        REQUIRED,
        f"armature inductance L, {_MOTOR}",
        "H",
        positive=True,
        length="robot.joint_names",
    ),
    Param(
        "motors.rotor_inertia",
        Kind.DOUBLE_ARRAY,
        REQUIRED,
        f"rotor inertia I_m, {_MOTOR}",
        "kg m^2",
        minimum=0.0,
        length="robot.joint_names",
    ),
    Param(
        "motors.gear_ratio",
        Kind.DOUBLE_ARRAY,
        REQUIRED,
        f"gear ratio k, {_MOTOR}",
        "",
        positive=True,
        length="robot.joint_names",
    ),
    Param(
        "motors.gear_damping",
        Kind.DOUBLE_ARRAY,
        REQUIRED,
        f"viscous gear damping d_m (motor side), {_MOTOR}",
        "N m s/rad",
        minimum=0.0,
        length="robot.joint_names",
    ),
    Param(
        "motors.transmission_radius",
        Kind.DOUBLE_ARRAY,
        PerJoint(0.0),
        "rho of the wheel or pinion driving a prismatic joint (K_m = K k / rho [N/A], J_m = I_m k^2 / rho^2 [kg], "
        f"D_m = d_m k^2 / rho^2 [N s/m]); 0 for a revolute joint; {_MOTOR}",
        "m",
        minimum=0.0,
        length="robot.joint_names",
        may_be_empty=True,
    ),
    Param(
        "motors.thermal",
        Kind.BOOL,
        True,
        "winding temperatures integrated (voltage mode): C_th dT/dt = R(T) i^2 - (T - T_a) / R_th, "
        "R(T) = R_20 (1 + alpha (T - 20 degC)) with motors.resistance as R_20; false: R fixed, no temperature",
    ),
    Param(
        "motors.thermal_resistance",
        Kind.DOUBLE_ARRAY,
        PerJoint(THERMAL_RESISTANCE),
        "R_th, winding to ambient (chosen, the paper gives none: ~1 K/W winding to housing + ~2 K/W housing to "
        f"ambient of a maxon RE 50/65-class motor, whose K, R and I_m match Table 1's); {_MOTOR}",
        "K/W",
        positive=True,
        length="robot.joint_names",
        may_be_empty=True,
    ),
    Param(
        "motors.heat_capacity",
        Kind.DOUBLE_ARRAY,
        PerJoint(HEAT_CAPACITY),
        "C_th of the winding (chosen, the paper gives none: a ~70 s winding time constant over ~1 K/W winding to "
        f"housing; tau = R_th C_th = 210 s); {_MOTOR}",
        "J/K",
        positive=True,
        length="robot.joint_names",
        may_be_empty=True,
    ),
    Param(
        "motors.ambient_temperature",
        Kind.DOUBLE,
        AMBIENT_TEMPERATURE,
        "T_a, also every winding's temperature at the start (chosen: a room at 20 degC, where R(T_a) = R_20)",
        "degC",
    ),
    Param(
        "motors.temperature_coefficient",
        Kind.DOUBLE,
        COPPER_TEMPERATURE_COEFFICIENT,
        "alpha of the winding's resistance (copper)",
        "1/K",
        minimum=0.0,
    ),
    Param("motors.voltage_limit", Kind.DOUBLE, 0.0, "|v| saturation in voltage mode; 0 = none", "V", minimum=0.0),
    Param(
        "motors.torque_limit",
        Kind.DOUBLE_ARRAY,
        [0.0],
        "|tau| saturation in torque mode: one value for every joint, or one per joint of robot.joint_names; 0 = none",
        "N m or N",
        minimum=0.0,
    ),
    Param(
        "motors.torque_limit_from_urdf",
        Kind.BOOL,
        False,
        "torque mode: each joint's |tau| saturation is its URDF <limit effort> (0 or none there: no limit) instead of "
        "motors.torque_limit",
    ),
    Param(
        "contacts.names",
        Kind.STRING_ARRAY,
        [],
        "the contacts (braced, or obstacles), each described under contacts.<name>; empty = none",
    ),
    Param(
        "bracing",
        Kind.BOOL,
        True,
        "false: no brace tasks and no desired forces; every contact is an obstacle (bracing-pair --no-bracing)",
    ),
    Param(
        "free_space",
        Kind.BOOL,
        False,
        "true: the surfaces are removed (only watched, for the penetration report); the paper's free comparison "
        "(bracing-pair --free-space)",
    ),
)

CONTACT: tuple[Param, ...] = (
    Param("frame", Kind.STRING, REQUIRED, "robot frame held on the surface"),
    Param(
        "surface",
        Kind.STRING,
        "plane",
        "plane: C = n . r - offset; sphere: C = |r - center| - radius; cylinder: C = |(I - a a^T)(r - point)| - radius",
        choices=("plane", "sphere", "cylinder"),
    ),
    Param(
        "normal",
        Kind.DOUBLE_ARRAY,
        [0.0, 0.0, 1.0],
        "plane: normal n of n . r = offset (normalised); the plane pushes along +n",
        length=3,
    ),
    Param("offset", Kind.DOUBLE, 0.0, "plane: c of n . r = c", "m"),
    Param(
        "center",
        Kind.DOUBLE_ARRAY,
        REQUIRED,
        "sphere: its centre",
        "m",
        length=3,
        required_if=("surface", "sphere"),
    ),
    Param(
        "point",
        Kind.DOUBLE_ARRAY,
        REQUIRED,
        "cylinder: a point on its axis; plane or sphere: where the contact point is, frame (the frame's origin, "
        "the default) or geometry (the point of the frame's link's URDF <collision> shapes nearest the surface, "
        "recomputed at every step)",
        "m",
        length=3,
        required_if=("surface", "cylinder"),
        words=("frame", "geometry"),
    ),
    Param("axis", Kind.DOUBLE_ARRAY, [0.0, 0.0, 1.0], "cylinder: direction of its axis (normalised)", length=3),
    Param("radius", Kind.DOUBLE, 0.0, "sphere or cylinder: radius (> 0 for those surfaces)", "m", minimum=0.0),
    Param("inside", Kind.BOOL, False, "sphere or cylinder: the frame stays inside (C changes sign)"),
    Param("friction", Kind.DOUBLE, 0.0, "Coulomb friction coefficient mu", "", minimum=0.0),
    Param(
        "friction_model",
        Kind.STRING,
        "coulomb",
        "coulomb: a sticking contact is held by constraint rows while |f_t| <= mu |f_n|, a sliding one has "
        "|f_t| = mu |f_n| against the slip (stick and slip are events located inside a step); regularized: the "
        "paper's f_t = mu f_n s / sqrt(|s|^2 + slip_epsilon^2)",
        choices=("coulomb", "regularized"),
    ),
    Param(
        "unilateral",
        Kind.BOOL,
        False,
        "false: the surface holds both ways (the paper); true: it only pushes, releases and touches down "
        "(an obstacle always is)",
    ),
    Param(
        "desired_normal_force",
        Kind.DOUBLE,
        ABSENT,
        "f_nd, the normal force the controller keeps; none: an obstacle (unilateral, no brace task, only pushes)",
        "N",
        tunable=True,
    ),
    Param(
        "brace_axes", Kind.STRING_ARRAY, [], "world axes (x, y, z) of the brace position task", nodes=("controller",)
    ),
    Param(
        "kp",
        Kind.DOUBLE_ARRAY,
        [],
        "brace task stiffness, one per brace axis (gains: acceleration: 1/s^2)",
        "N/m",
        length="brace_axes",
        tunable=True,
        nodes=("controller",),
    ),
    Param(
        "kd",
        Kind.DOUBLE_ARRAY,
        [],
        "brace task damping, one per brace axis (gains: acceleration: 1/s)",
        "N s/m",
        length="brace_axes",
        tunable=True,
        nodes=("controller",),
    ),
    Param(
        "ki",
        Kind.DOUBLE_ARRAY,
        [],
        "brace task integral gain on the position error, one per brace axis (held while a command saturates: "
        "anti-windup; gains: acceleration: 1/s^3); empty = none",
        "N/(m s)",
        length="brace_axes",
        may_be_empty=True,
        minimum=0.0,
        tunable=True,
        nodes=("controller",),
    ),
    Param(
        "target",
        Kind.DOUBLE_ARRAY,
        [],
        "brace target [x, y, z] held (trajectory.type hold); empty = the brace point's first measured position",
        "m",
        length=3,
        may_be_empty=True,
        nodes=("controller",),
    ),
    *trajectory_params("trajectory.", "hold", "the brace point's desired path", ("controller",)),
    Param(
        "force_feedback.kp",
        Kind.DOUBLE,
        0.0,
        "force feedback (not in the paper): the force fed to eqs. 38/40 is f_cmd = f_nd + kp (f_nd - f_meas) + "
        "ki * integral (f_nd - f_meas) dt, f_meas the normal force measured on contact_wrench/<name>; 0 = the paper",
        "",
        minimum=0.0,
        nodes=("controller",),
    ),
    Param(
        "force_feedback.topic",
        Kind.STRING,
        "",
        "where force feedback reads f_meas: a geometry_msgs/WrenchStamped topic in world axes (frame_id world), e.g. "
        "a force_torque_sensor_broadcaster's <name>/wrench; empty = contact_wrench/<name> (the simulator's)",
        nodes=("controller",),
    ),
    Param(
        "force_feedback.ki",
        Kind.DOUBLE,
        0.0,
        "force feedback's integral gain (held while a command saturates: anti-windup); 0 = none",
        "1/s",
        minimum=0.0,
        nodes=("controller",),
    ),
)

# Both nodes have one (each its own value).
LOG_THROTTLE_PERIOD = Param(
    "log_throttle_period",
    Kind.DOUBLE,
    1.0,
    "at most one report per kind of bad input per period (wall)",
    "s",
    minimum=0.0,
)

# Both nodes have them (each its own value): what one subscribed message may carry, checked before any
# per-element work, so no single message can stall a node's loop.
MAX_MESSAGE_ELEMENTS = Param(
    "max_message_elements",
    Kind.INTEGER,
    10000,
    "the most elements (joint names, values, path poses) a subscribed message may carry; a longer one is "
    "refused before any per-element work",
    minimum=1,
)
MAX_NAME_LENGTH = Param(
    "max_name_length",
    Kind.INTEGER,
    256,
    "the longest name (joint, frame) a subscribed message may carry; a longer one is refused before any "
    "per-element work",
    "characters",
    minimum=1,
)

# A plant that differs from the controller's model (the simulator's robot and motors only; the controller
# keeps the scenario's). 1 and empty: the scenario's plant, bit for bit.
PLANT_ERROR: tuple[Param, ...] = (
    Param(
        "plant_error.mass_scale",
        Kind.DOUBLE,
        1.0,
        "every moving link's mass and rotational inertia in the simulated plant times this",
        positive=True,
    ),
    Param("plant_error.friction_scale", Kind.DOUBLE, 1.0, "every contact's mu in the plant times this", minimum=0.0),
    Param(
        "plant_error.torque_constant_scale", Kind.DOUBLE, 1.0, "every motor's K in the plant times this", positive=True
    ),
    Param("plant_error.resistance_scale", Kind.DOUBLE, 1.0, "every motor's R in the plant times this", positive=True),
    Param("plant_error.inductance_scale", Kind.DOUBLE, 1.0, "every motor's L in the plant times this", positive=True),
    Param(
        "plant_error.rotor_inertia_scale",
        Kind.DOUBLE,
        1.0,
        "every motor's rotor inertia I_m in the plant times this",
        minimum=0.0,
    ),
    Param(
        "plant_error.urdf",
        Kind.STRING,
        "",
        "the plant's own URDF (same joints and frames, e.g. other masses); empty = robot.urdf",
    ),
)

# What the controller receives, as a real arm measures it (the simulator publishes it; the truth goes to
# ground_truth/...). 0: exact and instant, bit for bit the paper's sensing.
SENSORS: tuple[Param, ...] = (
    Param(
        "sensors.noise_seed", Kind.INTEGER, 0, "seed of every sensor's noise (the same seed: the same run)", minimum=0
    ),
    Param(
        "sensors.encoder_counts_per_rev",
        Kind.INTEGER,
        0,
        "encoder counts per joint revolution (after the gear): published q on a grid of 2 pi / counts; revolute "
        "joints only; 0 = exact",
        minimum=0,
    ),
    Param(
        "sensors.position_noise_rad",
        Kind.DOUBLE,
        0.0,
        "sigma of white noise on q (before the quantisation)",
        "rad or m",
        minimum=0.0,
    ),
    Param(
        "sensors.velocity_filter_hz",
        Kind.DOUBLE,
        0.0,
        "> 0: dq measured as the finite difference of the measured q through a first-order low-pass at this "
        "cutoff (as a drive differentiates its encoder); 0 = the true dq (plus sensors.velocity_noise_rad_s)",
        "Hz",
        minimum=0.0,
    ),
    Param(
        "sensors.velocity_noise_rad_s",
        Kind.DOUBLE,
        0.0,
        "sigma of white noise on the true dq (sensors.velocity_filter_hz 0)",
        "rad/s or m/s",
        minimum=0.0,
    ),
    Param(
        "sensors.force_noise_n",
        Kind.DOUBLE,
        0.0,
        "sigma of white noise on each force component of contact_wrench/<contact>",
        "N",
        minimum=0.0,
    ),
    Param("sensors.force_bias_n", Kind.DOUBLE, 0.0, "a force sensor's offset, along the contact's normal", "N"),
    Param(
        "sensors.current_noise_a", Kind.DOUBLE, 0.0, "sigma of white noise on motor_state's currents", "A", minimum=0.0
    ),
    Param(
        "sensors.command_latency_steps",
        Kind.INTEGER,
        0,
        "a command is applied this many steps after the state it answers (zero before the first lands)",
        minimum=0,
    ),
)

SIMULATOR: tuple[Param, ...] = (
    Param(
        "initial_position",
        Kind.DOUBLE_ARRAY,
        REQUIRED,
        "q at t = 0, robot.joint_names order",
        "rad or m",
        length="robot.joint_names",
    ),
    Param(
        "initial_velocity",
        Kind.DOUBLE_ARRAY,
        PerJoint(0.0),
        "dq at t = 0, robot.joint_names order",
        "rad/s or m/s",
        length="robot.joint_names",
        may_be_empty=True,
    ),
    Param(
        "initial_current",
        Kind.STRING,
        "zero",
        "voltage input: the windings' currents at t = 0: zero (at rest), or steady: the steady current of the "
        "first command, i = (v - K_m dq) / R(T), as a drive that is powered and holding when the run starts",
        choices=("zero", "steady"),
    ),
    Param("step", Kind.DOUBLE, 0.001, "integration step (one control period in lockstep)", "s", positive=True),
    Param("substeps", Kind.INTEGER, 1, "RK4 sub-steps per step (input held)", minimum=1),
    Param("duration", Kind.DOUBLE, 10.0, "sim time to run; 0 = until stopped", "s", minimum=0.0),
    Param("baumgarte", Kind.DOUBLE, 0.0, "Baumgarte gain a of the constraint rows; 0 = the paper", "1/s", minimum=0.0),
    Param(
        "slip_epsilon",
        Kind.DOUBLE,
        1e-4,
        "eps of the regularised slip direction s / sqrt(|s|^2 + eps^2)",
        "m/s",
        positive=True,
    ),
    Param("contact_tolerance", Kind.DOUBLE, 1e-6, "largest |C| of a contact at the start", "m", positive=True),
    Param(
        "project_initial_position",
        Kind.BOOL,
        False,
        "true: initial_position is a guess, moved to the nearest posture (metric M) where every bilateral contact "
        "holds, and every braced unilateral one that starts through, on or at most 0.05 m above its surface (an "
        "obstacle is left alone); the result is logged, and a joint moved more than 0.1 rad (0.01 m) is warned about",
    ),
    Param(
        "stepping",
        Kind.STRING,
        "lockstep",
        "lockstep: one step per command answering the last state; real_time: a wall-clock timer, latest command "
        "held; free_run: as fast as it can, latest command held (use_sim_time nodes follow /clock)",
        choices=("lockstep", "real_time", "free_run"),
    ),
    Param(
        "command_source",
        Kind.STRING,
        "motor_command",
        "motor_command: bracing_msgs/MotorCommand (lockstep or not); joint_commands: sensor_msgs/JointState efforts "
        "on joint_commands_topic, as ros2_control's JointStateTopicSystem sends them (real_time or free_run), the "
        "state also on joint_states_topic",
        choices=("motor_command", "joint_commands"),
    ),
    Param(
        "joint_commands_topic",
        Kind.STRING,
        "/robot_joint_commands",
        "command_source joint_commands: the JointState whose effort [N m or N, link side] is applied "
        "(JointStateTopicSystem's joint_commands_topic, same default)",
    ),
    Param(
        "joint_states_topic",
        Kind.STRING,
        "/robot_joint_states",
        "command_source joint_commands: the full JointState (position, velocity, effort) published there too "
        "(JointStateTopicSystem's joint_states_topic, same default)",
    ),
    Param(
        "motor_drive.bandwidth",
        Kind.DOUBLE,
        100.0,
        "joint_commands in voltage mode: the current loop's bandwidth w (kp = L w, ki = R w: i/i* = w/(s + w))",
        "rad/s",
        positive=True,
    ),
    Param(
        "motor_drive.kp",
        Kind.DOUBLE_ARRAY,
        [],
        "the current loop's proportional gain, robot.joint_names order; empty = L * motor_drive.bandwidth",
        "V/A",
        length="robot.joint_names",
        may_be_empty=True,
        minimum=0.0,
    ),
    Param(
        "motor_drive.ki",
        Kind.DOUBLE_ARRAY,
        [],
        "the current loop's integral gain, robot.joint_names order; empty = R_20 * motor_drive.bandwidth",
        "V/(A s)",
        length="robot.joint_names",
        may_be_empty=True,
        minimum=0.0,
    ),
    Param("real_time_factor", Kind.DOUBLE, 1.0, "real_time stepping: sim seconds per wall second", positive=True),
    Param(
        "command_timeout",
        Kind.DOUBLE,
        5.0,
        "wall time without a valid command before the watchdog acts",
        "s",
        positive=True,
    ),
    Param(
        "watchdog_policy",
        Kind.STRING,
        "hold",
        "what the watchdog steps with: the last command, or zero",
        choices=("hold", "zero"),
    ),
    Param(
        "min_subscribers", Kind.INTEGER, 1, "lockstep: joint_states subscribers to wait for before stepping", minimum=0
    ),
    Param(
        "min_status_subscribers",
        Kind.INTEGER,
        0,
        "run_status subscribers to wait for before the first state (bracing-pair sets 2: it follows the run there, "
        "and the recorder keeps the warnings; 3 with --view)",
        minimum=0,
    ),
    Param(
        "wait_for_recorder",
        Kind.BOOL,
        False,
        "publish the first state only once every topic has a subscriber (bracing-pair sets true)",
    ),
    Param(
        "record_batch",
        Kind.INTEGER,
        0,
        "also hand the per-state messages to the recorder in batches of this many states on record_batch "
        "(bracing_msgs/RecordBatch, for bracing-recorder --from-batches; bracing-pair sets 100); 0: off",
        minimum=0,
    ),
    Param(
        "divergence_residual",
        Kind.DOUBLE,
        0.01,
        "a step taking a held contact further than this off its plane is refused",
        "m",
        positive=True,
    ),
    Param(
        "divergence_speed",
        Kind.DOUBLE,
        1000.0,
        "a step leaving a joint faster than this is refused (the "
        "watchdog acts; refused under the watchdog's own command, the run stops with exit 3)",
        "rad/s or m/s",
        positive=True,
    ),
    LOG_THROTTLE_PERIOD,
    MAX_MESSAGE_ELEMENTS,
    MAX_NAME_LENGTH,
    *PLANT_ERROR,
    *SENSORS,
)

CONTROLLER: tuple[Param, ...] = (
    Param("hand.frame", Kind.STRING, "hand", "robot frame of the hand task"),
    Param("hand.axes", Kind.STRING_ARRAY, ["y", "z"], "world axes (x, y, z) of the hand position task"),
    Param(
        "hand.kp",
        Kind.DOUBLE_ARRAY,
        REQUIRED,
        "hand task stiffness, one per hand axis (gains: acceleration: 1/s^2)",
        "N/m",
        length="hand.axes",
        tunable=True,
    ),
    Param(
        "hand.kd",
        Kind.DOUBLE_ARRAY,
        REQUIRED,
        "hand task damping, one per hand axis (gains: acceleration: 1/s)",
        "N s/m",
        length="hand.axes",
        tunable=True,
    ),
    Param(
        "hand.ki",
        Kind.DOUBLE_ARRAY,
        [],
        "hand task integral gain on the position error, one per hand axis (held while a command saturates: "
        "anti-windup; gains: acceleration: 1/s^3); empty = none",
        "N/(m s)",
        length="hand.axes",
        may_be_empty=True,
        minimum=0.0,
        tunable=True,
    ),
    Param(
        "hand.orientation.axes",
        Kind.STRING_ARRAY,
        [],
        "world axes (x, y, z) about which the hand frame's orientation is held (the error: the rotation's log map "
        "in world axes); empty = no orientation task",
    ),
    Param(
        "hand.orientation.kp",
        Kind.DOUBLE_ARRAY,
        [],
        "orientation task stiffness, one per orientation axis (gains: acceleration: 1/s^2)",
        "N m/rad",
        length="hand.orientation.axes",
        minimum=0.0,
    ),
    Param(
        "hand.orientation.kd",
        Kind.DOUBLE_ARRAY,
        [],
        "orientation task damping, one per orientation axis (gains: acceleration: 1/s)",
        "N m s/rad",
        length="hand.orientation.axes",
        minimum=0.0,
    ),
    Param(
        "hand.orientation.ki",
        Kind.DOUBLE_ARRAY,
        [],
        "orientation task integral gain, one per orientation axis (anti-windup as hand.ki; gains: acceleration: "
        "1/s^3); empty = none",
        "N m/(rad s)",
        length="hand.orientation.axes",
        may_be_empty=True,
        minimum=0.0,
    ),
    Param(
        "hand.orientation.target",
        Kind.DOUBLE_ARRAY,
        [],
        "the hand frame's orientation held, a quaternion [x, y, z, w] in world (normalised); empty = its first "
        "measured orientation. Set while running: turned to as a hand_pose_target's orientation (no kick)",
        length=4,
        may_be_empty=True,
        tunable=True,
    ),
    Param(
        "gains",
        Kind.STRING,
        "stiffness",
        "the task gains' units: stiffness = forces (kp N/m, kd N s/m, ki N/(m s), the paper's); acceleration = "
        "accelerations (kp 1/s^2, kd 1/s, ki 1/s^3) times the constrained arm's task-space inertia at each update, "
        "so one set of gains gives the same bandwidth on any arm",
        choices=("stiffness", "acceleration"),
    ),
    *trajectory_params("hand.trajectory.", "circle", "the hand's desired path"),
    Param(
        "hand.trajectory.point",
        Kind.DOUBLE_ARRAY,
        [],
        "hold: the point; empty = the hand's first measured position",
        "m",
        length=3,
        may_be_empty=True,
    ),
    Param(
        "voltage_gain",
        Kind.DOUBLE_ARRAY,
        PerJoint(1.0),
        "K_V (diagonal, > 0) of eq. 41: v = K_V tau, robot.joint_names order",
        "V/(N m)",
        length="robot.joint_names",
        tunable=True,
    ),
    Param("gravity_compensation", Kind.BOOL, False, "add g(q) to the null-space input l (not in the paper)"),
    Param(
        "voltage_law.thermal_compensation",
        Kind.BOOL,
        False,
        "voltage input: v = K_V tau R(T) / R_20 from the windings' measured temperatures (motor_state), so the "
        "current the law asks for does not fall as they warm (not in the paper)",
    ),
    Param(
        "voltage_law.back_emf_compensation",
        Kind.BOOL,
        False,
        "voltage input: the motor model inverted, v = R tau / K_m + K_m dq (R = R(T) with thermal_compensation, else "
        "R_20), so the motor delivers the law's torque back-EMF and all (K_V unused); false = the paper's v = K_V tau",
    ),
    Param(
        "null_space_posture.kp",
        Kind.DOUBLE_ARRAY,
        PerJoint(0.0),
        "posture task in the null space of the tasks (not in the paper): stiffness toward null_space_posture.rest, "
        "robot.joint_names order; 0 = the paper's null space",
        "N m/rad or N/m",
        length="robot.joint_names",
        minimum=0.0,
    ),
    Param(
        "null_space_posture.kd",
        Kind.DOUBLE_ARRAY,
        PerJoint(0.0),
        "posture task damping, robot.joint_names order: damps the joints the paper's B^+ leaves free (a wrist that "
        "moves no task point); 0 = none",
        "N m s/rad or N s/m",
        length="robot.joint_names",
        minimum=0.0,
    ),
    Param(
        "null_space_posture.rest",
        Kind.DOUBLE_ARRAY,
        [],
        "the posture task's rest position, robot.joint_names order; empty = the first measured position",
        "rad or m",
        length="robot.joint_names",
        may_be_empty=True,
    ),
    Param(
        "null_space",
        Kind.STRING,
        "paper",
        "the inverse of B in eq. 38: paper = B^+ (minimum norm); dynamically_consistent = Mc B^T (B Mc B^T)^-1 = "
        "J_c^T (J_c Mc^-1 J_c^T)^-1, whose contact torques leave the task motions alone at rest (not in the paper)",
        choices=("paper", "dynamically_consistent"),
    ),
    Param(
        "damping_lambda",
        Kind.DOUBLE,
        1e-6,
        "regularisation of the damped inverse used when B is near-singular",
        positive=True,
    ),
    Param(
        "wait_for_recorder",
        Kind.BOOL,
        False,
        "answer the first state only once a recorder subscribes to both outputs (bracing-pair sets true)",
    ),
    Param(
        "record_batch",
        Kind.INTEGER,
        0,
        "also hand the answers (motor_command, controller_state) to the recorder in batches of this many on "
        "record_batch (bracing_msgs/RecordBatch, for bracing-recorder --from-batches; bracing-pair sets 100); 0: off",
        minimum=0,
    ),
    Param(
        "command_output",
        Kind.STRING,
        "motor_command",
        "motor_command: answer each joint_states with a stamped bracing_msgs/MotorCommand; effort_forward (torque "
        "input): std_msgs/Float64MultiArray efforts on effort_command_topic at control_rate, for ros2_control's "
        "JointGroupEffortController",
        choices=("motor_command", "effort_forward"),
    ),
    Param(
        "effort_command_topic",
        Kind.STRING,
        "effort_controller/commands",
        "effort_forward: the forward controller's command topic (<controller_name>/commands)",
    ),
    Param(
        "effort_command_joints",
        Kind.STRING_ARRAY,
        [],
        "effort_forward: the order of the published efforts (the forward controller's joints list); "
        "empty = robot.joint_names",
    ),
    Param("control_rate", Kind.DOUBLE, 1000.0, "effort_forward: the command timer's rate", "Hz", positive=True),
    Param(
        "state_timeout",
        Kind.DOUBLE,
        0.0,
        "effort_forward: no command from a joint_states older than this on the node's clock (use_sim_time: "
        "/clock); zero efforts instead until a state is answered again (the forward controller holds the last "
        "command it gets, with no timeout, so silence would hold efforts computed from a stale state). 0: off",
        "s",
        minimum=0.0,
    ),
    Param(
        "base_command",
        Kind.STRING,
        "task",
        "a mobile base (base_x, base_y, base_yaw among the joints): task: the law moves the base as part of the arm; "
        "cmd_vel: the base follows cmd_vel (geometry_msgs/TwistStamped, diff_drive_controller's conventions) "
        "through a velocity loop added on its actuators (the arm taking up what it would lean on the braces), the "
        "hand and brace paths carried with the base",
        choices=("task", "cmd_vel"),
    ),
    Param(
        "cmd_vel_timeout",
        Kind.DOUBLE,
        0.5,
        "base_command cmd_vel: a cmd_vel older than this on the node's clock (the sim time answered) is ignored "
        "when it comes, and the base brakes (zero velocity) once the latest is; 0: off (diff_drive_controller's)",
        "s",
        minimum=0.0,
    ),
    Param(
        "base_velocity_kd",
        Kind.DOUBLE,
        100.0,
        "base_command cmd_vel: each base actuator's velocity loop, tau = kd (v_cmd - v) (base_x, base_y: N s/m; "
        "base_yaw: N m s/rad)",
        "N s/m or N m s/rad",
        positive=True,
    ),
    Param(
        "base_velocity_ki",
        Kind.DOUBLE,
        0.0,
        "base_command cmd_vel: the velocity loop's integral gain, on the commanded velocity's integral: tau += ki "
        "(integral of v_cmd dt - q), so the base holds where cmd_vel puts it against the law's push; 0: none",
        "N/m or N m/rad",
        minimum=0.0,
    ),
    Param(
        "targets.max_velocity",
        Kind.DOUBLE,
        0.05,
        "hand_target / hand_path / brace_target/<contact>: the reference's speed toward a new target, at most",
        "m/s",
        positive=True,
    ),
    Param(
        "targets.max_acceleration",
        Kind.DOUBLE,
        0.2,
        "the reference's acceleration toward a new target, at most (no kick: position and velocity stay continuous)",
        "m/s^2",
        positive=True,
    ),
    Param(
        "targets.max_angular_velocity",
        Kind.DOUBLE,
        0.5,
        "hand_pose_target: the orientation task's reference turns toward the pose's orientation at most this fast",
        "rad/s",
        positive=True,
    ),
    Param(
        "targets.max_angular_acceleration",
        Kind.DOUBLE,
        2.0,
        "hand_pose_target: the orientation reference's angular acceleration, at most (no kick: it starts at rest "
        "from the orientation held)",
        "rad/s^2",
        positive=True,
    ),
    Param(
        "targets.max_horizon",
        Kind.DOUBLE,
        3600.0,
        "hand_path: how far after now (the controller's time) its last pose may lie; a later one is refused (a "
        "wall-clock stamp sent to a sim-time controller lies ~1.8e9 s ahead), as is a path entirely in the past",
        "s",
        positive=True,
    ),
    LOG_THROTTLE_PERIOD,
    MAX_MESSAGE_ELEMENTS,
    MAX_NAME_LENGTH,
)

NODE_PARAMETERS: dict[str, tuple[Param, ...]] = {"simulator": SIMULATOR, "controller": CONTROLLER}


def node_schema(node: str) -> tuple[Param, ...]:
    """The global parameters of ``node`` ("simulator" or "controller"): SHARED then its own."""
    return (*SHARED, *NODE_PARAMETERS[node])


def default(node: str, name: str) -> Any:
    """The schema's default of ``node``'s parameter ``name``."""
    param = find(node, name)
    if param is None or param.default is REQUIRED:
        raise KeyError(f"{node} has no parameter {name} with a default")
    return param.default


def contact_fields(node: str) -> tuple[Param, ...]:
    return tuple(p for p in CONTACT if node in p.nodes)


def contact_name(name: str, field: str) -> str:
    return f"contacts.{name}.{field}"


def _joint_hint(values: Sequence[str], read: Mapping[str, Any]) -> str:
    """What a per-joint list's length counts. Per-joint lists follow robot.joint_names, locked joints
    listed there included (their values unused): a list then stays as it is when a joint is locked
    or unlocked for a run (``--set robot.locked_joints=[...]``). A joint locked without being listed
    there (a gripper's fingers) needs no entry: the hint says which listed ones count though locked."""
    locked = [name for name in values if name in (read.get("robot.locked_joints") or ())]
    if not locked:
        return f"one per joint of robot.joint_names ({len(values)})"
    return (
        f"one per joint of robot.joint_names ({len(values)}), the locked {', '.join(locked)} included (values "
        "unused; a joint in robot.locked_joints but not in robot.joint_names needs none)"
    )


_HINTS: dict[str, Callable[[Sequence[str], Mapping[str, Any]], str]] = {
    "robot.joint_names": _joint_hint,
    "hand.axes": lambda values, read: f"one per hand axis {list(values)}",
    "hand.orientation.axes": lambda values, read: f"one per orientation axis {list(values)}",
    "brace_axes": lambda values, read: f"one per brace axis {list(values)}",
    "robot.locked_joints": lambda values, read: f"one per locked joint {list(values)}",
}


# -- typed reads: every parameter's value checked and typed here, in one pass (``read``) --------------
def check_known(
    params: Params, known: Iterable[str], dynamic_prefixes: Mapping[str, Iterable[str]] | None = None
) -> None:
    """Reject parameters that are not in the schema.

    ``dynamic_prefixes`` maps a prefix such as ``"contacts."`` to the fields allowed in
    its named sub-sections (``contacts.<any name>.<field>``).
    """
    known_set = set(known) | {"use_sim_time", "start_type_description_service"}
    dynamic = {prefix: set(fields) for prefix, fields in (dynamic_prefixes or {}).items()}
    unknown = []
    for name in params:
        if name in known_set:
            continue
        for prefix, fields in dynamic.items():
            rest = name[len(prefix) :].split(".", 1) if name.startswith(prefix) else []
            if len(rest) == 2 and rest[1] in fields:
                break
        else:
            unknown.append(name)
    if unknown:
        raise ConfigError(f"unknown parameter(s): {', '.join(sorted(unknown))}")


def get_float(
    params: Params, name: str, default: float | None = None, *, minimum: float | None = None, positive: bool = False
) -> float:
    value = params.get(name, default)
    if not number(value):
        raise ConfigError(f"{name}: expected a finite number, got {value!r}")
    if positive and value <= 0.0:
        raise ConfigError(f"{name}: must be > 0, got {value!r}")
    if minimum is not None and value < minimum:
        raise ConfigError(f"{name}: must be >= {minimum}, got {value!r}")
    return float(value)


def get_int(params: Params, name: str, default: int, *, minimum: int | None = None) -> int:
    value = params.get(name, default)
    if isinstance(value, bool) or not isinstance(value, int):
        raise ConfigError(f"{name}: expected an integer, got {value!r}")
    if minimum is not None and value < minimum:
        raise ConfigError(f"{name}: must be >= {minimum}, got {value!r}")
    return int(value)


def get_bool(params: Params, name: str, default: bool) -> bool:
    value = params.get(name, default)
    if not isinstance(value, bool):
        raise ConfigError(f"{name}: expected true or false, got {value!r}")
    return value


def get_str(params: Params, name: str, default: str | None = None, *, choices: Sequence[str] | None = None) -> str:
    value = params.get(name, default)
    if not isinstance(value, str) or (default is None and not value):
        raise ConfigError(f"{name}: expected a non-empty string, got {value!r}")
    if choices is not None and value not in choices:
        raise ConfigError(f"{name}: expected one of {', '.join(choices)}, got {value!r}")
    return value


def get_floats(params: Params, name: str, default: Sequence[float] | None = None) -> tuple[float, ...]:
    """A list of finite numbers; an empty or unset list reads as ``()``."""
    value = params.get(name, default)
    if value is None:
        value = []
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        value = [value]
    if not isinstance(value, (list, tuple)) or not all(number(v) for v in value):
        raise ConfigError(f"{name}: expected a list of finite numbers, got {value!r}")
    return tuple(float(v) for v in value)


def get_strs(params: Params, name: str, default: Sequence[str] = ()) -> tuple[str, ...]:
    value = params.get(name, default)
    if value is None:
        return ()
    if not isinstance(value, (list, tuple)) or not all(isinstance(v, str) and v for v in value):
        # A node started by hand reads a bare y as true (rcl, YAML 1.1); bracing's own readers mend it.
        hint = ' (YAML 1.1 reads a bare y or n as true/false: quote it, "y")' if _has_bool(value) else ""
        raise ConfigError(f"{name}: expected a list of non-empty strings, got {value!r}{hint}")
    if len(set(value)) != len(value):
        raise ConfigError(f"{name}: duplicate entries in {list(value)}")
    return tuple(value)


def _has_bool(value: Any) -> bool:
    return isinstance(value, (list, tuple)) and any(isinstance(v, bool) for v in value)


def read_value(param: Param, name: str, params: Params, read: Mapping[str, Any]) -> Any:
    """One parameter's typed value from ``params`` (its default if unset), or a ConfigError naming
    ``name``. ``read`` holds the values read so far (list lengths and conditions refer to them)."""
    required = param.default is REQUIRED and (
        param.required_if is None or read.get(param.required_if[0]) == param.required_if[1]
    )
    if param.words and isinstance(params.get(name), str):
        if params[name] not in param.words:
            raise ConfigError(f"{name}: expected {' or '.join(param.words)} or 3 numbers, got {params[name]!r}")
        return params[name]
    if ((param.default is REQUIRED and not required) or param.default is ABSENT) and name not in params:
        return None  # required only under another setting, or absent by choice
    if param.kind is Kind.DOUBLE_ARRAY and param.default is REQUIRED and not required and not params.get(name):
        return None  # an empty list for a value only another setting needs (a plane's sphere centre)
    default: Any = None if param.default is ABSENT else param.default
    if isinstance(default, PerJoint):
        default = [default.value] * len(read["robot.joint_names"])
    if param.kind is Kind.DOUBLE:
        return get_float(params, name, default, minimum=param.minimum, positive=param.positive)
    if param.kind is Kind.INTEGER:
        return get_int(params, name, default, minimum=None if param.minimum is None else int(param.minimum))
    if param.kind is Kind.BOOL:
        return get_bool(params, name, default)
    if param.kind is Kind.STRING:
        return get_str(params, name, default, choices=param.choices or None)
    if param.kind is Kind.STRING_ARRAY:
        value = get_strs(params, name, default if default is not None else ())
        if required and not value:
            raise ConfigError(f"{name}: expected a non-empty list, got none")
        if isinstance(param.length, int) and len(value) != param.length:
            raise ConfigError(f"{name}: expected {param.length} values, got {len(value)}")
        return value
    return _read_floats(param, name, params, read, default)


def _read_floats(param: Param, name: str, params: Params, read: Mapping[str, Any], default: Any) -> tuple[float, ...]:
    length: int | None = param.length if isinstance(param.length, int) else None
    hint = ""
    if isinstance(param.length, str):
        reference = read[param.length]
        length, hint = len(reference), _HINTS[param.length](reference, read)
    value = get_floats(params, name, default)
    if param.default is not REQUIRED and param.may_be_empty and not value:
        if isinstance(param.default, PerJoint):  # empty: the per-joint default
            return tuple(float(param.default.value) for _ in range(length or 0))
        return ()
    if length is not None and len(value) != length:
        if param.may_be_empty:
            what = f" ({hint})" if hint else ""
            raise ConfigError(f"{name}: expected {length} values{what} or an empty list, got {list(value)}")
        raise ConfigError(f"{name}: expected {length} values{f' ({hint})' if hint else ''}, got {len(value)}")
    if param.positive and any(v <= 0.0 for v in value):
        raise ConfigError(f"{name}: values must be > 0, got {list(value)}")
    if param.minimum is not None and any(v < param.minimum for v in value):
        raise ConfigError(f"{name}: values must be >= {param.minimum:g}, got {list(value)}")
    return value


@dataclass(frozen=True)
class Values:
    """What :func:`read` gives: typed values of every global parameter, and per contact."""

    values: dict[str, Any]
    contacts: dict[str, dict[str, Any]]  # contacts.<name>.<field>, per name in contacts.names order

    def __getitem__(self, name: str) -> Any:
        return self.values[name]


def read(node: str, params: Params) -> Values:
    """Validate ``node``'s flat parameters against its schema: unknown names, types, bounds,
    lengths. Each ConfigError names the parameter."""
    schema, fields = node_schema(node), contact_fields(node)
    check_known(params, [p.name for p in schema], {"contacts.": [f.name for f in CONTACT]})
    values: dict[str, Any] = {}
    for param in schema:
        values[param.name] = read_value(param, param.name, params, values)
    contacts: dict[str, dict[str, Any]] = {}
    for contact in values["contacts.names"]:
        own: dict[str, Any] = {}
        for field in fields:
            own[field.name] = read_value(field, contact_name(contact, field.name), params, {**values, **own})
        contacts[contact] = own
    return Values(values, contacts)


def all_names(node: str, contacts: Sequence[str]) -> list[str]:
    """Every parameter ``node`` declares for these contact names."""
    names = [p.name for p in node_schema(node)]
    names += [contact_name(c, f.name) for c in contacts for f in contact_fields(node)]
    return names


def find(node: str, name: str) -> Param | None:
    """The Param behind a flat name of ``node`` (``contacts.<any>.<field>`` included)."""
    for param in node_schema(node):
        if param.name == name:
            return param
    parts = name.split(".", 2)
    if len(parts) == 3 and parts[0] == "contacts":
        for field in contact_fields(node):
            if field.name == parts[2]:
                return field
    return None


def reference_markdown() -> str:
    """The parameter reference (``tools/docs_reference.py`` writes it to docs/reference/parameters.md)."""
    sections = (
        ("`/**` (both nodes)", SHARED),
        ("`/**`, per contact: `contacts.<name>.`", CONTACT),
        ("`bracing_simulator`", SIMULATOR),
        ("`bracing_controller`", CONTROLLER),
    )
    out: list[str] = []
    for title, params in sections:
        out += [
            f"**{title}**",
            "",
            "| parameter | type | default | unit | bounds | tunable | meaning |",
            "|---|---|---|---|---|---|---|",
        ]
        for p in params:
            who = "" if p.nodes == ("simulator", "controller") else f" ({', '.join(p.nodes)})"
            tunable = "yes" if p.tunable else ""
            meaning = p.description.replace("|", "\\|") + who
            row = [f"`{p.name}`", p.kind.value, p.default_text(), p.unit, p.bounds_text().replace("|", "\\|"), tunable]
            out.append("| " + " | ".join([*row, meaning]) + " |")
        out.append("")
    return "\n".join(out)
