"""Sensors, latency, model error and force feedback through the real nodes (bracing-pair over DDS): the
lockstep pair runs the same loop as the in-process rollout, and its bag holds what the controller
received beside the truth, which the summary judges."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from conftest import build_scenario
from ros_helpers import pair_argv, run
from rosbags.highlevel import AnyReader

from bracing_analysis.bag import read_series
from bracing_analysis.figures import plot_figure
from bracing_core.rollout import RunResult, run_recorded

DURATION_S = 2.2  # hand errors count from t = 2 s
COUNTS = 4096
SIM = {
    "sensors.encoder_counts_per_rev": COUNTS,
    "sensors.velocity_filter_hz": 100.0,
    "sensors.force_noise_n": 0.5,
    "sensors.force_bias_n": 0.4,
    "sensors.noise_seed": 11,
    "sensors.command_latency_steps": 2,
    "plant_error.mass_scale": 1.2,
}
CTL = {"contacts.elbow.force_feedback.kp": 0.3, "contacts.elbow.force_feedback.ki": 100.0}


def by_stamp(messages: list[object]) -> list[object]:
    return sorted(messages, key=lambda m: m.header.stamp.sec * 10**9 + m.header.stamp.nanosec)  # type: ignore[attr-defined]


@pytest.fixture(scope="module")
def sensed_run(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[str, list[object]], RunResult]:
    output = tmp_path_factory.mktemp("sensed") / "run"
    sets = [f"--set={key}={value}" for key, value in {**SIM, **CTL}.items()]
    done = run(
        pair_argv(output, "--duration", str(DURATION_S), "--mode", "torque", "--no-animation", *sets), timeout=300
    )
    assert done.returncode == 0, done.stdout + done.stderr
    messages: dict[str, list[object]] = {}
    with AnyReader([output / "bag"]) as reader:
        for connection, _, raw in reader.messages():
            messages.setdefault(connection.topic, []).append(reader.deserialize(raw, connection.msgtype))
    reference = run_recorded(build_scenario({"input_mode": "torque"}, sim=SIM, ctl=CTL), DURATION_S)
    return output, messages, reference


def test_the_pair_runs_the_rollouts_loop(sensed_run: tuple[Path, dict[str, list[object]], RunResult]) -> None:
    """What the controller received (joint_states) and what was true (ground_truth/joint_states) are the
    rollout's measured and true positions: the same noise, the same delay line, the same force fed back
    (the controller answers state k + 1 with the force report of step k, as the rollout does). Not bit
    for bit: the node's time is its stamp, k 1e6 ns * 1e-9, the rollout's k h, so the feedback integral's
    dt differs in its last bit (commands by 4e-14 N m), as the paper's own pair and rollout differ."""
    _, messages, reference = sensed_run
    states = reference.time.size
    measured = np.array([m.position for m in by_stamp(messages["/joint_states"])])  # type: ignore[attr-defined]
    truth = np.array([m.position for m in by_stamp(messages["/ground_truth/joint_states"])])  # type: ignore[attr-defined]
    assert measured.shape == truth.shape == (states, 4)
    # one count at most where a true q within rounding of a count's edge reads the other side (none seen)
    assert np.max(np.abs(measured - reference.measured_position)) <= 2.0 * math.pi / COUNTS * (1 + 1e-9)
    np.testing.assert_allclose(truth, reference.position, rtol=0, atol=1e-9)  # measured: 4e-14
    ticks = measured / (2.0 * math.pi / COUNTS)
    assert np.max(np.abs(ticks - np.round(ticks))) < 1e-9  # every published q on the encoder's grid
    assert len(messages["/ground_truth/motor_state"]) == states


def test_the_wrench_topic_carries_the_sensor_and_contacts_the_truth(
    sensed_run: tuple[Path, dict[str, list[object]], RunResult],
) -> None:
    _, messages, reference = sensed_run
    wrench = np.array([[m.wrench.force.z] for m in by_stamp(messages["/contact_wrench/elbow"])])[:, 0]  # type: ignore[attr-defined]
    true = np.array([m.contacts[0].normal_force for m in by_stamp(messages["/contacts"])])  # type: ignore[attr-defined]
    np.testing.assert_allclose(true, reference.normal_force[:, 0], rtol=0, atol=1e-9)
    offset = wrench - true  # the floor's normal is +z: the bias, plus the noise
    assert abs(float(offset.mean()) - 0.4) < 4 * 0.5 / math.sqrt(offset.size)
    assert float(offset.std()) == pytest.approx(0.5, rel=0.1)


def test_the_summary_judges_the_truth(sensed_run: tuple[Path, dict[str, list[object]], RunResult]) -> None:
    """The controller believes the hand where the measured q put it; the summary's hand error is the true one
    (the rollout's), and the force error the true force's."""
    output, messages, reference = sensed_run
    summary = json.loads((output / "summary.json").read_text())
    window = reference.time >= 2.0 - 1e-12
    hand = np.linalg.norm(reference.hand_desired[window] - reference.hand_actual[window], axis=1)
    assert summary["hand_rms_error_m"] == pytest.approx(float(np.sqrt(np.mean(hand**2))), rel=1e-9)
    force = reference.normal_force[:, 0] - reference.desired_normal_force[0]
    assert summary["normal_force_rms_error_n"] == pytest.approx(float(np.sqrt(np.mean(force**2))), rel=1e-6)
    states = by_stamp(messages["/controller_state"])
    believed = np.array([[m.hand_actual.x, m.hand_actual.y, m.hand_actual.z] for m in states])  # type: ignore[attr-defined]
    assert 0.0 < np.max(np.abs(believed - reference.hand_actual)) < 0.01  # a count's worth at the hand, not the truth


def test_the_report_draws_measured_beside_true(sensed_run: tuple[Path, dict[str, list[object]], RunResult]) -> None:
    """The hand and brace figures draw what the controller believed (dotted) beside the truth."""
    output, _, reference = sensed_run
    series = read_series(output / "bag")
    np.testing.assert_allclose(series.hand_actual, reference.hand_actual, rtol=0, atol=1e-9)
    for name in ("hand_y", "brace_y"):
        labels = [line.get_label() for line in plot_figure(name, series).axes[0].get_lines()]
        assert any("as measured" in label for label in labels), (name, labels)
