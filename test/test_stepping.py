"""The simulator node's stepping policy without DDS (bracing_core.stepping.SimulatorStepper): stamp
matching, refusal and rollback, the watchdog, the warnings, the real-time pace and the run's end, with an
injected wall clock, a list for a log and a list for the publishers. The node only wires these to ROS."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from conftest import build_scenario

from bracing_core import checks
from bracing_core.rollout import run_recorded
from bracing_core.simulator import DivergenceError
from bracing_core.stepping import EFFORT_WAIT_S, HeldEffort, Periodic, SimulatorStepper, StateOut, StepOut


class Clock:
    """Wall time [s] that moves only when told (each ``receive`` in these tests moves it by its timeout)."""

    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


class Log:
    """The node's log, rate-limited log and run_status as lists."""

    def __init__(self) -> None:
        self.lines: list[str] = []
        self.warnings: list[str] = []
        self.reports: list[tuple[str, str, str]] = []  # (level, kind, message), rate-limited in the node
        self.marked: list[str] = []
        self.said: list[tuple[str, float]] = []  # run_status warnings: what the summary reads

    def info(self, message: str) -> None:
        self.lines.append(message)

    def warning(self, message: str) -> None:
        self.warnings.append(message)

    def limited(self, level: str, kind: str, message: str) -> None:
        self.reports.append((level, kind, message))

    def mark(self, kind: str) -> None:
        self.marked.append(kind)

    def say(self, warnings: list[str], t: float) -> None:
        self.said += [(w, t) for w in warnings]

    def kinds(self) -> list[str]:
        return [kind for _, kind, _ in self.reports]


class Outlet:
    """The publishers: what each step sent."""

    def __init__(self) -> None:
        self.states: list[StateOut] = []
        self.steps: list[StepOut] = []
        self.sent_count = 0
        self.progress_times: list[float] = []

    def publish_state(self, state: StateOut) -> None:
        self.states.append(state)

    def publish_step(self, step: StepOut) -> None:
        self.steps.append(step)

    def sent(self) -> None:
        self.sent_count += 1

    def progress(self, t: float) -> None:
        self.progress_times.append(t)


def stepper(shared: dict[str, Any] | None = None, **sim: Any) -> tuple[SimulatorStepper, Log, Outlet, Clock]:
    scenario = build_scenario(shared, sim, with_controller=False)
    assert scenario.sim_config is not None
    log, outlet, clock = Log(), Outlet(), Clock()
    core = SimulatorStepper(scenario.sim_config, scenario.plant, scenario.sim, log, outlet, clock)
    return core, log, outlet, clock


def snapshot(core: SimulatorStepper) -> tuple[bytes, int, bytes, int]:
    """The simulator's whole state, bit for bit (state vector with the energies, steps, contacts, events)."""
    sim = core.sim
    state = sim.engine.state
    blocks = (state.position, state.velocity, state.current, state.temperature, state.energy)
    return np.concatenate(blocks).tobytes(), sim.steps_taken, sim.active.tobytes(), len(sim.events)


def receiving(core: SimulatorStepper, clock: Clock, offers: list[tuple[int, np.ndarray]]) -> Any:
    """A ``receive`` that offers the next queued (stamp, command) each call, and lets the wall clock run
    by its timeout when none is left (no command comes)."""

    def receive(timeout_s: float) -> None:
        if offers:
            core.offer(*offers.pop(0), False)
        else:
            clock.now += timeout_s

    return receive


U = np.array([0.3, -0.2, 0.1, 0.05])  # [V], a modest command for the paper's four joints


def test_a_command_with_another_stamp_is_refused_and_changes_nothing() -> None:
    core, log, _, _ = stepper()
    core.send_state()
    before = snapshot(core)
    core.offer(core.step_ns, U, False)  # from the future: state 1 is not out yet
    core.offer(-core.step_ns, U, False)  # stale
    assert core.pending == {}
    assert snapshot(core) == before
    assert log.kinds() == ["from the future", "stale"]
    assert "stamp 0.001000 s is from the future (waiting for 0.000000 s)" in log.reports[0][2]
    core.offer(0, U, False)
    assert list(core.pending) == [0] and snapshot(core) == before  # kept for its step, not applied yet


