"""The controller node's policy without DDS (bracing_core.answering.StateAnswerer): joint states refused
with the reason logged and nothing sent, the law's answer sent bit for bit, the wait for the step's
measurements, targets from the next state on, retunes, and the null-space warning said once."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from conftest import build_scenario, node_params
from test_stepping import Clock, Log

from bracing_core import checks
from bracing_core.answering import MEASUREMENT_WAIT_S, NULL_SPACE_CHECK_EVERY, Answer, StateAnswerer

Q0 = np.array([-0.2 * np.pi, -0.6 * np.pi, 0.9 * np.pi, 0.0])  # near the paper's start
NAMES = ["joint1", "joint2", "joint3", "joint4"]
REFUSED = ("error", "ignored", "")


def answerer(ctl: dict[str, Any] | None = None) -> tuple[StateAnswerer, Log, Clock, list[Answer]]:
    scenario = build_scenario(ctl=ctl)
    assert scenario.controller is not None
    log, clock = Log(), Clock()
    return StateAnswerer(scenario.controller.config, log, clock), log, clock, []


def no_reports(timeout_s: float) -> None:
    pass


def test_joint_states_are_matched_by_name_and_refused_with_the_reason() -> None:
    core, log, _, _ = answerer()
    assert core.joint_names == NAMES
    q, dq = np.arange(4.0), np.arange(4.0) + 10
    got = core.read_state(NAMES[::-1], q[::-1], dq[::-1], 0, REFUSED)
    assert got is not None and np.array_equal(got[0], q) and np.array_equal(got[1], dq)
    bad = [
        (NAMES[:3], q[:3], dq[:3], 0),  # a joint missing
        ([*NAMES[:3], "joint1"], q, dq, 0),  # duplicate
        (NAMES, np.array([0.0, np.nan, 0.0, 0.0]), dq, 0),  # not finite
        (NAMES, q[:3], dq, 0),  # lengths
        (NAMES, q, dq, 2**31 * 1_000_000_000),  # a stamp no answer can carry
    ]
    for names, position, velocity, stamp in bad:
        assert core.read_state(names, position, velocity, stamp, ("warning", "refused", "; no command sent")) is None
    assert [kind for _, kind, _ in log.reports] == ["missing", "duplicate", "non-finite", "length", "stamp"]
    assert all(level == "warning" and m.startswith("joint_states refused: ") for level, _, m in log.reports)
    assert log.reports[0][2].endswith("; no command sent")


def test_a_state_is_answered_with_the_law_s_output_bit_for_bit() -> None:
    core, log, _, sent = answerer()
    twin = build_scenario().controller
    assert twin is not None
    core.answer(5_000_000, Q0, np.zeros(4), no_reports, sent.append)
    expected = twin.update(0.005, Q0, np.zeros(4))
    assert [a.stamp_ns for a in sent] == [5_000_000] and core.answered_ns == 5_000_000
    assert np.array_equal(sent[0].output.command, expected.command)
    assert np.array_equal(sent[0].output.hand_desired, expected.hand_desired)
    assert not log.reports


def test_a_state_the_law_cannot_answer_sends_nothing() -> None:
    core, log, _, sent = answerer()
    core.answer(1_000_000, np.full(4, 1e300), np.full(4, 1e300), no_reports, sent.append)
    assert sent == [] and core.previous_ns is None and core.answered_ns == 0
    assert [kind for _, kind, _ in log.reports] in (["law"], ["command"])
    assert "joint_states at t = 0.001000 s ignored" in log.reports[0][2]


FEEDBACK = {"contacts.elbow.force_feedback.kp": 0.5}


def test_a_state_waits_for_the_last_step_s_force_report_then_says_it_lagged() -> None:
    core, log, clock, sent = answerer(FEEDBACK)
    assert core.measurements is not None and core.measurements.topics == ["contact_wrench/elbow"]
    waited: list[float] = []

    def late(timeout_s: float) -> None:  # no report comes: the wall clock runs
        waited.append(timeout_s)
        clock.now += timeout_s

    core.answer(0, Q0, np.zeros(4), late, sent.append)  # the first state has nothing to wait for
    assert waited == [0.0] and not log.reports
    core.answer(1_000_000, Q0, np.zeros(4), late, sent.append)
    assert sum(waited) == pytest.approx(MEASUREMENT_WAIT_S) and len(sent) == 2
    assert log.reports == [("warning", "lagging", "no report of the last step within 0.5 s: contact_wrench/elbow")]


def test_a_report_that_comes_ends_the_wait_and_a_bad_one_is_refused() -> None:
    core, log, clock, sent = answerer(FEEDBACK)
    core.answer(0, Q0, np.zeros(4), no_reports, sent.append)

    def reports(timeout_s: float) -> None:
        core.take_force("elbow", 0, np.array([0.0, np.inf, 1.0]))  # refused: not finite
        core.take_force("elbow", 0, np.array([0.0, 0.0, 3.0]), "base")  # refused: not world axes
        core.take_force("elbow", 0, np.array([0.0, 0.0, 3.0]))

    started = clock.now
    core.answer(1_000_000, Q0, np.zeros(4), reports, sent.append)
    assert clock.now == started and len(sent) == 2  # no wait: the report was there
    assert [kind for _, kind, _ in log.reports] == ["measurement", "measurement"]
    assert log.reports[1][2].startswith("ignored: contact_wrench/elbow: frame_id 'base'")


def test_a_target_is_followed_from_the_next_state_on() -> None:
    core, _, _, sent = answerer()
    twin = build_scenario().controller
    assert twin is not None
    core.answer(0, Q0, np.zeros(4), no_reports, sent.append)
    untouched = [twin.update(0.0, Q0, np.zeros(4))]
    core.targets.point(0, (sent[0].output.hand_desired + np.array([0.0, 0.0, 0.05])).tolist(), "world")
    for k in range(1, 20):
        core.answer(k * 1_000_000, Q0, np.zeros(4), no_reports, sent.append)
        untouched.append(twin.update(k * 1e-3, Q0, np.zeros(4)))
    rise = [a.output.hand_desired[2] - b.hand_desired[2] for a, b in zip(sent, untouched, strict=True)]
    assert rise[0] == 0.0 and rise[1] == pytest.approx(0.0, abs=1e-12)  # no jump where the target starts
    assert 0.0 < rise[-1] < 0.5 * 1.5 * 0.02**2 + 1e-9  # then toward the goal, at most a_max t^2 / 2 ahead


def test_a_retune_is_checked_whole_and_applied_from_the_next_state() -> None:
    core, log, _, sent = answerer()
    values = node_params("bracing_controller")
    unknown = "step: cannot change while running: not a parameter of the controller"
    assert core.retune(dict(values), [("step", 0.002)]) == unknown
    fixed = core.retune(dict(values), [("damping_lambda", 0.1)])
    assert fixed is not None and fixed.startswith("damping_lambda: cannot change while running: it needs a fresh start")
    refused = core.retune(dict(values), [("contacts.elbow.kp", [1.0] * 5)])  # one gain per brace axis
    assert refused is not None and "contacts.elbow.kp" in refused
    assert core.retuned is None and not log.lines
    assert core.retune(dict(values), [("contacts.elbow.desired_normal_force", -1.0)]) is None
    assert log.lines == ["retuned (from the next update): contacts.elbow.desired_normal_force = -1.0"]
    assert log.warnings == [checks.desired_force_warning("elbow", -1.0, 0.0)]
    assert core.config.shared.braced_contacts[0].desired_normal_force != -1.0
    core.answer(0, Q0, np.zeros(4), no_reports, sent.append)
    assert core.retuned is None and core.config.shared.braced_contacts[0].desired_normal_force == -1.0
    assert np.array_equal(sent[0].desired_normal_force, [-1.0])


def test_a_null_space_runaway_is_said_once_on_run_status(monkeypatch: pytest.MonkeyPatch) -> None:
    core, log, _, sent = answerer()
    monkeypatch.setattr(core.law, "null_space_speed", lambda dq: 1e3)
    monkeypatch.setattr(checks, "TASKS_SATISFIED_M", np.inf)
    for k in range(3 * NULL_SPACE_CHECK_EVERY):
        core.answer(k * 1_000_000, Q0, np.zeros(4), no_reports, sent.append)
    assert len(sent) == 3 * NULL_SPACE_CHECK_EVERY
    t = (NULL_SPACE_CHECK_EVERY - 1) * 1e-3
    assert len(log.said) == 1 and log.said[0][1] == pytest.approx(t)
    assert log.said[0][0].startswith(f"at t = {t:.3f} s joints move at 1e+03 rad/s where no task sees them")
