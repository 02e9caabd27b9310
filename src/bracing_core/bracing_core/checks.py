"""Warnings about a run that will work but not as the user likely means (no ROS).

A configuration can pass every check and still ask for nonsense: a braced contact pushed with
f_nd <= 0 N, a target the arm cannot reach, a real-time run the machine cannot keep up with, a
braced contact that lets go or never arrives, a table that pulls, a start the projection moved far.
Each is said once, in the node's log and in summary.json's ``warnings``; the texts are made here, so
that both say the same (the simulator's are chosen by ``watch.RunWatch``).

The reach check is cheap and sound (it never warns about a point the arm can reach): a frame
moved by a chain of joints is never further from the first joint's origin than the sum of the
distances between successive joint origins along the chain, plus the frame's offset from its
joint, plus the travel of each prismatic joint (``frame_reach``). A target point further than that
from the first joint, counted along the task's axes only (the others are free), cannot be reached.
The target path is sampled where it can be furthest: 720 points of a circle's turn, every waypoint
(the path between two waypoints is a straight segment, furthest at an end), a held point.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from bracing_core.types import Vector

if TYPE_CHECKING:  # pinocchio and the engine: only where a configuration is checked
    import pinocchio as pin

    from bracing_core.config import Plant
    from bracing_core.controller_config import ControllerConfig
    from bracing_core.trajectory import TrajectoryConfig

CIRCLE_SAMPLES = 720
"""Points of a circular target path checked per turn (half a degree apart)."""

REAL_TIME_SLACK = 0.95
"""Real-time stepping is said to be too slow below this share of the requested factor (a timer's
jitter costs a percent or two on an idle machine)."""

REAL_TIME_ACHIEVED = "real-time stepping achieved "
"""How the simulator's log gives real-time stepping's achieved factor (``{factor}x real time``):
bracing-pair reads it there."""

UNBOUNDED_TRAVEL_M = 1e6
"""A prismatic joint whose limits reach further than this [m] is taken as unbounded: no reach bound."""


def desired_force_warning(name: str, force: float, t: float | None = None) -> str | None:
    """The warning for a braced contact whose desired normal force ``force`` [N] is not positive
    (None if it is); ``t``: the time it was set at, if not from the start."""
    if force > 0.0:
        return None
    when = f" from t = {t:.3f} s" if t is not None and t > 0.0 else ""
    return (
        f"contacts.{name}.desired_normal_force is {force:g} N{when}: a braced contact is pushed on with f_nd > 0; "
        "with f_nd <= 0 a bilateral surface pulls the frame towards it and a unilateral one lets it go"
    )


FORCE_LOOP_DAMPING = 0.6
"""The damping ratio ``force_feedback_gains`` gives a force loop behind a slow motor circuit."""
STIFF_FORCE_GAINS = (0.3, 0.1)
"""(kp, ki h) of a force loop whose circuit settles within a control period h: the torque-input loop's
gains (kp 0.3, ki 100 /s at 1 ms), which keep its Jury conditions (alpha kp < 1, alpha (2 kp + ki h) < 2)
for a force response alpha up to 2.8 times the model's."""


def force_feedback_gains(time_constant: float, step: float) -> tuple[float, float]:
    """(kp, ki [1/s]) for ``contacts.<name>.force_feedback`` given the motor circuit's time constant
    ``time_constant`` = L / R [s] (0 with torque input) and the control period ``step`` [s].

    A circuit that settles within a step (a geared servo, L / R 0.2 ms at 1 ms; torque input) leaves the
    force loop the discrete one of torque input: kp 0.3, ki 0.1 / h (``STIFF_FORCE_GAINS``; kp near 1 sits
    on its stability limit, and a geared wrist chatters on and off its table above it). A slower circuit
    (the paper's motors, L / R 0.28 s) makes it second order, tau_e s^2 + (1 + kp) s + ki = 0: kp 1 and
    ki = (1 + kp)^2 / (4 zeta^2 tau_e) give it the damping ratio zeta = ``FORCE_LOOP_DAMPING`` (9.9 /s there)."""
    if time_constant <= step:
        kp, ki_step = STIFF_FORCE_GAINS
        return kp, ki_step / step
    kp = 1.0
    return kp, (1.0 + kp) ** 2 / (4.0 * FORCE_LOOP_DAMPING**2 * time_constant)


def let_go_warning(name: str, t: float, gains: tuple[float, float] | None = None) -> str:
    """A braced contact released from its surface at ``t`` [s], and what to change if its force is fed back
    (``gains``: ``force_feedback_gains`` for the arm's motors, if known)."""
    derived = f" (for these motors: kp <= {gains[0]:.3g}, ki <= {gains[1]:.3g} /s)" if gains is not None else ""
    return (
        f"contact {name!r} let go of its surface at t = {t:.3f} s although the controller braces it: from then on "
        "its force law acts on a contact that is not there (a unilateral contact releases when the force would pull); "
        f"if its force is fed back, the force loop outran the arm: lower contacts.{name}.force_feedback.kp and .ki"
        f"{derived} (docs/model.md derives them from the motors)"
    )