def test_lockstep_steps_with_the_answer_to_the_state() -> None:
    core, log, outlet, clock = stepper()
    core.send_state()
    core.step_lockstep(receiving(core, clock, [(0, U)]))
    assert core.sim.steps_taken == 1 and np.array_equal(core.command, U)
    assert [s.t_ns for s in outlet.states] == [0, core.step_ns]  # the new state goes out
    assert [s.t_ns for s in outlet.steps] == [0]  # then the reports of the step it came from
    assert outlet.sent_count == 1 and not log.reports


def test_a_refused_step_rolls_back_exactly_and_sends_nothing() -> None:
    core, _, outlet, clock = stepper()
    core.send_state()
    core.step_lockstep(receiving(core, clock, [(0, U)]))
    before, sent = snapshot(core), (len(outlet.states), len(outlet.steps), outlet.sent_count)
    assert not core.advance(np.full(4, 1e300))
    assert snapshot(core) == before
    assert (len(outlet.states), len(outlet.steps), outlet.sent_count) == sent
    assert core.refusal and np.array_equal(core.command, U)


def engine_snapshot(core: SimulatorStepper) -> tuple[Any, ...]:
    """``snapshot`` and the engine's contact modes (sticking contacts, slide directions, signs of f_n held)."""
    modes = core.sim.engine.modes
    return (*snapshot(core), list(modes.held), list(modes.sticking), modes.slide.tobytes(), modes.pushing.tobytes())


@pytest.mark.parametrize(
    ("command", "speed", "residual", "reason"),
    [
        (np.full(4, 1e300), np.inf, np.inf, "non-finite"),  # the engine's status: the state diverged
        (U, 0.0, np.inf, "joint speed exceeds divergence_speed 0.0"),  # the node's refusal of a step taken
        (U, np.inf, 0.0, "constraint residual"),
    ],
)
def test_a_step_the_engine_takes_back_leaves_what_checkpoint_and_restore_leave(
    command: np.ndarray, speed: float, residual: float, reason: str
) -> None:
    """Simulator.advance takes a refused step back in the engine, to where the node's checkpoint and restore
    took it (the contact modes as before the step's start, the event log, the step count), so the next step
    is the same bit for bit."""
    core, *_ = stepper()
    twin, *_ = stepper()
    for c in (core, twin):
        c.advance(U)  # a state with contacts held and energies integrated
    checkpoint = twin.sim.checkpoint()
    with np.errstate(over="ignore", invalid="ignore"), pytest.raises(DivergenceError, match=reason):
        core.sim.advance(command, speed, residual, True)
    with np.errstate(over="ignore", invalid="ignore"), pytest.raises(DivergenceError):  # the Python path
        twin.sim.step(command)
        twin.sim.check(speed, residual)
    twin.sim.restore(checkpoint)
    assert engine_snapshot(core) == engine_snapshot(twin)
    for c in (core, twin):
        assert c.advance(-U)
    assert engine_snapshot(core) == engine_snapshot(twin)


def test_a_refused_command_is_said_and_the_next_valid_one_is_taken() -> None:
    """The step continues exactly as if the absurd command had never come."""
    core, log, _, clock = stepper()
    twin, _, _, twin_clock = stepper()
    for c in (core, twin):
        c.send_state()
    stamp = 0
    core.step_lockstep(receiving(core, clock, [(stamp, np.full(4, 1e300)), (stamp, U)]))
    twin.step_lockstep(receiving(twin, twin_clock, [(stamp, U)]))
    assert log.kinds() == ["absurd"] and "would not be finite" in log.reports[0][2]
    assert "the state is kept" in log.reports[0][2]
    assert snapshot(core) == snapshot(twin)


