"""bracing-pair --engine mujoco: our controller, unchanged (effort_forward), braces the paper arm in MuJoCo.

The MuJoCo node (bracing_mujoco.mujoco_robot) has a mujoco_ros2_control robot's topic face; the run is
compared with our engine's on the same scenario, torque input, 2 s. Tolerances, with what was measured:
- Penetration <= 1.5 mm (measured 0.85 mm). MuJoCo's contacts are soft: at its default solref (0.02 s
  time constant, damping ratio 1) and solimp (0.9-0.95) the elbow sphere sinks until the constraint's
  spring holds f_nd = 10 N; our engine holds the elbow on the floor exactly (a constraint, ~1e-16 m).
- f_n against f_nd: within 0.1 N from t = 0.2 s (measured 0.021 N), rms 0.5 N over the whole run
  (measured 0.31 N): the first ~0.15 s are the soft contact settling (the sphere sinking in, up to
  2.8 N off) while the elbow starts to slide; our engine's f_n is f_nd to 1e-14 from the first step.
- The friction force stays inside MuJoCo's elliptic cone, |f_t| <= mu f_n, to 2 % (measured 0.1 %:
  the soft cone's regularisation lets it sit on the cone's edge while sliding).
- The hand within 3 mm of our engine's at every controller stamp (measured 1.2 mm, in the soft
  contact's first 50 ms), and the elbow active (f_n > 0) in every sample: it never leaves the floor.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
from rclpy.qos import QoSProfile, ReliabilityPolicy
from ros_helpers import REPO_ROOT, NodeProcess, isolated_env, node_argv, pair_argv, params_file, start
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray
from test_fuzz import close_peer, start_peer

from bracing_analysis.bag import read_series
from bracing_analysis.wrench_contacts import contacts_from_wrenches

sys.path.insert(0, str(REPO_ROOT / "tools"))
import engine_comparison

MU = 0.1  # config/paper_4link.yaml's elbow friction
F_ND = 10.0  # [N] its desired normal force


def _run(output: Path, *extra: str) -> dict:
    done = subprocess.run(
        pair_argv(output, *engine_comparison.PAIR_ARGS, *extra),  # the results page's comparison's runs
        env=isolated_env(),
        capture_output=True,
        text=True,
        timeout=120,
        cwd=REPO_ROOT,
    )
    assert done.returncode == 0, done.stdout + done.stderr
    return json.loads((output / "summary.json").read_text())


def test_pair_on_mujoco_keeps_the_elbow_on_the_floor_at_the_desired_force(tmp_path: Path) -> None:
    summary = _run(tmp_path / "mujoco", "--engine", "mujoco")
    ours = _run(tmp_path / "bracing")
    elbow = summary["contacts"]["elbow"]
    assert summary["input_mode"] == "torque" and elbow["braced"]
    assert elbow["active_fraction"] == 1.0
    assert 0.0 < summary["max_penetration_m"] <= 1.5e-3
    assert elbow["normal_force_rms_error_n"] <= 0.5
    assert summary["energy_consumed_j"] is None and elbow["slip_m"] is None  # n/a: no motor_state, no slip speed
    series = read_series(tmp_path / "mujoco" / "bag")
    assert series.topic_counts["/contacts"] == 0 and series.topic_counts["/contact_wrench/elbow"] == 2001
    contacts_from_wrenches(series)
    cs = series.contacts["elbow"]
    late = cs.t >= 0.2
    assert np.max(np.abs(cs.normal_force[late] - F_ND)) <= 0.1
    assert np.all(cs.friction_force <= 1.02 * MU * cs.normal_force)
    base = read_series(tmp_path / "bracing" / "bag")
    _, here, there = np.intersect1d(np.round(series.t, 6), np.round(base.t, 6), return_indices=True)
    assert here.size >= 1990
    assert np.max(np.linalg.norm(series.hand_actual[here] - base.hand_actual[there], axis=1)) <= 3e-3
    assert abs(summary["hand_rms_error_m"] - ours["hand_rms_error_m"]) <= 3e-3

    # The results page's comparison (tools/engine_comparison.py) from these two runs: its figures as measured here.
    found = engine_comparison.figures(tmp_path / "mujoco", tmp_path / "bracing")
    assert found["common_stamps"] == here.size and found["hand_apart_max_m"] <= 3e-3
    assert found["mujoco"]["penetration_m"] == summary["max_penetration_m"]
    assert found["mujoco"]["force_late_max_n"] == np.max(np.abs(cs.normal_force_error[cs.t_matched >= 0.2]))
    assert found["mujoco"]["force_late_max_n"] <= 0.1 and found["mujoco"]["force_rms_n"] <= 0.5
    assert found["ours"]["force_rms_n"] <= 1e-9 and found["ours"]["penetration_m"] <= 1e-9  # held exactly
    recorded = json.loads(engine_comparison.record_comparison(tmp_path / "comparison.json", found).read_text())
    assert set(recorded) == {"recorded", "study", "config", "figures", "tables"} and recorded["figures"] == found
    table = recorded["tables"][engine_comparison.TABLE]
    assert len(table["rows"]) == 6 and all(len(row) == 3 for row in table["rows"])


def test_mujoco_robot_refuses_a_wrong_length_and_a_non_finite_command(tmp_path: Path) -> None:
    """One error per kind (rate-limited: the same kind within log_throttle_period counted, not repeated),
    naming what was wrong; the held (zero) command stays. The robot steps once joint_states has a subscriber
    (min_subscribers 1), which the peer makes only after the robot's log shows both refusals: its 0.02 s run
    comes after them, however slowly either process starts."""
    alone = {
        "wait_for_recorder": False,
        "min_subscribers": 1,
        "min_status_subscribers": 0,
        "duration": 0.02,
        "log_throttle_period": 3600.0,  # the inf (a second non-finite) within it, whatever the machine's pace
    }
    env = isolated_env()
    argv = node_argv("bracing_mujoco.mujoco_robot", params_file(tmp_path, "bracing_simulator", alone))
    robot = NodeProcess(start(argv, env))
    peer = start_peer(env, "bad_commander")
    try:
        reliable = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
        pub = peer.node.create_publisher(Float64MultiArray, "effort_controller/commands", reliable)
        assert peer.spin_until(lambda: pub.get_subscription_count() >= 1, 60.0), robot.text()[-3000:]
        for data in ([1.0, 2.0, 3.0], [math.nan, 0.0, 0.0, 0.0], [0.0, 0.0, math.inf, 0.0]):
            pub.publish(Float64MultiArray(data=data))
        for refused in ("3 values for 4 joints", "non-finite value at index 0 (nan)"):
            assert robot.wait_for(f"effort_controller/commands refused: {refused}", 60.0), robot.text()[-3000:]
        peer.listen(JointState, "joint_states", lambda m: m.effort)  # the robot's run starts
        states = peer.received["joint_states"]
        last = 20_000_000  # [ns] the run's last state's stamp (0.02 s)
        assert peer.spin_until(lambda: states and states[-1].header.stamp.nanosec == last, 60.0), robot.text()[-3000:]
        robot.process.wait(60)  # it ends by itself
    finally:
        close_peer(peer)
        code = robot.stop()
    log = robot.text()
    assert code == 0, log
    assert "index 2 (inf)" not in log
    assert "finished at t = 0.020000 s" in log
    assert all(not any(state.effort) for state in states), states[-1:]  # the held zero command, from the first