ON_THE_SURFACE = (
    "project_initial_position: true puts a braced unilateral contact that starts at most 0.05 m above its surface on it"
)


def never_reached_warning(name: str) -> str:
    """A braced contact that never held on its surface during the run."""
    return (
        f"contact {name!r} never touched its surface although the controller braces it: the run had no brace "
        f"(a unilateral contact that starts above its surface must be brought down onto it; {ON_THE_SURFACE})"
    )


NULL_SPACE_SPEED = 2.0
"""[rad/s or m/s] joint speed that no task sees (``DecoupledController.null_space_speed``) above which, with the
hand on its path, the null space is moving on its own: the paper's B^+ leaves such joints undamped."""
TASKS_SATISFIED_M = 0.01
"""[m] hand error below which the tasks count as satisfied for that warning."""


def null_space_warning(speed: float, hand_error: float, t: float) -> str | None:
    """The warning for joints moving fast where no task sees them while the hand is on its path (None if not)."""
    if not (speed > NULL_SPACE_SPEED and hand_error < TASKS_SATISFIED_M):
        return None
    return (
        f"at t = {t:.3f} s joints move at {speed:.3g} rad/s where no task sees them while the hand is on its path: "
        "the null space leaves such joints undamped and a light wrist can run away; set null_space_posture.kd "
        "(and .kp) to damp them (with null_space: dynamically_consistent the contact torques leave them alone too)"
    )


def late_reach_warning(name: str, t: float) -> str:
    """A braced contact that started off its surface and first held on it at ``t`` [s]."""
    return (
        f"contact {name!r} started off its surface and first held on it at t = {t:.3f} s although the controller "
        f"braces it from the start: until then its force law acted on a contact that was not there ({ON_THE_SURFACE})"
    )


def pull_warning(name: str, share: float, since: float, lowest: float, mean: float) -> str:
    """A bilateral contact whose normal force was negative in ``share`` of the run's states, the first
    at ``since`` [s], down to ``lowest`` [N], ``mean`` [N] over those states."""
    return (
        f"contact {name!r} pulled on its surface (f_n < 0) in {100.0 * share:.0f} % of the run from t = {since:.3f} s, "
        f"down to {lowest:.3g} N (mean {mean:.3g} N while pulling): a table cannot pull: set unilateral: true "
        f"(contacts.{name}.unilateral) and the contact lets go instead"
    )


def projection_warning(moves: Sequence[tuple[str, float, float, bool, float, float]], limit_text: str) -> str:
    """``project_initial_position`` moved joints far: (joint, given, projected, prismatic, lower, upper) of
    each, ``limit_text`` the threshold as said (e.g. "0.1 rad (0.01 m)")."""
    parts = []
    for joint, given, projected, prismatic, lower, upper in moves:
        unit = "m" if prismatic else "rad"
        text = f"joint {joint!r} by {projected - given:+.3g} {unit} ({given:.3f} -> {projected:.3f} {unit}"
        room = min(projected - lower, upper - projected)
        if room < (0.01 if prismatic else 0.1):
            side = "lower" if projected - lower <= upper - projected else "upper"
            text += f", {room:.3g} {unit} from its {side} limit"
        parts.append(text + ")")
    return (
        f"project_initial_position moved {', '.join(parts)} to put the contacts on their surfaces, more than "
        f"{limit_text}: the run starts far from initial_position; give an initial_position near the surfaces "
        "(the projected one is in the simulator's log)"
    )


def drift_warning(name: str, residual: float, t: float, baumgarte: float) -> str:
    """A held contact ``residual`` [m] off its surface at ``t`` [s], with Baumgarte gain ``baumgarte`` [1/s]."""
    return (
        f"held contact {name!r} has drifted {residual:.3g} m off its surface at t = {t:.3f} s "
        f"(baumgarte = {baumgarte:g} 1/s; raise it, e.g. 10-200 1/s, to hold the contacts)"
    )


def first_report_warning(message: str, t: float) -> str:
    """The first of a kind of report the simulator's log repeats (rate-limited), as the summary has it."""
    return f"{message} (first at t = {t:.3f} s; the simulator's log says how often)"


def slow_real_time_warning(achieved: float, requested: float) -> str | None:
    """The warning for real-time stepping that ran at ``achieved`` x real time when ``requested``
    was asked (None if it kept up, within ``REAL_TIME_SLACK``)."""
    if not math.isfinite(achieved) or achieved >= REAL_TIME_SLACK * requested:
        return None
    return (
        f"real-time stepping ran at {achieved:.3g}x real time instead of the requested {requested:g}x: the steps "
        "took longer than their wall-clock period, so the commands lag the state by more than the loop assumes; "
        "use lockstep stepping (the default) on a machine that cannot keep up"
    )


