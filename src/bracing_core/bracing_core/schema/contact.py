"""The fields of each contact, under ``contacts.<name>.``: the surface, and for a braced contact the
controller's force and brace task."""

from __future__ import annotations

from bracing_core.schema.param import ABSENT, REQUIRED, Kind, Param, trajectory_params

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
