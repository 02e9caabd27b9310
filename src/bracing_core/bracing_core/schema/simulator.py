"""The simulator node's own parameters: stepping, start, watchdog, the plant's error and the sensors."""

from __future__ import annotations

from bracing_core.schema.param import REQUIRED, Kind, Param, PerJoint
from bracing_core.schema.shared import LOG_THROTTLE_PERIOD, MAX_MESSAGE_ELEMENTS, MAX_NAME_LENGTH

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
        "wait_for_reset",
        Kind.BOOL,
        False,
        "lockstep: at the run's end, stay and wait for reset_simulation (the next run, from the initial state) "
        "instead of exiting; SIGINT ends it",
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
