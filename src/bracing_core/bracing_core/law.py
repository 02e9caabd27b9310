"""The decoupled force/position law (docs/model.md, Control law; paper eqs. 36-41), no ROS.

    B = J_c Mc^-1,  A = B (J_c - mu J_t)^T,  a = B (h + g + Dc dq) - gamma
    tau = B^+ (a - A f_nd) + (I - B^+ B) l
    l = sum_j J_j^T [Kp_j (r_dj - r_j) + Kd_j (dr_dj - dr_j)] + J_h^T [Kp_h (r_dh - r_h) + Kd_h (dr_dh - dr_h)]
    v = K_V tau                                   (voltage mode; tau itself in torque mode)

Each task uses only the world axes the configuration names. With no contacts, tau = l.

The law runs in the compiled engine (``bracing_engine.Law``, C++ on pinocchio: its own model
with the rotor inertia as armature, B^+ from B B^T, damped when B is near-singular). This
class describes the configured tasks, contacts and gains to it and wraps its answers.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin

import bracing_engine as engine
from bracing_core import schema
from bracing_core.config import Plant
from bracing_core.controller_config import ControllerConfig, OrientationConfig
from bracing_core.dynamics import engine_contact, engine_drive, engine_robot
from bracing_core.params import ConfigError
from bracing_core.trajectory import TrajectoryConfig
from bracing_core.types import HAND_TASK, TaskIndex, Vector, brace_task

if TYPE_CHECKING:
    from typing_extensions import CapsuleType


def axis_gains(axes: tuple[int, ...], gains: tuple[float, ...]) -> Vector:
    """Per-axis gains of a task as a gain per world axis (zero on the axes it does not use)."""
    out = np.zeros(3)
    for axis, gain in zip(axes, gains, strict=True):
        out[axis] += gain
    return out


def task(
    frame: str,
    axes: tuple[int, ...],
    kp: tuple[float, ...],
    kd: tuple[float, ...],
    path: TrajectoryConfig,
    ki: tuple[float, ...] = (),
) -> engine.Task:
    """A PID task as the engine takes it: gains per world axis, the configured axes, the path (``ki`` empty:
    no integral)."""
    return engine.Task(
        frame=frame,
        kp=axis_gains(axes, kp),
        kd=axis_gains(axes, kd),
        path=path.path(),
        axes=list(axes),
        ki=integral_gains(axes, ki),
    )


def orientation_task(config: OrientationConfig) -> engine.OrientationTask:
    """The hand frame's orientation task as the engine takes it (gains per world axis; R_d from the quaternion)."""
    target = None
    if config.target is not None:
        x, y, z, w = config.target
        target = pin.Quaternion(w, x, y, z).toRotationMatrix()
    axes = config.axes
    return engine.OrientationTask(
        axes=list(axes),
        kp=axis_gains(axes, config.kp),
        kd=axis_gains(axes, config.kd),
        ki=integral_gains(axes, config.ki),
        target=target,
    )


def integral_gains(axes: tuple[int, ...], ki: tuple[float, ...]) -> Vector:
    """A task's integral gains per world axis (zeros where none is configured)."""
    return axis_gains(axes, ki) if ki else np.zeros(3)


