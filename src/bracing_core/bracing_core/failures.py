"""Why a run failed, in words a user can act on (no ROS): what ran away, near what, and what to change.

A run that the simulator stops (a non-finite step, a joint past divergence_speed or its URDF limit, a
held contact off its surface) has an ``error`` that names the joints whose speed grew over the last
``RUNAWAY_WINDOW_S`` before the failure and, where the tasks' Jacobian is nearly singular there, the
joints that move along its weakest direction; and a ``hint`` for each known cause:

- a joint at its limit that no task sees, its null-space posture undamped: ``null_space_posture``;
- a target out of reach (what drove the arm to where it failed): move it;
- a singular posture (the task Jacobian's weakest direction, relative to its strongest, below
  ``SINGULAR_RATIO``): keep the path away from it, damp it;
- a stiff circuit (voltage input, the step's sub-step longer than RK4 keeps stable for the motors'
  fastest electromechanical mode at the failing posture): ``substeps`` or a shorter ``step``;
- a braced contact that let go under force feedback: the force loop's gains.

A run that ends well can still carry the hint of a known cause its warnings name (a contact lost under
force feedback, a target out of reach). The pair (from its bag) and the in-process rollout (from its
recording) both ask ``diagnose``, so both say the same.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from bracing_core.config import Plant
    from bracing_core.controller_config import ControllerConfig
    from bracing_core.schema import Values

RUNAWAY_WINDOW_S = 0.05
"""[s] of sim time before the failure over which a joint's speed growth is measured."""
RUNAWAY_SHARE = 0.2
"""A joint is named as running away when its speed at the failure is at least this share of the fastest's."""
SINGULAR_RATIO = 0.05
"""The task Jacobian's smallest singular value over its largest below which the posture counts as singular."""
RK4_STABLE_STEP = 2.78
"""h |lambda| up to which classic RK4 is stable on a real negative eigenvalue (2.785...)."""
OK, FAILED = "ok", "failed"
EXIT_DIVERGED = 3
"""The simulator's exit code when the simulation diverged, and then bracing-pair's: its summary.json says
what ran away (``error``) and what to change (``hint``)."""
DIVERGED = "error: simulation diverged at t = "
"""How the simulator's stderr gives a divergence (bracing-pair's summary.json ``error`` reads it there)."""
EXIT_NODE_FAILED = 1
"""A node's exit code when an exception ended its run (its per-state path's on rcl, in C++, or its loop's), and
then bracing-pair's: its summary.json's ``error`` says which node, where and what."""
NODE_FAILED = "error: the run failed in "
"""How a node's stderr gives the exception that ended its run: where, then its type and message (bracing-pair's
summary.json ``error`` reads it there)."""
LET_GO = re.compile(r"contact '([^']*)' let go of its surface")
"""A let-go warning (``checks.let_go_warning``): its contact's name."""

NULL_SPACE_HINT = (
    "no task sees joint {joint} and the null space leaves it undamped, so it drifts to its limit: set "
    "null_space_posture.kd (and .kp) for it (e.g. kd 0.2 N m s/rad, kp 1 N m/rad on a light wrist), and "
    "null_space: dynamically_consistent keeps the contact torques off it"
)
SINGULAR_HINT = (
    "the tasks lose a direction near this posture ({joints} move along it without moving a task point): keep "
    "the path and initial_position away from it, raise damping_lambda (the damped inverse near a singular "
    "posture), damp those joints with null_space_posture.kd, or drop a task axis it needs"
)
STIFF_HINT = (
    "the motor circuits are too stiff for the step: their fastest mode at this posture is {rate:.3g} 1/s, so a "
    "sub-step of {substep:.3g} s is beyond RK4's stability (h |lambda| {product:.3g} > {limit:g}); set the "
    "simulator's substeps >= {needed} or a shorter step (the controller's gains then also see the faster circuit)"
)
LET_GO_HINT = (
    "contact {name!r} let go under force feedback: the force loop outran the arm and pulled the contact off; lower "
    "contacts.{name}.force_feedback.kp and .ki to the gains the warning derives from the motors (kp below 1 where "
    "the circuit settles within a control period: docs/model.md, force feedback with voltage input), or set them "
    "to 0 (the paper's feed-forward)"
)
REACH_HINT = (
    "a target is out of reach (see the warning): move it within the arm's reach, or take the task axis "
    "along which it is out of reach off the task"
)


