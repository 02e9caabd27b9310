"""TIAGo driven by ``cmd_vel`` while its elbow braces on the table (config/tiago_table.yaml): the controller's
policy in process (``StateAnswerer``, what the controller node runs) on three bases, its wheels turning
(``robot.base: diff_drive``), a planar base with the wheels held, and that planar base without the velocity
loop's integral; 0.1 m/s forward (and 0.2 rad/s on the wheels) sent every 0.1 s from 0.5 s to 1.4 s, the last
command followed until its 0.5 s timeout. Printed as a table and, with ``--record FILE``, written as a recorded
file (bracing_experiments.recorded: with the date, commit and machine) that the results page renders
(tools/docs_reference.py). test_tiago_scenario.py drives the same runs through ``drive`` and checks them.

    python tools/tiago_cmd_vel.py [--record docs/results/data/tiago_cmd_vel.json]
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from bracing_core.answering import Answer, StateAnswerer
from bracing_core.base import BASE_JOINTS
from bracing_core.mobile_base import base_indices
from bracing_core.numbers import markdown_table
from bracing_core.rollout import Scenario, build_scenario
from bracing_experiments.recorded import write_recorded

ROOT = Path(__file__).resolve().parents[1]
TIAGO = ROOT / "config" / "tiago_table.yaml"
F_ND = 10.0
"""[N] The file's contacts.elbow.desired_normal_force."""
ARM = ["torso_lift_joint", *(f"arm_{k}_joint" for k in range(1, 8))]
MOTOR = {"torque_constant": 0.1, "resistance": 0.5, "inductance": 1e-4, "rotor_inertia": 1e-6, "gear_ratio": 100.0,
         "gear_damping": 1e-5}  # fmt: skip
"""The file's servo, the same on every joint."""
STEP_S = 0.001
STEPS = 2500
"""The run: 2.5 s of 1 ms steps."""
SENT_STEPS = range(500, 1500, 100)
"""The steps a cmd_vel is sent at: every 0.1 s from 0.5 s to 1.4 s."""
SPEED_MPS = 0.1
TURN_RAD_S = 0.2
"""The wheeled base's commanded yaw rate (the planar bases drive straight)."""
TIMEOUT_S = 0.5
"""The file's cmd_vel timeout: the last command is followed until it is this old."""
COMMANDED_S = (SENT_STEPS[-1] - SENT_STEPS[0]) * STEP_S + TIMEOUT_S
"""[s] How long the base follows a command (1.4 s)."""
DRIVEN = slice(SENT_STEPS[0], round(SENT_STEPS[-1] + TIMEOUT_S / STEP_S))
"""The steps from the first cmd_vel to the timeout's braking."""
TABLE = "tiago-cmd-vel"


class ListLog:
    """The controller's log as lists (``NodeLog``): its warnings and rate-limited reports kept."""

    def __init__(self) -> None:
        self.warnings: list[str] = []

    def info(self, message: str) -> None:
        pass

    def warning(self, message: str) -> None:
        self.warnings.append(message)

    def limited(self, level: str, kind: str, message: str) -> None:
        self.warnings.append(message)

    def mark(self, kind: str) -> None:
        pass

    def say(self, warnings: list[str], t: float) -> None:
        self.warnings.extend(warnings)


def _servos(n: int) -> dict[str, Any]:
    return {f"motors.{name}": [value] * n for name, value in MOTOR.items()}