def test_the_watchdog_holds_the_last_command_after_command_timeout() -> None:
    core, log, _, clock = stepper(command_timeout=0.25)
    twin, *_ = stepper()
    core.send_state()
    core.step_lockstep(receiving(core, clock, [(0, U)]))
    started = clock.now
    core.step_lockstep(receiving(core, clock, []))  # no answer to state 1
    assert clock.now - started == pytest.approx(0.25)  # it waited command_timeout, no longer
    for _ in range(2):
        twin.advance(U)
    assert snapshot(core) == snapshot(twin)  # stepped with the held command, bit for bit
    message = "no valid motor_command for t = 0.001000 s within 0.25 s: holding the last command"
    assert log.said == [(checks.first_report_warning(message, 0.001), 0.001)]  # said before the step
    assert log.marked == ["watchdog"] and core.watch.warnings == [log.said[0][0]]
    core.step_lockstep(receiving(core, clock, []))  # the second time: the rate-limited log counts it
    assert len(log.said) == 1 and log.reports[-1][:2] == ("warning", "watchdog")


def test_the_watchdog_applies_zero_when_asked() -> None:
    core, log, _, clock = stepper(command_timeout=0.1, watchdog_policy="zero")
    twin, *_ = stepper()
    core.send_state()
    core.step_lockstep(receiving(core, clock, [(0, U)]))
    core.step_lockstep(receiving(core, clock, []))
    twin.advance(U)
    twin.advance(np.zeros(4))
    assert snapshot(core) == snapshot(twin)
    assert log.said[0][0].find("applying zero") >= 0


def test_a_watchdog_step_that_diverges_ends_the_run() -> None:
    core, _, _, clock = stepper(command_timeout=0.1)
    core.send_state()
    core.command = np.full(4, 1e300)  # held: the watchdog would step with it
    with pytest.raises(DivergenceError, match="under the watchdog's command: hold"):
        core.step_lockstep(receiving(core, clock, []))
    assert core.sim.steps_taken == 0


def test_the_run_ends_with_the_answer_to_the_final_state_and_its_warnings() -> None:
    core, _, outlet, clock = stepper(duration=0.002)
    core.send_state()
    while not core.done():
        stamp = core.now_ns
        core.step_lockstep(receiving(core, clock, [(stamp, U)]))
    assert core.sim.steps_taken == 2
    core.finish_lockstep(receiving(core, clock, [(core.now_ns, 2 * U)]))
    assert np.array_equal(core.command, 2 * U)
    assert [s.t_ns for s in outlet.steps] == [0, core.step_ns, 2 * core.step_ns]  # the final state's reports too
    assert outlet.sent_count == 2  # the final reports are flushed by the node, not counted
    assert core.progress_line().startswith("progress t=0.002 max_residual=")


def test_the_run_ends_with_the_held_command_when_the_final_answer_is_absurd() -> None:
    core, log, outlet, clock = stepper({"input_mode": "torque"}, duration=0.001)
    core.send_state()
    core.step_lockstep(receiving(core, clock, [(0, U)]))
    with np.errstate(all="ignore"):
        core.finish(np.full(4, 1e308))  # finite, but the forces it asks for are not
    assert np.array_equal(core.command, U) and log.kinds() == ["absurd"]
    assert "at the final state" in log.reports[0][2]
    assert np.isfinite(outlet.steps[-1].forces.normal_force).all()


def test_saturation_is_warned_once_in_full_then_rate_limited() -> None:
    core, log, _, _ = stepper(shared={"motors.voltage_limit": 1.0})
    core.send_state()
    core.offer(0, U, True)
    core.offer(0, U, True)
    assert [w for w, _ in log.said] == [checks.first_report_warning("motor_command saturated to +/-1.0", 0.0)]
    assert log.reports == [("warning", "saturated", "motor_command saturated to +/-1.0")]


def test_real_time_steps_with_the_latest_command_then_zero_once_it_is_stale() -> None:
    core, log, _, clock = stepper(stepping="real_time", command_timeout=0.5)
    twin, *_ = stepper()
    assert core.period == pytest.approx(0.001)
    core.start_real_time()
    core.tick()  # no command yet: zero, not a watchdog warning (nothing went stale)
    core.offer(123, U, False)  # real time: any stamp, the latest counts
    core.tick()
    clock.now += 0.6
    core.tick()
    for u in (np.zeros(4), U, np.zeros(4)):
        twin.advance(u)
    assert snapshot(core) == snapshot(twin)
    assert [w for w, _ in log.said] == [checks.first_report_warning("motor_command stale: applying zero", 0.002)]