@dataclass(frozen=True)
class Failure:
    """summary.json's ``status``, ``error`` and ``hint``; ``cause`` names the known cause (``""`` for none)."""

    status: str
    error: str | None
    hint: str | None
    cause: str = ""

    def keys(self) -> dict[str, str | None]:
        return {"status": self.status, "error": self.error, "hint": self.hint}


@dataclass(frozen=True)
class History:
    """The states recorded up to the failure (model joint order)."""

    time: np.ndarray  # (N,) [s]
    position: np.ndarray  # (N, n)
    velocity: np.ndarray  # (N, n)
    joint_names: Sequence[str]


def runaway_joints(history: History) -> list[tuple[str, float, float]]:
    """(joint, |dq| RUNAWAY_WINDOW_S before the end, |dq| at the end) of the joints running away: at least
    RUNAWAY_SHARE of the fastest at the end, and faster than they were; fastest first."""
    if history.time.size == 0:
        return []
    end = np.abs(history.velocity[-1])
    k = int(np.searchsorted(history.time, history.time[-1] - RUNAWAY_WINDOW_S))
    before = np.abs(history.velocity[min(k, history.time.size - 1)])
    fastest = float(np.max(end)) if end.size else 0.0
    if not fastest > 0.0:
        return []
    chosen = [j for j in np.argsort(-end) if end[j] >= RUNAWAY_SHARE * fastest and end[j] > before[j]]
    return [(str(history.joint_names[j]), float(before[j]), float(end[j])) for j in chosen]


def task_jacobian(plant: Plant, config: ControllerConfig, q: np.ndarray) -> np.ndarray:
    """The hand's and each brace's task rows and each braced plane's normal row, stacked, at ``q`` (world axes)."""
    import pinocchio as pin

    model, data = plant.robot.model, plant.robot.data
    pin.computeJointJacobians(model, data, q)
    pin.updateFramePlacements(model, data)

    def rows(frame: str, parameter: str) -> np.ndarray:
        jacobian = pin.getFrameJacobian(model, data, plant.frame_id(frame, parameter), pin.LOCAL_WORLD_ALIGNED)
        return np.asarray(jacobian[:3])

    stacked = [rows(config.hand_task.frame, "hand.frame")[list(config.hand_task.axes)]]
    for c in config.shared.braced_contacts:
        translation = rows(c.frame, f"contacts.{c.name}.frame")
        stacked.append(translation[list(c.brace_axes)])
        normal = getattr(c.surface, "normal", None)
        if normal is not None:
            stacked.append(np.asarray(normal, dtype=float) @ translation)
    return np.vstack([np.atleast_2d(r) for r in stacked if np.size(r)])


def singular_joints(plant: Plant, config: ControllerConfig, q: np.ndarray) -> tuple[float, list[str]] | None:
    """(smallest / largest singular value, the joints that move most along the weakest direction) of
    ``task_jacobian`` at ``q`` if below SINGULAR_RATIO, else None."""
    if plant.robot.model.nq != q.size:
        return None  # a continuous joint's angle is two numbers in the model: not measured here
    jacobian = task_jacobian(plant, config, q)
    _, values, vt = np.linalg.svd(jacobian)
    if values.size == 0 or not values[0] > 0.0:
        return None
    ratio = float(values[-1] / values[0])
    if ratio >= SINGULAR_RATIO:
        return None
    direction = np.abs(vt[jacobian.shape[0] - 1]) if vt.shape[0] >= jacobian.shape[0] else np.abs(vt[-1])
    names = plant.joint_names
    chosen = [names[j] for j in np.argsort(-direction) if direction[j] >= 0.3 * float(np.max(direction))]
    return ratio, chosen


def stiff_circuit(plant: Plant, q: np.ndarray, step: float, substeps: int) -> tuple[float, float, int] | None:
    """(fastest rate [1/s], h |lambda|, sub-steps needed) where voltage input's circuits at ``q`` make a
    sub-step of ``step / substeps`` unstable for RK4; None where they do not."""
    from bracing_core.config import circuit_substeps, electromechanical_rate

    if plant.mode.value != "voltage":
        return None
    rate = electromechanical_rate(plant, q)
    product = step / substeps * rate
    if product <= RK4_STABLE_STEP:
        return None
    return rate, product, circuit_substeps(plant, q, step)


