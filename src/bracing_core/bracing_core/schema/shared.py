"""The ``/**`` section both nodes read (robot, motors, input mode, contacts' names), and the parameters
each node has its own value of."""

from __future__ import annotations

from bracing_core.motors import AMBIENT_TEMPERATURE, COPPER_TEMPERATURE_COEFFICIENT, HEAT_CAPACITY, THERMAL_RESISTANCE
from bracing_core.schema.param import REQUIRED, Kind, Param, PerJoint

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
        per_run=True,
    ),
    Param(
        "free_space",
        Kind.BOOL,
        False,
        "true: the surfaces are removed (only watched, for the penetration report); the paper's free comparison "
        "(bracing-pair --free-space)",
        per_run=True,
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