def planar_tiago(kd: float, ki: float = 0.0) -> Scenario:
    """The file's robot on robot.base: planar (its wheels still held), the base's three joints first in every
    per-joint list, driven by cmd_vel with the velocity loop's ``kd`` [N s/m] and ``ki`` [N/m]."""
    n = 3 + len(ARM)
    shared: dict[str, Any] = {"robot.base": "planar", "robot.joint_names": [*BASE_JOINTS, *ARM], **_servos(n)}
    shared["motors.transmission_radius"] = [0.0985, 0.0985, 0.0, 0.01] + [0.0] * 7  # the wheel's; the torso's pinion
    sim = {"initial_position": [0.0, 0.0, 0.0, 0.1, 1.5, 0.3, -1.5, 0.8, 0.0, 0.0, 0.0]}
    ctl = {
        "voltage_gain": [1.0] * n,
        "null_space_posture.kp": [0.0, 0.0, 0.0, 0.0] + [5.0] * 7,
        "null_space_posture.kd": [0.0, 0.0, 0.0, 100.0] + [1.0] * 7,  # none on the base: it would brake the loop
        "base_command": "cmd_vel",
        "base_velocity_kd": kd,
        "base_velocity_ki": ki,
    }
    return build_scenario(TIAGO, shared=shared, sim=sim, ctl=ctl)


def wheeled_tiago(kd: float = 10.0, ki: float = 100.0) -> Scenario:
    """TIAGo on its turning wheels (torque input), base_command cmd_vel, each wheel's loop ``kd`` [N m s/rad] and
    ``ki`` [N m/rad]."""
    n = 2 + len(ARM)
    locked = build_scenario(TIAGO, with_controller=False).plant.robot.locked_joints
    shared: dict[str, Any] = {
        "robot.joint_names": ["wheel_left_joint", "wheel_right_joint", *ARM],
        "robot.locked_joints": [j for j in locked if j.startswith(("head_", "hand_"))],
        **_servos(n),
    }
    shared["motors.transmission_radius"] = [0.0, 0.0, 0.01] + [0.0] * 7
    sim = {"initial_position": [0.0, 0.0, 0.1, 1.5, 0.3, -1.5, 0.8, 0.0, 0.0, 0.0]}
    ctl = {
        "voltage_gain": [1.0] * n,
        "null_space_posture.kp": [0.0, 0.0, 0.0] + [5.0] * 7,
        "null_space_posture.kd": [0.0, 0.0, 100.0] + [1.0] * 7,
        "base_command": "cmd_vel",
        "base_velocity_kd": kd,
        "base_velocity_ki": ki,
    }
    return build_scenario(TIAGO, shared=shared, sim=sim, ctl=ctl)


@dataclass
class Drive:
    """A driven run, per step: the base's pose (x [m], y [m], yaw [rad]), the elbow's normal force [N], the
    tool's distance from its carried circle [m]; the controller's warnings."""

    pose: np.ndarray
    normal_force: np.ndarray
    hand_error: np.ndarray
    warnings: list[str] = field(default_factory=list)


def drive(scenario: Scenario, turn_rad_s: float = 0.0, log: Any = None) -> Drive:
    """``STEPS`` lockstep steps of the scenario under the controller's policy, cmd_vel (``SPEED_MPS`` forward,
    ``turn_rad_s``) sent at ``SENT_STEPS``; ``log`` the policy's (a ``ListLog`` if None)."""
    assert scenario.controller is not None
    log = ListLog() if log is None else log
    core = StateAnswerer(scenario.controller.config, log, lambda: 100.0)
    plant, sent = scenario.sim, list[Answer]()
    indices = base_indices(list(scenario.plant.joint_names))
    assert indices is not None
    pose, f_n, hand_error = np.zeros((STEPS, 3)), np.zeros(STEPS), np.zeros(STEPS)
    for k in range(STEPS):
        if k in SENT_STEPS:
            core.take_cmd_vel(k * 1_000_000, [SPEED_MPS, 0.0, 0.0], [0.0, 0.0, turn_rad_s])
        core.answer(k * 1_000_000, plant.position, plant.velocity, lambda _: None, sent.append)
        out = sent[-1].output
        pose[k], hand_error[k] = plant.position[list(indices)], np.linalg.norm(out.hand_desired - out.hand_actual)
        f_n[k] = plant.step(out.command).normal_force[0]
    return Drive(pose, f_n, hand_error, list(getattr(log, "warnings", [])))