def _hint_from_warnings(warnings: Sequence[str], fed_back: Sequence[str]) -> tuple[str, str] | None:
    """(cause, hint) of a known cause a run's warnings name: a braced contact of ``fed_back`` (force feedback)
    that let go (``checks.let_go_warning``), a target out of reach (``checks.out_of_reach``)."""
    for warning in warnings:
        found = LET_GO.match(warning)
        if found is not None and found.group(1) in fed_back:
            return "contact_lost", LET_GO_HINT.format(name=found.group(1))
    if any("target out of reach" in w for w in warnings):
        return "out_of_reach", REACH_HINT
    return None


def fed_back(values: Values) -> list[str]:
    """The braced contacts whose normal force is fed back, from the controller's typed values (``schema.read``)."""
    return [name for name, own in values.contacts.items() if own.force_feedback.kp or own.force_feedback.ki]


def fed_back_contacts(config: ControllerConfig) -> list[str]:
    """The braced contacts whose normal force is fed back, from the controller's configuration."""
    return [c.name for c in config.shared.braced_contacts if c.feedback_kp or c.feedback_ki]


def succeeded(warnings: Sequence[str], fed_back: Sequence[str] = ()) -> Failure:
    """A run that ended well: status ok, no error, the hint of a known cause its warnings name (or None);
    ``fed_back``: the braced contacts under force feedback."""
    known = _hint_from_warnings(warnings, fed_back)
    return Failure(OK, None, known[1] if known else None, known[0] if known else "")


def _limit_joint(reason: str, names: Sequence[str]) -> str | None:
    """The joint a joint-limit refusal names ("joint 'x' would leave its URDF limits")."""
    for name in names:
        if f"joint {name!r} would leave its URDF limits" in reason:
            return name
    return None


def diagnose(
    reason: str,
    history: History,
    plant: Plant,
    config: ControllerConfig | None,
    step: tuple[float, int],
    warnings: Sequence[str] = (),
) -> Failure:
    """The failure of a run the simulator stopped with ``reason`` after ``history``; ``step``: the
    simulator's (step [s], substeps); ``config``: the controller's (None: no controller to blame)."""
    runaway = runaway_joints(history)
    q = history.position[-1] if history.time.size else None
    parts = [reason]
    if runaway:
        grew = ", ".join(f"{name} ({before:.3g} -> {after:.3g})" for name, before, after in runaway)
        parts.append(f"ran away: {grew} rad/s or m/s over the last {RUNAWAY_WINDOW_S * 1e3:g} ms")
    singular = singular_joints(plant, config, q) if config is not None and q is not None else None
    if singular is not None:
        parts.append(
            f"near a singular posture: the tasks' Jacobian's weakest direction is {singular[0]:.2g} of its strongest, "
            f"along {', '.join(singular[1])}"
        )
    error = "; ".join(parts)
    cause, hint = _cause(reason, runaway, singular, plant, config, q, step, warnings)
    return Failure(FAILED, error, hint, cause)


def _cause(
    reason: str,
    runaway: list[tuple[str, float, float]],
    singular: tuple[float, list[str]] | None,
    plant: Plant,
    config: ControllerConfig | None,
    q: np.ndarray | None,
    step: tuple[float, int],
    warnings: Sequence[str],
) -> tuple[str, str | None]:
    """(cause, hint), the first known cause that fits, in the order of the module docstring."""
    joint = _limit_joint(reason, plant.joint_names)
    if joint is not None and config is not None and not _damped(config, plant, joint):
        return "null_space", NULL_SPACE_HINT.format(joint=joint)
    if any("target out of reach" in w for w in warnings):  # what drove the arm to where it failed
        return "out_of_reach", REACH_HINT
    if singular is not None:
        return "singular", SINGULAR_HINT.format(joints=", ".join(singular[1]))
    stiff = stiff_circuit(plant, q, *step) if q is not None else None
    if stiff is not None:
        rate, product, needed = stiff
        substep = step[0] / step[1]
        return "stiff_circuit", STIFF_HINT.format(
            rate=rate, substep=substep, product=product, limit=RK4_STABLE_STEP, needed=needed
        )
    feedback = fed_back_contacts(config) if config else []
    known = _hint_from_warnings(warnings, feedback)
    return known if known is not None else ("", None)


def _damped(config: ControllerConfig, plant: Plant, joint: str) -> bool:
    """Whether ``joint`` has a null-space posture damping (null_space_posture.kd > 0)."""
    if not config.null_space_posture.kd:
        return False
    kd = plant.to_model_order(config.null_space_posture.kd)
    return bool(kd[list(plant.joint_names).index(joint)] > 0.0)
