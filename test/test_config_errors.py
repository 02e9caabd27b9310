"""A bad configuration fails at start-up with one message naming the parameter or file."""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import CONFIG_DIR, PAPER_YAML, build_scenario, node_params
from ros_helpers import node_argv, pair_argv, run

from bracing_core.chain_urdf import JointSpec, LinkSpec, chain_urdf, serial_chain_urdf
from bracing_core.config import SimulatorConfig, build_simulator
from bracing_core.controller_config import ControllerConfig
from bracing_core.law import DecoupledController
from bracing_core.params import ConfigError
from bracing_core.rcl_yaml import load_params_file

SIM_CASES: list[tuple[str, dict[str, Any], str]] = [
    ("missing urdf", {"robot.urdf": "no_such_robot.urdf"}, "robot.urdf: file 'no_such_robot.urdf' not found"),
    ("unknown frame", {"contacts.elbow.frame": "knee"}, "unknown frame 'knee'"),
    ("short motor array", {"motors.resistance": [0.6, 0.6]}, "motors.resistance: expected 4 values"),
    ("zero resistance", {"motors.resistance": [0.6, 0.0, 0.6, 0.6]}, "motors.resistance: values must be > 0"),
    ("negative inductance", {"motors.inductance": [0.17, 0.17, -1.0, 0.17]}, "motors.inductance: values must be > 0"),
    ("zero step", {"step": 0.0}, "step: must be > 0"),
    ("wrong type", {"step": "fast"}, "step: expected a finite number"),
    ("bad mode", {"input_mode": "current"}, "input_mode: expected one of voltage, torque, got 'current'"),
    ("unknown parameter", {"stpe": 0.001}, "unknown parameter(s): stpe"),
    ("unknown contact field", {"contacts.elbow.frictoin": 0.1}, "unknown parameter(s): contacts.elbow.frictoin"),
    ("initial position length", {"initial_position": [0.0, 0.0]}, "initial_position: expected 4 values"),
    (
        "wrong joint names",
        {"robot.joint_names": ["joint1", "joint2", "joint3", "wrist"]},
        "do not match the model's joints",
    ),
    ("infeasible start", {"initial_position": [-0.6, -1.88, 2.51, -1.26]}, "infeasible start: contact 'elbow'"),
    ("zero normal", {"contacts.elbow.normal": [0.0, 0.0, 0.0]}, "contacts.elbow.normal: must be a non-zero vector"),
    ("negative friction", {"contacts.elbow.friction": -0.1}, "contacts.elbow.friction: must be >= 0"),
]


@pytest.mark.parametrize(("case", "overrides", "message"), SIM_CASES, ids=[c[0] for c in SIM_CASES])
def test_simulator_configuration_errors(case: str, overrides: dict[str, Any], message: str) -> None:
    with pytest.raises(ConfigError) as error:
        build_simulator(SimulatorConfig.from_params(node_params("bracing_simulator", overrides), [CONFIG_DIR]))
    assert message in str(error.value)
    assert "\n" not in str(error.value)


CONTROLLER_CASES: list[tuple[str, dict[str, Any], str]] = [
    (
        "task above n - p",
        {"contacts.elbow.brace_axes": ["y", "z"], "contacts.elbow.kp": [1.0, 1.0], "contacts.elbow.kd": [1.0, 1.0]},
        "exceeds n - p = 4 - 1 = 3",
    ),
    ("hand gains length", {"hand.kp": [300.0]}, "hand.kp: expected 2 values"),
    ("brace gains length", {"contacts.elbow.kd": [20.0, 1.0]}, "contacts.elbow.kd: expected 1 values"),
    ("unknown hand frame", {"hand.frame": "gripper"}, "unknown frame 'gripper'"),
    ("bad axis", {"hand.axes": ["y", "w"]}, "hand.axes: axes must be among x, y, z"),
    (
        "bad trajectory",
        {"hand.trajectory.type": "spiral"},
        "hand.trajectory.type: expected one of hold, circle, waypoints",
    ),
    ("zero period", {"hand.trajectory.period": 0.0}, "hand.trajectory.period: must be > 0"),
    ("voltage gain sign", {"voltage_gain": [1.0, -1.0, 1.0, 1.0]}, "voltage_gain: K_V must be positive definite"),
]


@pytest.mark.parametrize(("case", "overrides", "message"), CONTROLLER_CASES, ids=[c[0] for c in CONTROLLER_CASES])
def test_controller_configuration_errors(case: str, overrides: dict[str, Any], message: str) -> None:
    with pytest.raises(ConfigError) as error:
        DecoupledController(ControllerConfig.from_params(node_params("bracing_controller", overrides), [CONFIG_DIR]))
    assert message in str(error.value)