def test_real_time_refuses_an_absurd_command_for_good_and_steps_with_zero() -> None:
    core, log, _, _ = stepper(stepping="real_time")
    twin, *_ = stepper()
    core.start_real_time()
    core.offer(0, np.full(4, 1e300), False)
    core.tick()
    twin.advance(np.zeros(4))
    assert snapshot(core) == snapshot(twin) and core.latest_command is None
    assert log.kinds() == ["absurd"]


def test_the_real_time_pace_is_measured_and_a_slow_run_warned() -> None:
    core, log, _, clock = stepper(stepping="real_time", real_time_factor=2.0, duration=0.002)
    assert core.period == pytest.approx(0.0005)
    core.start_real_time()
    while not core.done():
        core.tick()
    clock.now += 0.004  # 2 ms of sim time in 4 ms of wall time: 0.5x, asked 2x
    core.finish_real_time()
    assert core.real_time_achieved == pytest.approx(0.5)
    assert f"{checks.REAL_TIME_ACHIEVED}0.5000x real time (asked 2x)" in log.lines
    assert checks.slow_real_time_warning(0.5, 2.0) in [w for w, _ in log.said]


def test_free_run_has_no_pace_and_no_pace_warning() -> None:
    core, log, _, clock = stepper(stepping="free_run", duration=0.001)
    assert core.period is None
    core.start_real_time()
    core.tick()
    clock.now += 1.0
    core.finish_real_time()
    assert not any("real time" in w for w, _ in log.said)


def test_free_run_steps_with_the_latest_motor_command_and_keeps_no_other() -> None:
    """free_run holds the latest command as real_time does (before: it kept every command by stamp for
    a lockstep step that never came, stepped with zero and grew without bound)."""
    core, _, _, _ = stepper(stepping="free_run", duration=0.002)
    twin, *_ = stepper()
    core.start_real_time()
    for k in range(50):
        core.offer(k, U * (k + 1) / 50, False)
    core.tick()
    twin.advance(U)
    assert snapshot(core) == snapshot(twin)
    assert core.pending == {}


def test_joint_commands_in_voltage_mode_go_through_the_drive_which_a_refused_step_does_not_advance() -> None:
    core, _, _, _ = stepper(stepping="real_time", command_source="joint_commands")
    assert core.drive is not None and not np.any(core.effort_limit)
    core.start_real_time()
    core.offer_effort(np.array([0.5, 0.0, 0.0, 0.0]), False)
    core.tick()
    integral = core.drive.integral.copy()
    assert np.any(integral != 0.0)  # a step taken: the current loop's period counts
    before = snapshot(core)
    request = core.latest_command
    assert request is not None
    voltage = core.drive.voltage(request[1], core.sim.current, core.sim.velocity, core.config.step)
    assert not core.advance(voltage * 1e300)
    assert snapshot(core) == before and np.array_equal(core.drive.integral, integral)


def test_joint_commands_saturate_efforts_to_the_torque_limit_in_torque_mode() -> None:
    shared = {"input_mode": "torque", "motors.torque_limit": 2.0}
    core, log, _, _ = stepper(shared, stepping="real_time", command_source="joint_commands")
    assert core.drive is None and core.effort_limit.tolist() == [2.0] * 4
    core.offer_effort(np.full(4, 2.0), True)
    assert log.reports == [("warning", "saturated", "/robot_joint_commands saturated to +/-2.0")]