# -- reach ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Reach:
    """Where a frame can be: within ``radius`` [m] of ``anchor`` (the first joint's origin, world)."""

    anchor: Vector  # (3,) [m]
    radius: float  # [m]
    joint: str  # the first joint of the chain (its name, for messages)


def frame_reach(model: pin.Model, frame: int) -> Reach | None:
    """The bound on where ``frame`` can be (see the module docstring), or None if a prismatic joint
    of its chain has no finite limits. The first joint's origin does not move: its parent is the world."""
    joint = int(model.frames[frame].parentJoint)
    radius = float(np.linalg.norm(model.frames[frame].placement.translation))
    chain = []
    while joint != 0:
        chain.append(joint)
        joint = int(model.parents[joint])
    if not chain:  # fixed to the world: it is where it is
        return Reach(np.array(model.frames[frame].placement.translation, dtype=float), 0.0, "world")
    first = chain[-1]
    for joint in chain:
        if joint != first:
            radius += float(np.linalg.norm(model.jointPlacements[joint].translation))
        if model.joints[joint].shortname().startswith("JointModelP"):  # prismatic: its travel too
            index = int(model.idx_qs[joint])
            travel = max(abs(float(model.lowerPositionLimit[index])), abs(float(model.upperPositionLimit[index])))
            if not travel < UNBOUNDED_TRAVEL_M:
                return None
            radius += travel
    anchor = np.array(model.jointPlacements[first].translation, dtype=float)
    return Reach(anchor, radius, str(model.names[first]))


def path_samples(trajectory: TrajectoryConfig, start: Vector) -> Iterator[tuple[float, Vector]]:
    """(t [s], desired point [m]) where the path can be furthest out (see the module docstring);
    nothing for a hold of the first measured position, which the arm is at."""
    path = trajectory.path()
    if trajectory.kind == "circle":
        times: Sequence[float] = [trajectory.period * k / CIRCLE_SAMPLES for k in range(CIRCLE_SAMPLES)]
    elif trajectory.kind == "waypoints":  # each segment ends at rest on its waypoint
        times = [trajectory.segment_time * (k + 1) for k in range(len(trajectory.waypoints))]
    else:
        times = [0.0] if trajectory.point is not None else []
    for t in times:
        point, _ = path.sample(start, t)
        yield t, np.asarray(point, dtype=float)


def out_of_reach(
    what: str, parameter: str, frame: str, axes: Sequence[int], trajectory: TrajectoryConfig, reach: Reach
) -> str | None:
    """The warning for the first sampled point of ``trajectory`` that ``frame`` cannot reach along
    ``axes`` (None if there is none)."""
    names = ", ".join("xyz"[a] for a in axes)
    for t, point in path_samples(trajectory, reach.anchor):
        distance = float(np.linalg.norm((point - reach.anchor)[list(axes)]))
        if distance > reach.radius + 1e-9:
            where = ", ".join(f"{v:.3g}" for v in point)
            at = f" at t = {t:.3g} s" if trajectory.kind != "hold" else ""
            return (
                f"{what} target out of reach: {parameter} ({trajectory.kind}) asks for [{where}]{at}, "
                f"{distance:.3f} m from {reach.joint} along {names}, but frame {frame!r} is never more than "
                f"{reach.radius:.3f} m from it (the lengths along its chain); the task cannot be met there"
            )
    return None


def reach_warnings(config: ControllerConfig, plant: Plant) -> list[str]:
    """A warning for the hand's and each brace's target path where it leaves the reach of its frame."""
    hand = config.hand_task
    tasks = [("hand", "hand.trajectory", hand.frame, hand.axes, hand.trajectory)]
    for c in config.shared.braced_contacts:
        parameter = f"contacts.{c.name}.target" if c.trajectory.kind == "hold" else f"contacts.{c.name}.trajectory"
        tasks.append((f"brace point {c.name!r}", parameter, c.frame, c.brace_axes, c.trajectory))
    out = []
    for what, parameter, frame, axes, trajectory in tasks:
        if not axes:
            continue  # no task along any axis: nothing to reach
        reach = frame_reach(plant.robot.model, plant.frame_id(frame, parameter))
        warning = None if reach is None else out_of_reach(what, parameter, frame, axes, trajectory, reach)
        if warning is not None:
            out.append(warning)
    return out


def configuration_warnings(config: ControllerConfig, plant: Plant) -> list[str]:
    """What a controller configuration asks for that will not work as meant: desired forces <= 0 on
    braced contacts, targets out of reach (checked before the run, from the kinematics)."""
    forces = [desired_force_warning(c.name, c.desired_normal_force or 0.0) for c in config.shared.braced_contacts]
    return [w for w in forces if w is not None] + reach_warnings(config, plant)