def drive_figures(run: Drive) -> dict[str, float]:
    """A driven run's figures: where the base ends, its distance from its start [m] and its yaw [rad], how far it
    drifted before the first cmd_vel [m], its speed at the end [m/s]; the elbow's largest |f_n - f_nd| while
    driven (from the first cmd_vel to the timeout) and over the whole run, with its time [N, s]; the tool's
    largest distance from its carried circle from the first cmd_vel on [m]."""
    xy = run.pose[:, :2]
    off = np.abs(run.normal_force - F_ND)
    return {
        "travel_m": float(np.linalg.norm(xy[-1] - xy[0])),
        "yaw_rad": float(run.pose[-1, 2]),
        "drift_before_m": float(np.linalg.norm(xy[SENT_STEPS[0] - 1] - xy[0])),
        "end_speed_mps": float(np.linalg.norm(xy[-1] - xy[-2]) / STEP_S),
        "force_off_driven_max_n": float(off[DRIVEN].max()),
        "force_off_max_n": float(off.max()),
        "force_off_max_at_s": float(np.argmax(off) * STEP_S),
        "hand_error_driven_max_m": float(run.hand_error[SENT_STEPS[0] :].max()),
    }


BASES: dict[str, tuple[str, str, float]] = {
    "wheels": ("diff_drive, wheels turning", "kd 10 N m s/rad, ki 100 N m/rad per wheel", TURN_RAD_S),
    "planar": ("planar (wheels held)", "kd 500 N s/m, ki 5000 N/m", 0.0),
    "planar_no_integral": ("planar, no integral", "kd 500 N s/m", 0.0),
}
"""The table's runs: (base, its velocity loop, the commanded yaw rate [rad/s]), built by ``scenario_of``."""


def scenario_of(name: str) -> Scenario:
    """The scenario of ``BASES[name]``."""
    if name == "wheels":
        return wheeled_tiago(10.0, 100.0)
    return planar_tiago(500.0, 5000.0 if name == "planar" else 0.0)


def cmd_vel_table(found: dict[str, dict[str, float]]) -> dict[str, list[Any]]:
    """The results page's table: a row per base."""
    rows = []
    for name, (base, loop, turn) in BASES.items():
        f = found[name]
        commanded = f"{SPEED_MPS * COMMANDED_S:.3g} m" + (f", {turn * COMMANDED_S:.3g} rad" if turn else "")
        travel = f"{f['travel_m']:.3g} m" + (f", {f['yaw_rad']:.3g} rad" if turn else "")
        rows.append(
            [
                base,
                loop,
                f"{travel} ({commanded})",
                f"{f['drift_before_m'] * 1e3:.2g}",
                f"{f['end_speed_mps']:.2g}",
                f"{f['force_off_driven_max_n']:.2g}",
                f"{f['force_off_max_n']:.2g} (t = {f['force_off_max_at_s']:.3g} s)",
                f"{f['hand_error_driven_max_m'] * 1e3:.2g}",
            ]
        )
    header = [
        "base",
        "velocity loop",
        "travel from its start (commanded)",
        "drift before the first cmd_vel [mm]",
        "speed at the end [m/s]",
        "f_n off f_nd, largest while driven [N]",
        "over the run [N]",
        "tool off its carried circle, largest [mm]",
    ]
    return {"header": header, "rows": rows}


def record_cmd_vel(path: Path, found: dict[str, dict[str, float]]) -> Path:
    """The runs' figures and their table as the recorded file ``path``."""
    content = {"study": "TIAGo driven by cmd_vel", "config": TIAGO.name, "figures": found}
    return write_recorded(path, {**content, "tables": {TABLE: cmd_vel_table(found)}}, ROOT)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=(__doc__ or "").split("\n\n")[0])
    parser.add_argument("--record", type=Path, metavar="FILE", help="also write the table as a recorded file")
    args = parser.parse_args(argv)
    found = {name: drive_figures(drive(scenario_of(name), turn)) for name, (_, _, turn) in BASES.items()}
    print(markdown_table(**cmd_vel_table(found)))
    if args.record is not None:
        print(f"recorded: {record_cmd_vel(args.record, found)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