class DecoupledController:
    """One control update per measured state; the same object runs in the node and in tests."""

    def __init__(self, config: ControllerConfig, plant: Plant | None = None) -> None:
        self.config = config
        # The controller does not read the simulator's section: its contact model uses the
        # simulator's default slip regularisation.
        self.plant = plant if plant is not None else Plant(config.shared, schema.default("simulator", "slip_epsilon"))
        robot = self.plant.robot
        self.robot = robot
        self.contact_set = self.plant.braced_set  # obstacles are the simulator's business
        self.mode = config.shared.input_mode
        contacts = config.shared.braced_contacts
        self.desired_normal_force = np.array([c.desired_normal_force for c in contacts], dtype=float)
        hand, posture = config.hand_task, config.null_space_posture
        self.plant.frame_id(hand.frame, "hand.frame")  # a ConfigError naming the parameter
        braces = [
            engine.BracedContact(
                contact=engine_contact(contact),
                desired_normal_force=float(desired),
                task=task(c.frame, c.brace_axes, c.kp, c.kd, c.trajectory, c.ki),
                feedback_kp=c.feedback_kp,
                feedback_ki=c.feedback_ki,
            )
            for contact, c, desired in zip(self.contact_set.contacts, contacts, self.desired_normal_force, strict=True)
        ]
        self.spec = engine.LawSpec(
            robot=engine_robot(robot),
            drive=engine_drive(robot, self.plant.motors, self.mode),
            voltage_gain=self.plant.to_model_order(config.voltage_gain),
            hand=task(hand.frame, hand.axes, hand.kp, hand.kd, hand.trajectory, hand.ki),
            braces=braces,
            gravity_compensation=config.gravity_compensation,
            damping_lambda=config.damping_lambda,
            dynamically_consistent=config.null_space == "dynamically_consistent",
            slip_epsilon=float(self.contact_set.slip_epsilon),
            thermal_compensation=config.voltage_law.thermal_compensation,
            command_limit=self.plant.command_limit,
            back_emf_compensation=config.voltage_law.back_emf_compensation,
            posture_kp=self.plant.to_model_order(posture.kp),
            posture_kd=self.plant.to_model_order(posture.kd),
            posture_rest=self.plant.to_model_order(posture.rest) if posture.rest else np.zeros(0),
            acceleration_gains=config.gains == "acceleration",
            orientation=orientation_task(config.orientation),
        )
        self.engine = engine.Law(self.spec)

    def retune(self, config: ControllerConfig) -> None:
        """Take the tunable values of ``config`` (``schema`` ``tunable``: task gains, integral gains included,
        desired normal forces, K_V) from the next update on. Everything else must be as this controller's. An
        integral gain set from zero starts its integral at zero; one set to zero forgets it."""
        self.config = config
        contacts = config.shared.braced_contacts
        self.desired_normal_force[:] = [c.desired_normal_force for c in contacts]
        self.engine.retune(
            axis_gains(config.hand_task.axes, config.hand_task.kp),
            axis_gains(config.hand_task.axes, config.hand_task.kd),
            [axis_gains(c.brace_axes, c.kp) for c in contacts],
            [axis_gains(c.brace_axes, c.kd) for c in contacts],
            self.desired_normal_force,
            self.plant.to_model_order(config.voltage_gain),
            integral_gains(config.hand_task.axes, config.hand_task.ki),
            [integral_gains(c.brace_axes, c.ki) for c in contacts],
        )

    def reset(self) -> None:
        """Forget the targets taken from the first state and the integrals (a new run starts)."""
        self.engine.reset()

    def check_task_rank(self, q0: Vector) -> None:
        """Refuse a task direction the arm cannot move along at the start ``q0`` (model order): each
        configured axis (hand axes, then each brace's) must add a rank to the stacked task Jacobian
        within the motions the braced contacts allow (the null space of J_c; the engine's
        ``Law.first_rankless_axis``). ConfigError names the first axis that adds none, and what fails:
        the axis itself (the frame cannot move along it), the task's axes together (fewer free
        directions along them than axes: keep that many), or the tasks before it (they take the
        directions it needs), counting free directions with ``Law.task_rank``."""
        q0 = np.asarray(q0, dtype=float)
        task, axis = self.engine.first_rankless_axis(q0)
        if task < 0:
            return
        tasks = self._rank_tasks()
        # the engine's row (task, axis): the hand's rotation rows are task 0's axes 3-5
        index = next(i for i, t in enumerate(tasks) if t.task == task and t.offset == (3 if axis >= 3 else 0))
        current, axis = tasks[index], axis % 3
        parameter, frame, axes = current.parameter, current.frame, current.axes
        if self.engine.task_rank(q0, current.rows([axis])) == 0:
            verb = "rotate about" if current.offset else "move along"
            raise ConfigError(
                f"{parameter}: frame {frame!r} cannot {verb} {'xyz'[axis]} at the start (that direction adds "
                "no rank to the task Jacobian, within the motions the braced contacts allow); remove the axis"
            )
        own = list(axes[: axes.index(axis) + 1])  # this task's axes so far: each alone is free
        free = self.engine.task_rank(q0, current.rows(own))
        if free < len(own):
            keep = {1: "one", 2: "two"}.get(free, str(free))
            raise ConfigError(
                f"{parameter}: {_axes_text(own)} needs {len(own)} free directions beside the contacts; frame "
                f"{frame!r} has {free} along them at the start (each axis alone has one): keep {keep} of them"
            )
        rows = [row for t in tasks[:index] for row in t.rows(list(t.axes))] + current.rows(own)
        others = "; ".join(f"{t.parameter} {_axes_text(t.axes)}" for t in tasks[:index] if t.axes)
        raise ConfigError(
            f"{parameter}: {_axes_text(own)} with {others} needs {len(rows)} free directions beside the contacts; "
            f"the arm has {self.engine.task_rank(q0, rows)} for them at the start (each task alone has enough): "
            "remove an axis from one of them"
        )

    def _rank_tasks(self) -> list[_RankTask]:
        """The configured tasks in the engine's order (the hand, its orientation, each brace)."""
        config = self.config
        tasks = [_RankTask("hand.axes", config.hand_task.frame, config.hand_task.axes, HAND_TASK, 0)]
        tasks.append(_RankTask("hand.orientation.axes", config.hand_task.frame, config.orientation.axes, HAND_TASK, 3))
        contacts = config.shared.braced_contacts
        tasks += [
            _RankTask(f"contacts.{c.name}.brace_axes", c.frame, c.brace_axes, brace_task(k), 0)
            for k, c in enumerate(contacts)
        ]
        return tasks

    def update(self, t: float, q: Vector, dq: Vector) -> engine.LawOutput:
        """The command for the measured state (q, dq) at time t [s] (model joint order); the desired normal
        forces are ``desired_normal_force``'s."""
        return self.engine.update(float(t), np.asarray(q, dtype=float), np.asarray(dq, dtype=float))

    @property
    def uses_force_feedback(self) -> bool:
        """A braced contact has force-feedback gains: the law reads its measured force (``measure_force``)."""
        return bool(self.engine.uses_force_feedback)

    @property
    def uses_temperature(self) -> bool:
        """Thermal compensation applies (voltage input, thermal motors): the law reads ``measure_temperature``."""
        return bool(self.engine.uses_temperature)

    def c_api(self) -> CapsuleType:
        """The law's C ABI (``bracing_engine.law_api``, law_api.h): a capsule for bracing_rcl's C++ path, keeping
        the law alive."""
        return engine.law_api(self.engine)

    def null_space_speed(self, dq: Vector) -> float:
        """max |(I - J^+ J) dq| [rad/s or m/s], J the task rows at the last update's q: motion no task sees."""
        return float(self.engine.null_space_speed(np.asarray(dq, dtype=float)))

    def measure_force(self, contact: int, force: Vector) -> None:
        """Braced contact ``contact``'s measured force on the robot [N], world axes (contact_wrench/<name>)."""
        self.engine.measure_force(int(contact), np.asarray(force, dtype=float))

    def measure_temperature(self, temperature: Vector) -> None:
        """The windings' measured temperatures [degC], model joint order (motor_state)."""
        self.engine.measure_temperature(np.asarray(temperature, dtype=float))


@dataclass(frozen=True)
class _RankTask:
    """A configured task as the rank check names it: its parameter, frame, world axes, the engine's task index
    and the offset of its rows (3: the hand's rotation rows)."""

    parameter: str
    frame: str
    axes: tuple[int, ...]
    task: TaskIndex
    offset: int

    def rows(self, axes: list[int]) -> list[tuple[int, int]]:
        return [(self.task, self.offset + a) for a in axes]


def _axes_text(axes: list[int] | tuple[int, ...]) -> str:
    """World axis indices as the configuration writes them: [x, y]."""
    return "[" + ", ".join("xyz"[a] for a in axes) + "]"


def check_task_rank(config: ControllerConfig, plant: Plant, q0: Vector) -> None:
    """``DecoupledController.check_task_rank`` for a configuration with no controller built yet."""
    DecoupledController(config, plant).check_task_rank(q0)