def test_refusals_are_taken_back_from_the_sensors_too() -> None:
    """With noisy sensors a refused step draws no noise: the run goes on as if it had not been tried."""
    sensors = {"sensors.position_noise_rad": 1e-3, "sensors.force_noise_n": 0.5, "sensors.current_noise_a": 0.01}
    core, _, outlet, clock = stepper(**sensors)
    twin, _, twin_out, twin_clock = stepper(**sensors)
    for c in (core, twin):
        c.send_state()
    core.step_lockstep(receiving(core, clock, [(0, np.full(4, 1e300)), (0, U)]))
    twin.step_lockstep(receiving(twin, twin_clock, [(0, U)]))
    assert snapshot(core) == snapshot(twin)
    for ours, theirs in ((outlet.states[-1], twin_out.states[-1]),):
        assert ours.measured is not None and theirs.measured is not None
        assert all(np.array_equal(a, b) for a, b in zip(ours.measured, theirs.measured, strict=True))
    assert np.array_equal(outlet.steps[-1].wrenches, twin_out.steps[-1].wrenches)
    assert np.array_equal(outlet.steps[-1].current, twin_out.steps[-1].current)


PULLING = {"contacts.elbow.desired_normal_force": -30.0}
"""A bilateral table made to pull from t = 0.204 s: the watch's warning counts states across its batches."""


@pytest.mark.parametrize(("shared", "duration"), [(None, 0.05), (PULLING, 0.35)])
def test_lockstep_with_the_law_in_process_is_the_rollout_bit_for_bit(
    shared: dict[str, Any] | None, duration: float
) -> None:
    """The node's loop, its ROS taken away: the law answers each state, the policy steps with the answer;
    the warnings are the rollout's (the node hands its watch WATCH_EVERY states at once, the rollout all)."""
    scenario = build_scenario(shared)
    law = scenario.controller
    assert law is not None
    core, log, outlet, _ = stepper(shared, duration=duration)

    def receive(timeout_s: float) -> None:
        state = outlet.states[-1]
        core.offer(state.t_ns, law.update(state.t_ns * 1e-9, state.position, state.velocity).command, False)

    core.send_state()
    while not core.done():
        core.step_lockstep(receive)
    core.finish_lockstep(receive)
    recording = run_recorded(scenario, duration)
    assert np.array_equal(np.array([s.position for s in outlet.states]), recording.position)
    assert np.array_equal(np.array([s.velocity for s in outlet.states]), recording.velocity)
    assert np.array_equal(np.array([s.forces.normal_force for s in outlet.steps]), recording.normal_force)
    assert np.array_equal(np.array([s.current for s in outlet.steps]), recording.current)
    assert [w for w, _ in log.said] == list(recording.warnings) and not log.reports
    assert len(log.said) == (1 if shared else 0)


def test_the_mujoco_robot_holds_a_valid_effort_command_and_refuses_others() -> None:
    log, clock = Log(), Clock()
    held = HeldEffort(["a", "b"], "effort_controller/commands", log, clock)
    held.offer([1.0, -2.0])
    held.offer([1.0])
    held.offer([1.0, float("nan")])
    assert np.array_equal(held.command, [1.0, -2.0]) and held.commands == 1
    assert log.reports == [
        ("error", "length", "effort_controller/commands refused: 1 values for 2 joints (joints ['a', 'b'])"),
        (
            "error",
            "non-finite",
            "effort_controller/commands refused: non-finite value at index 1 (nan) (joints ['a', 'b'])",
        ),
    ]


def test_a_mujoco_step_waits_for_the_answer_at_most_effort_wait_s() -> None:
    log, clock = Log(), Clock()
    held = HeldEffort(["a"], "effort_controller/commands", log, clock)
    waits: list[float] = []

    def silent(timeout_s: float) -> None:
        waits.append(timeout_s)
        clock.now += min(timeout_s, 0.02)  # a wait that ends early (another message came), then the rest

    started = clock.now
    held.wait_for_answer(silent)
    assert clock.now - started == pytest.approx(EFFORT_WAIT_S)
    assert waits == pytest.approx([0.05, 0.03, 0.01])
    started = clock.now
    held.wait_for_answer(lambda timeout_s: held.offer([3.0]))  # an answer at once: no further wait
    assert clock.now == started and held.command[0] == 3.0


def test_periodic_says_due_once_per_period() -> None:
    clock = Clock()
    due = Periodic(0.5, clock).due
    seen = []
    for _ in range(12):
        seen.append(due())
        clock.now += 0.125  # exact in binary: the period's end is hit, not missed by rounding
    assert seen == [True, False, False, False] * 3
