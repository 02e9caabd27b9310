"""The controller node's own parameters: the hand task, the law, its outputs and the targets' limits."""

from __future__ import annotations

from bracing_core.schema.param import REQUIRED, Kind, Param, PerJoint, trajectory_params
from bracing_core.schema.shared import LOG_THROTTLE_PERIOD, MAX_MESSAGE_ELEMENTS, MAX_NAME_LENGTH

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
