"""The simulator node's stepping policy, without ROS: which command a step takes, what is refused and
taken back, the watchdog, the warnings, the real-time pace and the run's end.

Lockstep (``stepping: lockstep``): state k goes out; the step waits for the command stamped with state
k's stamp (``offer`` refuses any other stamp), takes the first such command whose step is finite, and
takes back (``Simulator.restore``) a step it refuses; with no acceptable command within
``command_timeout`` the watchdog applies its policy (``hold``: the last applied command; else zero).
Real time (``real_time``, ``free_run``): each ``tick`` steps with the latest command, zero once it is
older than ``command_timeout``. Each step's state and reports go out through a ``StepOutlet`` (the
node's publishers), each word about the run through a ``NodeLog``; the wall clock is injected.
``reset`` (the node's reset_simulation service) takes the run back to its initial state, with the
parameters as they are.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np

import bracing_engine as engine
from bracing_core.checks import REAL_TIME_ACHIEVED
from bracing_core.config import Plant, SimulatorConfig
from bracing_core.drive import CurrentLoopDrive, DriveGains
from bracing_core.dynamics import InputMode
from bracing_core.link_penetration import LinkDepth, LinkPenetration
from bracing_core.node_log import NodeLog
from bracing_core.numbers import all_finite
from bracing_core.simulator import DivergenceError, Energy, Simulator
from bracing_core.types import Mask, Vector
from bracing_core.watch import RunWatch

PROGRESS_PERIOD_S = 0.5
"""[s] wall between two progress lines (and run_status PROGRESS)."""
WATCH_EVERY = 100
"""States handed to the run's watch at once: its checks are vectorised over states (the rollout hands it
a whole run), and one state at a time cost the simulator node ~25 us a step (py-spy: 9 % of
its samples). A warning comes at most this many states later, with the time it is about."""
EFFORT_WAIT_S = 0.05
"""[s] wall: the longest a MuJoCo step waits for the controller's answer to the last state (``HeldEffort``)."""


class Periodic:
    """Whether ``period`` [s] of ``clock`` has passed since it last said so (the first time: yes)."""

    def __init__(self, period: float, clock: Callable[[], float]) -> None:
        self.period, self.clock = period, clock
        self._next = 0.0

    def due(self) -> bool:
        now = self.clock()
        if now < self._next:
            return False
        self._next = now + self.period
        return True


@dataclass(frozen=True)
class StateOut:
    """One state as joint_states carries it: the truth, and what the sensors measured (None: exact)."""

    t_ns: int
    position: Vector
    velocity: Vector
    effort: Vector  # link-side motor torque under the held command
    measured: tuple[Vector, Vector] | None  # (position, velocity) as measured
    links: list[LinkDepth] | None = None  # robot.collision_geometry: the link deepest into each surface


@dataclass(frozen=True)
class StepOut:
    """A step's reports: forces at its start under the held command (``contacts``, one wrench per
    configured contact, as measured), the motors (``motor_state``: energies and the windings'
    temperatures up to its start)."""

    t_ns: int
    forces: engine.Answer
    active: np.ndarray  # (p,) bool: which contacts hold a force
    wrenches: list[Vector]  # each configured contact's force on the robot [N], as measured
    voltage: Vector
    current: Vector  # as measured
    true_current: Vector  # the truth (ground_truth/motor_state)
    power: Vector
    energies: tuple[float, float, float]  # consumed, net, copper loss [J]
    temperature: Vector  # empty without the thermal model


class StepOutlet(Protocol):
    """Where a step's messages go (the node's publishers)."""

    def publish_state(self, state: StateOut) -> None: ...

    def publish_step(self, step: StepOut) -> None: ...

    def sent(self) -> None:
        """A step's messages are out (flow control)."""

    def progress(self, t: float) -> None:
        """Say (run_status) that the run is at sim time ``t``."""