def test_non_positive_mass_in_the_urdf_is_refused(tmp_path: Path) -> None:
    urdf = tmp_path / "bad.urdf"
    urdf.write_text(
        chain_urdf("bad", (1.0, 0.0, 0.5, 1.0), (0.5,) * 4, (0.03,) * 4, (2.0,) * 4, {"elbow": 2, "hand": 4})
    )
    with pytest.raises(ConfigError, match=r"link2.*mass"):
        build_simulator(SimulatorConfig.from_params(node_params("bracing_simulator", {"robot.urdf": str(urdf)})))


def test_unreadable_urdf_is_refused(tmp_path: Path) -> None:
    urdf = tmp_path / "broken.urdf"
    urdf.write_text("<robot name='x'><link name='a'>")
    with pytest.raises(ConfigError, match=r"robot\.urdf: pinocchio cannot load"):
        build_simulator(SimulatorConfig.from_params(node_params("bracing_simulator", {"robot.urdf": str(urdf)})))


def test_missing_params_file_is_refused(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="params file not found"):
        load_params_file(tmp_path / "nope.yaml", "bracing_simulator")


@pytest.mark.parametrize("module", ["bracing_sim.node", "bracing_controller.node"])
def test_nodes_exit_with_one_line_naming_the_problem(tmp_path: Path, module: str) -> None:
    extra = tmp_path / "bad.yaml"
    extra.write_text("/**:\n  ros__parameters:\n    robot:\n      urdf: /nonexistent/robot.urdf\n")
    done = run(node_argv(module, extra))
    assert done.returncode == 2
    assert done.stderr.strip() == "error: robot.urdf: file not found: /nonexistent/robot.urdf"


def test_unparsable_params_file_is_one_clear_line(tmp_path: Path) -> None:
    bad = tmp_path / "bad.yaml"
    bad.write_text("bracing_simulator:\n  ros__parameters:\n    step: [1.0, 'a']\n")
    done = run([sys.executable, "-m", "bracing_sim.node", "--ros-args", "--params-file", str(bad)])
    assert done.returncode == 2
    assert "Traceback" not in done.stderr
    last = done.stderr.strip().splitlines()[-1]  # rcl logs a line of its own first
    assert last.startswith("error: ") and "params file" in last


def test_pair_refuses_a_bad_configuration_before_starting_anything(tmp_path: Path) -> None:
    config = tmp_path / "scenario.yaml"
    config.write_text(
        PAPER_YAML.read_text()
        .replace("resistance: [0.6, 0.6, 0.6, 0.6]", "resistance: [0.6, 0.6]")
        .replace("urdf: paper_4link.urdf", f"urdf: {CONFIG_DIR / 'paper_4link.urdf'}")
    )
    done = run(pair_argv(tmp_path / "run", config=config))
    assert done.returncode == 2
    assert "motors.resistance: expected 4 values" in done.stderr
    assert not (tmp_path / "run" / "bag").exists()


@pytest.mark.parametrize(
    ("setting", "message"),
    [
        ("contacts.elbow.normal=[0,0,0]", "contacts.elbow.normal: must be a non-zero vector"),
        ("contacts.elbow.offset=0.05", "infeasible start: contact 'elbow' (frame 'elbow') is -0.05 m off its plane"),
        ("hand.axes=[x,y]", "hand.axes: frame 'hand' cannot move along x"),
    ],
    ids=["zero normal", "infeasible start", "task rank"],
)
def test_pair_refusing_what_only_the_full_check_finds_keeps_nothing(tmp_path: Path, setting: str, message: str) -> None:
    """The schema allows these; the configuration's own checks (the start posture, the task's
    rank there), which run while the processes start, refuse them: exit code 2, the line, no run
    directory (no empty bag) left, and no process of the run alive."""
    output = tmp_path / "run"
    done = run(pair_argv(output, "--set", setting))
    assert done.returncode == 2
    assert message in done.stderr
    assert "Traceback" not in done.stderr
    assert not output.exists()
    left = subprocess.run(["pgrep", "-f", str(output)], capture_output=True, text=True)
    assert left.stdout == "", left.stdout


# -- messages that point at the fix ---------------------------------------------------------
def yaw_arm_urdf() -> str:
    """The paper's arm with a base that turns about the vertical (joint1) instead of pitching: a spatial
    4-joint arm. Its elbow (tip of link 2) moves on a sphere about joint2; held at one height by the
    floor contact, only the base's turn moves it, along one direction of the x-y plane."""
    joints = [JointSpec("joint1", axis=(0.0, 0.0, 1.0))] + [JointSpec(f"joint{k}") for k in (2, 3, 4)]
    links = [LinkSpec("link1", 1.0, 0.1, 0.03)] + [LinkSpec(f"link{k}", 1.0, 0.5, 0.03) for k in (2, 3, 4)]
    return serial_chain_urdf("yaw_arm", joints, links, {"elbow": 2, "hand": 4})