def joint_command_drive(config: SimulatorConfig, plant: Plant) -> CurrentLoopDrive | None:
    """command_source joint_commands in voltage mode: the current loop that turns efforts into voltages."""
    if config.command_source != "joint_commands" or config.shared.input_mode is not InputMode.VOLTAGE:
        return None
    motors, drive = plant.motors, config.motor_drive
    gains = DriveGains.from_bandwidth(
        drive.bandwidth,
        motors.inductance,
        motors.resistance,
        plant.to_model_order(drive.kp) if drive.kp else (),
        plant.to_model_order(drive.ki) if drive.ki else (),
    )
    return CurrentLoopDrive(gains, motors.reflected_constant, motors.voltage_limit)


def limit_text(limit: Vector, joint_names: Sequence[str]) -> str:
    """Per-joint command limits as a warning names them: +/-value when every joint has the same one."""
    if np.all(limit == limit[0]):
        return f"+/-{float(limit[0])}"
    return (
        "each joint's limit ("
        + ", ".join(f"{n} +/-{float(v)}" for n, v in zip(joint_names, limit, strict=False) if v > 0)
        + ")"
    )


class SimulatorStepper:
    """The simulator node's stepping (see the module docstring). ``clock``: wall time [s], monotonic."""

    def __init__(
        self,
        config: SimulatorConfig,
        plant: Plant,
        sim: Simulator,
        log: NodeLog,
        outlet: StepOutlet,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.log, self.outlet, self.clock = log, outlet, clock
        self.state_out_yet = False  # whether a state has gone out (a reset then sends the initial one)
        self.abandoned_ns: int | None = None  # the stamp a reset stopped waiting for (its answer dropped quietly)
        self._build(config, plant, sim)

    def _build(self, config: SimulatorConfig, plant: Plant, sim: Simulator) -> None:
        """What a run's configuration, plant and simulator give the stepping (``__init__``, and ``reset`` to a
        configuration rebuilt from changed per-run parameters), the run at its start."""
        self.config, self.plant, self.sim = config, plant, sim
        self.mode = config.shared.input_mode
        self.limit = plant.command_limit  # per joint, model order (0: none)
        self.step_ns = sim.step_ns
        self.total_steps = round(config.duration / config.step) if config.duration > 0 else None
        self.initial = sim.checkpoint()  # where reset_simulation goes back to
        self._begin_run()
        # joint_commands: the limit each joint's efforts are saturated to (0: none; the drive: its voltage limit)
        self.effort_limit: Vector = plant.motors.torque_limit if self.drive is None else np.zeros(sim.n)
        self.wrench_count = len(config.shared.contacts)  # the configured contacts, first in the contact set

    def _begin_run(self) -> None:
        """Everything that a run changes, as it is at the run's start (``__init__``, ``reset``)."""
        config, plant, sim, clock = self.config, self.plant, self.sim, self.clock
        # What the controller receives, as a real arm measures it (sensors.*); None: exact.
        sensing = config.sensors
        self.sensors = None if sensing.exact else sensing.engine(config.step, plant.robot.prismatic.tolist())
        self.drive = joint_command_drive(config, plant)
        self.command = np.zeros(sim.n)  # last applied (held) command
        self.pending: dict[int, Vector] = {}  # lockstep: valid commands by stamp [ns]
        self.latest_command: tuple[float, Vector] | None = None  # real-time: (wall time, command)
        self.max_residual = 0.0  # [m], over the run so far (contacts holding a force)
        self.refusal = ""  # why the last refused step was refused
        self.real_time_achieved = math.nan  # real-time stepping: sim time / wall time, once finished
        self.progress_due = Periodic(PROGRESS_PERIOD_S, clock).due  # a progress line
        self._events_logged = 0
        self._started = 0.0  # wall time real-time stepping started
        # What the run should be warned about (the in-process rollout says the same).
        self.watch = RunWatch(plant, config, sim)
        # robot.collision_geometry: every link's shapes against the surfaces at each state out
        self.links = LinkPenetration(plant, sim.dynamics.engine) if config.shared.collision_geometry else None
        self._watched: list[tuple[float, Mask, Vector, Vector]] = []  # states not yet handed to the watch

    # -- the run's start and end --------------------------------------------------------
    def start_lines(self) -> list[str]:
        """What the log says of the run before it starts."""
        config, sim = self.config, self.sim
        lines = [
            f"{self.mode.value} input, {len(self.plant.contact_set)} contact(s), step {config.step} s, "
            f"{config.stepping}, duration {config.duration or 'unbounded'} s"
        ]
        if sim.substeps > config.substeps:
            lines.append(f"stiff motor circuits: {sim.substeps} RK4 sub-steps per step (substeps {config.substeps})")
        if config.initial_current == "steady" and self.mode is InputMode.VOLTAGE:
            lines.append("initial_current: steady: the windings start at the first command's steady current")
        if config.project_initial_position:
            given = self.plant.to_model_order(config.initial_position)
            projected = dict(zip(self.plant.joint_names, sim.position.round(9).tolist(), strict=True))
            moved = float(np.max(np.abs(sim.position - given)))
            lines.append(f"initial position projected onto the contacts: {projected} (moved {moved:.3g} at most)")
        return lines

    def reset(self, rebuilt: tuple[SimulatorConfig, Plant, Simulator] | None = None) -> None:
        """Back to the run's initial state (reset_simulation), with the parameters as they are: the engine's
        state (q, dq, the windings' currents and temperatures, the energy integrals), its contact modes and
        events, the step count (the sim clock: the next state is stamped as the first was), the held and
        pending commands, the sensors' filters and noise, the current loop and the run's watch. ``rebuilt``:
        the configuration, plant and simulator a fresh process builds from the parameters as they are now (a
        per-run one changed), the next run's instead of this one's. A state already out is sent again from the
        start (the controller sees its time go back); the answer to the state waited for is dropped without a
        word. Real time: the pace starts again now."""
        self.abandoned_ns = self.now_ns
        if rebuilt is None:
            self.sim.restore(self.initial)
            self._begin_run()
        else:
            self._build(*rebuilt)
        self._started = self.clock()
        self.log.info(f"reset_simulation: back to the initial state at t = {self.sim.time:.6f} s")
        if self.state_out_yet:
            self.send_state()

    def done(self) -> bool:
        return self.total_steps is not None and self.sim.steps_taken >= self.total_steps

    @property
    def now_ns(self) -> int:
        """The current state's stamp [ns]."""
        return self.sim.now_ns

    def progress_line(self) -> str:
        return f"progress t={self.sim.time:.3f} max_residual={self.max_residual:.3e}"

    def send_state(self) -> None:
        """The current state under the held command (the run's first)."""
        self.state_out_yet = True
        self.outlet.publish_state(self.state_out(self.state_effort()))

    def finish(self, command: Vector | None = None) -> None:
        """Report the final state (under ``command``, the answer to it if there is one, else the held
        command), and say the run's last warnings (before FINISHED: the recorder has them then)."""
        t_ns = self.now_ns
        if command is not None and self.sensors is not None:
            command = self.sensors.delay(command)
        d = self.sim.evaluate(command) if command is not None else None
        if d is None or not all_finite(d.normal_force, d.friction_force, d.effort):
            if command is not None:
                self.refusal = "non-finite forces or effort at the final state"
                self.refuse(command)
            d = self.sim.evaluate(self.command)
        else:
            self.command = command  # type: ignore[assignment]  # not None here
        sim = self.sim
        self.outlet.publish_step(self.step_out(t_ns, self.command, d, sim.current, sim.temperature, sim.energy))
        self._watch_state(t_ns, d)
        self._hand_to_watch()
        self.say(self.watch.finish())

    # -- warnings -------------------------------------------------------------------
    def say(self, warnings: list[str]) -> None:
        self.log.say(warnings, self.sim.time)

    def warn_first(self, kind: str, message: str) -> None:
        """A warning the log repeats (rate-limited per kind): the first of its kind is said in full
        (``say``: on run_status too), the rest are counted by the log."""
        first = self.watch.once(kind, message, self.sim.time)
        if first:
            self.say(first)
            self.log.mark(kind)  # the limiter counts on from this one
        else:
            self.log.limited("warning", kind, message)

    @property
    def command_topic(self) -> str:
        """Where the commands come from: motor_command, or joint_commands_topic (command_source)."""
        config = self.config
        return "motor_command" if config.command_source == "motor_command" else config.joint_commands_topic

    def refuse(self, command: Vector) -> None:
        """Say that ``command`` (from ``command_topic``) was refused because its step is not finite,
        naming its largest value (with the drive: the voltage its current loop set for the effort)."""
        j = int(np.argmax(np.abs(command)))
        unit = "V" if self.mode is InputMode.VOLTAGE else "N m"
        value = f"{self.plant.joint_names[j]} = {command[j]:.6g} {unit}"
        if self.drive is not None:
            value = f"the current loop's voltage for its efforts: {value}"
        self.log.limited(
            "error",
            "absurd",
            f"{self.command_topic} rejected: its step at t = {self.sim.time:.6f} s would not be finite "
            f"({value}; {self.refusal}); the state is kept",
        )

    # -- commands -------------------------------------------------------------------
    def offer(self, stamp_ns: int, command: Vector, saturated: bool) -> None:
        """A valid motor_command (joint order, saturated to ``limit``): lockstep keeps it for the state
        it answers and refuses any other stamp; real time keeps the latest."""
        now_ns = self.now_ns
        if stamp_ns == self.abandoned_ns and stamp_ns != now_ns:
            return  # the answer to the state a reset stopped waiting for
        if self.config.stepping == "lockstep" and stamp_ns != now_ns:
            age = "stale" if stamp_ns < now_ns else "from the future"
            self.log.limited(
                "error",
                age,
                f"motor_command rejected: stamp {stamp_ns * 1e-9:.6f} s is {age} (waiting for {now_ns * 1e-9:.6f} s)",
            )
            return
        if saturated:  # said only of a command that is applied
            self.warn_first("saturated", f"motor_command saturated to {limit_text(self.limit, self.plant.joint_names)}")
        if self.config.stepping == "lockstep":
            self.pending[stamp_ns] = command
        else:  # real_time and free_run hold the latest
            self.latest_command = (self.clock(), command)

    def offer_effort(self, command: Vector, saturated: bool) -> None:
        """A valid joint_commands effort command [N m or N, link side] (real time: held)."""
        if saturated:
            self.log.limited(
                "warning",
                "saturated",
                f"{self.config.joint_commands_topic} saturated to "
                f"{limit_text(self.effort_limit, self.plant.joint_names)}",
            )
        self.latest_command = (self.clock(), command)

    # -- one step -------------------------------------------------------------------
    def advance(self, command: Vector) -> bool:
        """Step with ``command`` held (or, with sensors.command_latency_steps, the answer that many
        states old), send the new state, then the step's reports.

        The new state goes out first: the controller computes its answer while the reports of the
        step just taken are built and sent. A command whose step is not finite (the state, the
        energies, or the model at the new state: a finite but absurd value such as 1e300 V), or that
        takes a held contact further than divergence_residual off its surface, is refused: the step
        is taken back, nothing is sent, ``refusal`` says why, and False is returned.
        """
        sim = self.sim
        t_ns = self.now_ns
        command = self.sensors.delay(command) if self.sensors is not None else command
        try:
            step = self._advance(command)  # in the engine: an overflow is reported as a refusal
        except DivergenceError as exc:
            if self.sensors is not None:
                self.sensors.take_back()
            self.refusal = str(exc)
            return False
        self.command = command
        self.max_residual = max(self.max_residual, step.measured)
        self.outlet.publish_state(self.state_out(step.effort))
        answer, energy = step.answer, Energy(*step.energy.tolist())  # a kept step has its answer
        assert answer is not None
        self.outlet.publish_step(self.step_out(t_ns, command, answer, step.current, step.temperature, energy))
        self.outlet.sent()
        self._take_events()
        self._watch_state(t_ns, answer)
        if self.progress_due():
            self.log.info(self.progress_line())
            self.outlet.progress(sim.time)
        return True

    def _advance(self, command: Vector) -> engine.Advance:
        """The step with ``command`` as the node judges it, in one engine call (``Simulator.advance``): taken back
        and DivergenceError if refused."""
        config = self.config
        return self.sim.advance(
            command, config.divergence_speed, config.divergence_residual, self.mode is InputMode.VOLTAGE
        )

    def _take_events(self) -> None:
        """Log the contact events of the step just taken (not Coulomb friction's) and give them to the watch."""
        events = self.sim.events[self._events_logged :]
        for event in events:
            kind = event.kind
            extra = f", {event.energy_loss:.4g} J lost in the impact" if kind is engine.EventKind.touchdown else ""
            if kind in (engine.EventKind.stick, engine.EventKind.slip):  # Coulomb friction: frequent, and not news
                continue
            self.log.info(f"contact {event.contact!r}: {kind.name} at t = {event.time:.6f} s{extra}")
        self._events_logged = len(self.sim.events)
        self.watch.events(events)

    def _watch_state(self, t_ns: int, d: engine.Answer) -> None:
        """Keep the state a step's reports described (as ``contacts`` has it) for the watch (``WATCH_EVERY``)."""
        self._watched.append((t_ns * 1e-9, d.held, d.normal_force, d.residual))
        if len(self._watched) >= WATCH_EVERY:
            self._hand_to_watch()

    def _hand_to_watch(self) -> None:
        """The states kept, to the watch at once; say its warnings."""
        if not self._watched:
            return
        times, active, normal_force, residual = (np.array(column) for column in zip(*self._watched, strict=True))
        self._watched = []
        self.say(self.watch.states(times, active, normal_force, residual))

    def state_effort(self, command: Vector | None = None) -> Vector:
        """JointState.effort under ``command`` (default: the held one): the link-side motor torque
        (the command itself in torque mode)."""
        command = self.command if command is None else command
        if self.mode is InputMode.TORQUE:
            return command
        return self.sim.evaluate(command).effort

    # -- what goes out --------------------------------------------------------------
    def state_out(self, effort: Vector) -> StateOut:
        """The current state; with sensors, once per state and in order (the velocity filter and the noise advance)."""
        position, velocity = self.sim.position, self.sim.velocity
        measured = self.sensors.joints(position, velocity) if self.sensors is not None else None
        links = None
        if self.links is not None:
            links, warnings = self.links.measure(position, self.sim.time)
            self.say(warnings)
        return StateOut(self.now_ns, position, velocity, effort, measured, links)

    def step_out(
        self, t_ns: int, command: Vector, d: engine.Answer, current: Vector, temperature: Vector, energy: Energy
    ) -> StepOut:
        """Reports of one step: forces at its start under the held command, energies and the windings'
        temperatures up to its start (the sensors' noise drawn in the order the topics go out)."""
        sensors = self.sensors
        wrenches = []
        for j in range(min(d.contact_count, self.wrench_count)):
            force = float(d.normal_force[j]) * d.normals[j] + d.tangential_force[j]
            wrenches.append(sensors.force(force, d.normals[j]) if sensors is not None else force)
        n = self.sim.n
        if self.mode is InputMode.VOLTAGE:
            voltage, power = command, command * current
        else:  # direct drive: no circuit; mechanical power tau dq
            voltage, current, power = np.zeros(n), np.zeros(n), command * self.sim.velocity
        if not self.sim.dynamics.thermal:
            temperature = np.zeros(0)  # no thermal model: empty, not a made-up ambient
        measured = current
        if sensors is not None and self.mode is InputMode.VOLTAGE:
            measured = sensors.currents(current)
        energies = (energy.consumed, energy.net, energy.copper_loss)
        return StepOut(t_ns, d, d.held, wrenches, voltage, measured, current, power, energies, temperature)

    # -- lockstep -------------------------------------------------------------------
    def next_command(self, receive: Callable[[float], None], deadline: float) -> Vector | None:
        """The next valid command stamped with the current state's stamp, or None at ``deadline``
        (wall). ``receive(timeout)`` takes the commands that come within ``timeout`` [s] to ``offer``."""
        expected = self.now_ns
        while expected not in self.pending:
            remaining = deadline - self.clock()
            if remaining <= 0.0:
                return None
            receive(min(remaining, 0.1))
        command = self.pending.pop(expected)
        self.pending.clear()
        return command

    def step_lockstep(self, receive: Callable[[float], None]) -> None:
        """One step with the answer to the current state: the first valid command stamped with its
        stamp whose step is finite; the watchdog's choice if none comes within command_timeout.
        Raises DivergenceError if even that step is not finite (the model, not the input)."""
        deadline = self.clock() + self.config.command_timeout
        while (command := self.next_command(receive, deadline)) is not None:
            if self.advance(command):
                return
            self.refuse(command)
            if self.runs_away_anyway():  # no command can save it: stop now, not after the watchdog's wait
                raise DivergenceError(f"{self.refusal} (under the command and under the watchdog's too)")
        if not self.advance(self.watchdog_command()):
            raise DivergenceError(f"{self.refusal} (under the watchdog's command: {self.config.watchdog_policy})")

    def runs_away_anyway(self) -> bool:
        """Whether the watchdog's command (the held one or zero, ``watchdog_policy``) is refused too: the state
        runs away under any command, so waiting ``command_timeout`` for another one only delays the error
        (and keeps the recorder from the last states). Tried and taken back; ``refusal`` is kept."""
        sim, refusal = self.sim, self.refusal
        command = self.command if self.config.watchdog_policy == "hold" else np.zeros(sim.n)
        checkpoint = sim.checkpoint()
        try:
            self._advance(self.sensors.delay(command) if self.sensors is not None else command)
            finite = True
        except (DivergenceError, np.linalg.LinAlgError):
            finite = False
        finally:
            sim.restore(checkpoint)
            if self.sensors is not None:
                self.sensors.take_back()
        self.refusal = refusal
        return not finite

    def finish_lockstep(self, receive: Callable[[float], None]) -> None:
        """The run's end: the final state's reports under the answer to it (if it comes in time)."""
        self.finish(self.next_command(receive, self.clock() + self.config.command_timeout))

    def watchdog_command(self) -> Vector:
        """What the watchdog applies when no valid command came in time, after saying so."""
        config = self.config
        policy = config.watchdog_policy
        self.warn_first(
            "watchdog",
            f"no valid motor_command for t = {self.now_ns * 1e-9:.6f} s within {config.command_timeout} s: "
            f"{'holding the last command' if policy == 'hold' else 'applying zero'}",
        )
        return self.command if policy == "hold" else np.zeros(self.sim.n)

    # -- real time ------------------------------------------------------------------
    @property
    def period(self) -> float | None:
        """[s] wall between two real-time steps; None: free_run, as fast as it can."""
        config = self.config
        return None if config.stepping == "free_run" else config.step / config.real_time_factor

    def start_real_time(self) -> None:
        """The first state out; the wall clock of the pace starts."""
        self.send_state()
        self._started = self.clock()

    def tick(self) -> None:
        """One real-time step with the latest command (zero once stale); a refused one is taken back and
        the step taken with zero instead (the refused command is never used again)."""
        if self.done():
            return
        command = self._applied(self._real_time_request())
        if not self.advance(command):
            self.refuse(command)
            self.latest_command = None  # never again: a stale command becomes zero
            if not self.advance(self._applied(np.zeros(self.sim.n))):
                raise DivergenceError(f"{self.refusal} (under a zero command)")
        if self.drive is not None:
            self.drive.commit()

    def _real_time_request(self) -> Vector:
        """The latest command, or zero (after saying so) once it is older than command_timeout."""
        config, latest = self.config, self.latest_command
        if latest is not None and self.clock() - latest[0] <= config.command_timeout:
            return latest[1]
        if latest is not None:
            self.warn_first("watchdog", f"{self.command_topic} stale: applying zero")
        return np.zeros(self.sim.n)

    def _applied(self, request: Vector) -> Vector:
        """What the plant gets for a held request: the request itself, or with the drive (joint_commands
        in voltage mode) the voltage its current loop sets for this step."""
        if self.drive is None:
            return request
        return self.drive.voltage(request, self.sim.current, self.sim.velocity, self.config.step)

    def finish_real_time(self) -> None:
        """The run's end: say how fast it went (in the log; to bracing-pair in FINISHED, ``real_time_achieved``),
        warn if slower than asked (a timer whose ticks run late skips them: the sim time lags the wall
        clock), then ``finish``."""
        wall_s = self.clock() - self._started
        achieved = self.sim.time / wall_s if wall_s > 0.0 else float("inf")
        self.real_time_achieved = achieved
        asked = self.config.real_time_factor
        self.log.info(f"{REAL_TIME_ACHIEVED}{achieved:.4f}x real time (asked {asked:g}x)")
        self._hand_to_watch()  # the states' warnings before the pace's, in time order
        if self.config.stepping == "real_time":  # free_run asks for no pace
            self.say(self.watch.real_time(achieved, asked))
        self.finish()


class HeldEffort:
    """The MuJoCo robot's commands, as a mujoco_ros2_control robot with a JointGroupEffortController
    takes them: one effort per joint (``joints`` order) held until a valid one replaces it (a wrong
    length or a non-finite value refused, rate-limited); and its loop's wait: each state waits for the
    controller's answer, at most ``EFFORT_WAIT_S`` (then the held command), so a slow machine slows the
    run down instead of starving the controller."""

    def __init__(self, joints: Sequence[str], topic: str, log: NodeLog, clock: Callable[[], float] = time.monotonic):
        self.joints, self.topic, self.log, self.clock = list(joints), topic, log, clock
        self.command = np.zeros(len(self.joints))  # held until a valid one replaces it
        self.commands = 0  # valid commands taken so far

    def offer(self, values: Sequence[float] | Vector) -> None:
        """A Float64MultiArray's values: held, or refused with the reason."""
        n = len(self.joints)
        problem = None
        if len(values) != n:
            problem, kind = f"{len(values)} values for {n} joints", "length"
        elif bad := [i for i, v in enumerate(values) if not math.isfinite(v)]:
            problem, kind = f"non-finite value at index {bad[0]} ({values[bad[0]]})", "non-finite"
        if problem is not None:
            self.log.limited("error", kind, f"{self.topic} refused: {problem} (joints {self.joints})")
            return
        self.command = np.array(values, dtype=float)
        self.commands += 1

    def wait_for_answer(self, receive: Callable[[float], None]) -> None:
        """Until a command has come since this call began, or EFFORT_WAIT_S of wall time;
        ``receive(timeout)`` takes what comes within ``timeout`` [s] (to ``offer``)."""
        seen, deadline = self.commands, self.clock() + EFFORT_WAIT_S
        while self.commands == seen and self.clock() < deadline:
            receive(max(0.0, deadline - self.clock()))