def test_the_rank_check_names_a_combination_of_axes_and_the_free_directions(tmp_path: Path) -> None:
    """On the yaw arm the elbow's brace along x alone passes, along y alone too; [x, y] cannot: the
    frame has one free direction beside the floor contact. The message says that, not that the frame
    cannot move along y. An axis the frame never moves along keeps its message."""
    urdf = tmp_path / "yaw_arm.urdf"
    urdf.write_text(yaw_arm_urdf())
    q0 = [0.5, -0.6 * math.pi, 0.8 * math.pi, -0.4 * math.pi]  # the paper's pitches, the base turned 0.5 rad
    height = 0.1 + 0.5 * math.cos(q0[1])  # the elbow's z at q0: the floor is put there

    def brace(axes: list[str]) -> None:
        shared = {
            "robot.urdf": str(urdf),
            "contacts.elbow.offset": height,
            "contacts.elbow.brace_axes": axes,
            "contacts.elbow.kp": [100.0] * len(axes),
            "contacts.elbow.kd": [20.0] * len(axes),
        }
        build_scenario(
            shared, sim={"initial_position": q0}, ctl={"hand.axes": ["z"], "hand.kp": [300.0], "hand.kd": [50.0]}
        )

    brace(["x"])
    brace(["y"])
    with pytest.raises(ConfigError) as combined:
        brace(["x", "y"])
    assert str(combined.value) == (
        "contacts.elbow.brace_axes: [x, y] needs 2 free directions beside the contacts; frame 'elbow' has 1 along "
        "them at the start (each axis alone has one): keep one of them"
    )
    with pytest.raises(ConfigError, match=r"contacts\.elbow\.brace_axes: frame 'elbow' cannot move along z"):
        brace(["z"])  # the floor holds its height


def test_the_tasks_before_an_axis_that_take_its_direction_are_named() -> None:
    """The paper's arm with its wrist straight (joint4 = 0, links 3 and 4 at 0.3 pi from the vertical):
    joints 3 and 4 then move the hand along one direction only, so the hand along y and z takes the
    elbow's one free direction too; the elbow's y, free on its own, has none left, and the message names
    the hand's axes with it."""
    with pytest.raises(ConfigError) as error:
        build_scenario(sim={"initial_position": [-0.2 * math.pi, -0.6 * math.pi, 1.1 * math.pi, 0.0]})
    assert str(error.value) == (
        "contacts.elbow.brace_axes: [y] with hand.axes [y, z] needs 3 free directions beside the contacts; the arm "
        "has 2 for them at the start (each task alone has enough): remove an axis from one of them"
    )


def test_extra_model_joints_point_at_locked_joints_and_need_no_entries(tmp_path: Path) -> None:
    """The issue's arm: a URDF with two prismatic gripper fingers beyond the joints the file names. The
    mismatch says to lock them; locked without being named in robot.joint_names they need no entry in
    any per-joint list, and the run is the four-joint arm's. Named there, every per-joint list counts
    them, and the length error says so."""
    urdf = tmp_path / "gripper.urdf"
    fingers = [JointSpec(f"finger_{side}", type="prismatic", axis=(0.0, 1.0, 0.0), lower=-0.05, upper=0.05)
               for side in ("left", "right")]  # fmt: skip
    joints = [JointSpec(f"joint{k}") for k in (1, 2, 3, 4)] + fingers
    links = [
        LinkSpec(f"link{k}", m, 0.5, r) for k, m, r in ((1, 1.0, 0.03), (2, 1.0, 0.03), (3, 0.5, 0.01), (4, 1.0, 0.03))
    ]
    links += [LinkSpec(f"finger_{side}_link", 0.05, 0.05, 0.005) for side in ("left", "right")]
    urdf.write_text(serial_chain_urdf("gripper_arm", joints, links, {"elbow": 2, "hand": 4}))
    with pytest.raises(ConfigError) as mismatch:
        build_scenario({"robot.urdf": str(urdf)})
    message = str(mismatch.value)
    assert message.startswith("robot.joint_names ['joint1', 'joint2', 'joint3', 'joint4'] do not match the model's")
    assert "it also moves 'finger_left', 'finger_right': to hold them fixed, set robot.locked_joints: " in message
    assert "[finger_left, finger_right] (a locked joint not in robot.joint_names needs no entry" in message
    sc = build_scenario({"robot.urdf": str(urdf), "robot.locked_joints": ["finger_left", "finger_right"]})
    assert sc.plant.joint_names == ("joint1", "joint2", "joint3", "joint4")
    paper = build_scenario({})
    assert sc.controller is not None and paper.controller is not None
    np.testing.assert_allclose(sc.sim.position, paper.sim.position, rtol=0, atol=0)
    named = {
        "robot.urdf": str(urdf),
        "robot.joint_names": ["joint1", "joint2", "joint3", "joint4", "finger_left", "finger_right"],
        "robot.locked_joints": ["finger_left", "finger_right"],
    }
    with pytest.raises(ConfigError) as counted:
        build_scenario(named)
    assert str(counted.value) == (
        "motors.torque_constant: expected 6 values (one per joint of robot.joint_names (6), the locked finger_left, "
        "finger_right included (values unused; a joint in robot.locked_joints but not in robot.joint_names needs "
        "none)), got 4"
    )
