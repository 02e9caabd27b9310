"""Time integration of the constrained dynamics: classic RK4 with the input held.

The state is (q, dq, i, T: the motor windings' temperatures) plus running energy integrals, integrated together so the
integrals are as accurate as the trajectory. ``Simulator.step(command)`` advances one
configured step (optionally in sub-steps) and returns the model's answer at the start
of the step, which is what the simulator reports for that step (forces, effort).

The stepping runs in the compiled engine (``bracing_engine.Simulator``): the four stages,
the energy integrals, unilateral contacts releasing at a step's start and landing at its
end (inelastic impact), the joint-limit stop and the divergence check. This class checks
the input and raises the errors; its answers are the engine's ``Answer``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

import bracing_engine as engine
from bracing_core.dynamics import ConstrainedDynamics
from bracing_core.types import EngineField, Vector, as_vector

ENERGY_KEYS = tuple(slot.name for slot in engine.EnergySlot)
WINDING_TEMPERATURE_LIMIT: float = engine.WINDING_TEMPERATURE_LIMIT  # [degC] (copper melts at 1085 degC)


def _refusal_reason(
    refusal: engine.Refusal, measured: float, divergence_speed: float, divergence_residual: float
) -> str:
    """Why the simulator node refuses a step (``bracing_engine.Refusal``: after it, in the rollout and
    ``Simulator.check``)."""
    if refusal is engine.Refusal.too_fast:
        return f"joint speed exceeds divergence_speed {divergence_speed}: {measured:.3g}"
    if refusal is engine.Refusal.too_hot:
        return f"a motor winding would reach {measured:.3g} degC, beyond {WINDING_TEMPERATURE_LIMIT:g} degC (it burns)"
    if refusal is engine.Refusal.off_surface:
        return f"constraint residual {measured:.3g} m exceeds divergence_residual {divergence_residual} m"
    return "non-finite forces or effort"


class DivergenceError(RuntimeError):
    """The integration produced a non-finite state; the state was left as it was."""


class JointLimitError(DivergenceError):
    """A step would take a joint past its URDF position limit; the state was left as it was."""


@dataclass(frozen=True)
class Energy:
    """Energy integrals since the start [J].

    consumed = int sum |v i| dt, net = int sum v i dt, copper_loss = int sum R(T) i^2 dt
    (voltage mode; torque mode uses the mechanical power tau dq and no copper loss);
    viscous_loss = int dq^T Dc dq dt, friction_loss = int sum mu f_n (dir . slip) dt,
    constraint_work = int f_n . (J_c dq) dt (zero for an ideal, satisfied constraint),
    impact_loss = kinetic energy taken by inelastic touchdowns of unilateral contacts.
    """

    consumed: float
    net: float
    copper_loss: float
    viscous_loss: float
    friction_loss: float
    constraint_work: float
    impact_loss: float = 0.0


@dataclass(frozen=True)
class Checkpoint:
    """A copy of the simulator's state (see :meth:`Simulator.checkpoint`)."""

    state: engine.State  # q, dq, i, T and the energy integrals
    steps_taken: int
    active: np.ndarray  # which contacts hold a force
    events: int  # length of the event log
    modes: engine.ContactModes  # the engine's contact modes (held, sticking, slide direction, sign of f_n)


class Simulator:
    """Integrates one ConstrainedDynamics from an initial state with a fixed step."""

    def __init__(
        self,
        dynamics: ConstrainedDynamics,
        step: float,
        initial_position: Vector,
        initial_velocity: Vector | None = None,
        substeps: int = 1,
    ) -> None:
        n = dynamics.n
        if not (np.isfinite(step) and step > 0.0):
            raise ValueError(f"step: must be > 0 seconds, got {step}")
        if int(substeps) != substeps or substeps < 1:
            raise ValueError(f"substeps: must be an integer >= 1, got {substeps}")
        q0 = np.asarray(initial_position, dtype=float)
        dq0 = np.zeros(n) if initial_velocity is None else np.asarray(initial_velocity, dtype=float)
        for name, value in (("initial_position", q0), ("initial_velocity", dq0)):
            if value.shape != (n,) or not np.all(np.isfinite(value)):
                raise ValueError(f"{name}: expected {n} finite values, got {np.ravel(value).tolist()}")
        robot = dynamics.robot
        outside = np.flatnonzero((q0 < robot.lower_limits) | (q0 > robot.upper_limits))
        if outside.size:
            j = int(outside[0])
            raise ValueError(
                f"initial_position: joint {robot.joint_names[j]!r} at {q0[j]:.6g} is outside its URDF limits "
                f"[{robot.lower_limits[j]:g}, {robot.upper_limits[j]:g}]"
            )
        self.dynamics = dynamics
        self.full_dynamics = dynamics  # kept for callers of the former API: the engine holds every contact
        contacts = dynamics.contacts.contacts
        self._names = [c.name for c in contacts]
        self._unilateral = np.array([c.unilateral for c in contacts], dtype=bool)
        self._enforced = np.array([c.enforced for c in contacts], dtype=bool)
        self.step_size = float(step)
        self.substeps = int(substeps)
        self.n = n
        self.t0_ns = 0  # [ns] the stamp of the state before the first step
        self.events: list[engine.ContactEvent] = []
        self.engine = engine.Simulator(  # the compiled integrator (public: a rollout steps it)
            dynamics.engine, self.step_size, self.substeps, q0, dq0, robot.lower_limits, robot.upper_limits
        )

    # -- state ------------------------------------------------------------------------
    steps_taken = EngineField(int)
    step_ns = EngineField(int)  # [ns] what each step adds to the state's stamp
    position = EngineField(as_vector)  # q [rad or m]
    velocity = EngineField(as_vector)  # dq [rad/s or m/s]
    current = EngineField(as_vector)  # i [A] (zeros in torque mode)
    temperature = EngineField(as_vector)  # the windings' T [degC] (ambient throughout without the thermal model)

    @property
    def now_ns(self) -> int:
        """[ns] the current state's stamp (the simulator node's joint_states stamp)."""
        return self.t0_ns + self.steps_taken * self.step_ns

    @property
    def time(self) -> float:
        """[s] the current state's time: its stamp as the controller node reads it (``engine.stamp_seconds``)."""
        return engine.stamp_seconds(self.now_ns)

    @property
    def energy(self) -> Energy:
        return Energy(*self.engine.energy.tolist())

    @property
    def active(self) -> np.ndarray:
        """(p,) bool: the contacts holding a force now."""
        return np.array(self.engine.active, dtype=bool)

    @property
    def sticking(self) -> np.ndarray:
        """(p,) bool: the Coulomb contacts that stick now (their tangential motion held)."""
        return np.array(self.engine.modes.sticking, dtype=bool)

    # -- model answers ----------------------------------------------------------------
    def evaluate(self, command: Vector) -> engine.Answer:
        """The model at the current state under ``command`` (no time passes)."""
        try:
            return self.engine.evaluate(np.asarray(command, dtype=float))
        except engine.SingularError as exc:
            raise np.linalg.LinAlgError(str(exc)) from None

    # -- checkpoints --------------------------------------------------------------------
    def checkpoint(self) -> Checkpoint:
        """The state as it is now, for :meth:`restore` (e.g. to take back a step whose result
        the caller refuses)."""
        return Checkpoint(self.engine.state, self.steps_taken, self.active, len(self.events), self.engine.modes)

    def restore(self, checkpoint: Checkpoint) -> None:
        """Back to ``checkpoint``: state, step count, released contacts and event log."""
        self.engine.set_state(checkpoint.state)
        self.steps_taken = checkpoint.steps_taken
        del self.events[checkpoint.events :]
        self.engine.truncate_events(checkpoint.events)
        self.engine.set_modes(checkpoint.modes)

    # -- integration ------------------------------------------------------------------
    def step(self, command: Vector) -> engine.Answer:
        """Advance one step with ``command`` held (zero-order hold); RK4 per sub-step.

        Returns the model's answer at the start of the step. Raises ValueError for a
        command of the wrong shape or with non-finite values, DivergenceError if the new
        state is not finite; in both cases the state is unchanged.
        """
        u = self._command(command)
        time = self.time
        try:
            result = self.engine.step(u)
        except engine.SingularError as exc:
            raise np.linalg.LinAlgError(str(exc)) from None
        finally:
            if self.engine.event_count != len(self.events):
                self._take_events()
        self._raise_for(result.status, time)
        assert result.answer is not None  # a step taken (ok) has its answer
        return result.answer

    def advance(
        self, command: Vector, divergence_speed: float, divergence_residual: float, evaluate_effort: bool
    ) -> engine.Advance:
        """The simulator node's step (``step``, then ``check``, then the new state's effort: the model's under
        ``command`` if ``evaluate_effort``, else the command), in one engine call
        (``bracing_engine.Simulator.advance``). Raises as ``step`` and ``check`` do, and DivergenceError for a
        non-finite effort; the state is then as it was before the step (as ``restore`` takes it back). Kept: the
        engine's ``Advance`` (its answer, effort, the largest held |C| as ``measured``, the currents, temperatures
        and energies at the step's start)."""
        u = np.asarray(command, dtype=float)
        if u.ndim != 1:
            self._command(u)  # raises its ValueError
        try:
            result = self.engine.advance(u, divergence_speed, divergence_residual, evaluate_effort)
        except engine.SingularError as exc:
            raise np.linalg.LinAlgError(str(exc)) from None
        finally:
            if self.engine.event_count != len(self.events):
                self._take_events()
        if not result.command_taken:  # the engine checks it: no u . u overflows here
            with np.errstate(over="ignore", invalid="ignore"):
                self._command(u)  # raises its ValueError
        if result.status is not engine.StepStatus.ok:  # taken back: the time is the step's start
            self._raise_for(result.status, self.time)
        if result.refusal is not engine.Refusal.none:
            reason = _refusal_reason(result.refusal, result.measured, divergence_speed, divergence_residual)
            raise DivergenceError(reason)
        return result

    def _command(self, command: Vector) -> Vector:
        """``command`` as the step holds it, or ValueError for one of the wrong shape or with non-finite values."""
        u = np.asarray(command, dtype=float)
        # A finite u . u means every entry is finite; otherwise check exactly (u . u may overflow).
        if u.shape != (self.n,) or (not math.isfinite(u.dot(u)) and not np.isfinite(u).all()):
            raise ValueError(f"command: expected {self.n} finite values, got {np.ravel(u).tolist()}")
        return u

    def rollout(
        self,
        law: engine.Law,
        steps: int,
        divergence_speed: float = np.inf,
        divergence_residual: float = np.inf,
        sensors: engine.Sensors | None = None,
        command_limit: Vector | None = None,
        keep_failure: bool = False,
        out: engine.Recording | None = None,
    ) -> engine.Recording:
        """The closed loop with ``law`` (a ``bracing_engine.Law``) for ``steps`` steps, in the engine:
        per state k = 0..steps what the nodes publish in lockstep (``bracing_engine.rollout``; the
        last state answered and evaluated without a step). Raises as ``step`` does, and
        DivergenceError where the simulator node would refuse a step (speed above
        ``divergence_speed`` [rad/s], a held contact further than ``divergence_residual`` [m] off);
        with ``keep_failure`` it returns what it recorded up to such a failure instead (``rollout_error``
        says why it stopped; its arrays are cut to the rows filled).
        ``sensors``: what the law reads and when its commands land (None: exact and instant). ``command_limit``:
        each joint's |command| saturation (model order, 0: none), as the simulator node applies it. ``out``:
        a fresh Recording to fill (``rollout.RunResult``; None: a new one)."""
        limit = np.zeros(0) if command_limit is None else np.asarray(command_limit, dtype=float)
        out = engine.Recording() if out is None else out
        try:
            engine.rollout(
                law, self.engine, int(steps), self.t0_ns, divergence_speed, divergence_residual, out, sensors, limit
            )
        except engine.SingularError as exc:
            raise np.linalg.LinAlgError(str(exc)) from None
        finally:
            self._take_events()
        error = None if keep_failure else self.rollout_error(out, divergence_speed, divergence_residual)
        if error is not None:
            raise error
        return out

    def rollout_error(
        self, out: engine.Recording, divergence_speed: float = np.inf, divergence_residual: float = np.inf
    ) -> DivergenceError | None:
        """The error a rollout that stopped early raises (None if it ran to its end)."""
        error = self._error_for(out.step_status, self.time)  # a step refused: the state is the one it started from
        if error is None and out.refusal is not engine.Refusal.none:  # a step taken whose result the node refuses
            reason = _refusal_reason(out.refusal, out.measured, divergence_speed, divergence_residual)
            error = DivergenceError(f"{reason} after the step at t = {out.time[-1]:.3f} s")
        return error

    def check(self, divergence_speed: float, divergence_residual: float) -> float:
        """The largest |C| of a held contact after the step just taken, or DivergenceError saying why
        the simulator node must not let it stand (the engine's ``refusal``, which the rollout asks
        too): non-finite forces, a joint faster than ``divergence_speed`` [rad/s] (finite, but a
        state no arm reaches: RK4 overflows a few steps later under any input), a held contact
        further than ``divergence_residual`` [m] off its surface."""
        refusal, measured = self.engine.refusal(divergence_speed, divergence_residual)
        if refusal is not engine.Refusal.none:
            raise DivergenceError(_refusal_reason(refusal, measured, divergence_speed, divergence_residual))
        return float(measured)

    def _raise_for(self, status: engine.StepStatus, time: float) -> None:
        """Raise the error of a step from ``time`` that the engine refused (diverged or a joint limit), if any."""
        error = self._error_for(status, time)
        if error is not None:
            raise error

    def _error_for(self, status: engine.StepStatus, time: float) -> DivergenceError | None:
        """The error of a step from ``time`` that the engine refused, None for a step taken."""
        if status is engine.StepStatus.diverged:
            return DivergenceError(f"non-finite state after the step at t = {time:.6f} s; state kept")
        if status is engine.StepStatus.joint_limit:
            robot, j = self.dynamics.robot, self.engine.failed_joint
            unit = "m" if robot.prismatic[j] else "rad"
            return JointLimitError(
                f"joint {robot.joint_names[j]!r} would leave its URDF limits [{robot.lower_limits[j]:g}, "
                f"{robot.upper_limits[j]:g}] {unit} (q = {self.engine.failed_position:.6g}) in the step at "
                f"t = {time:.6f} s; state kept"
            )
        return None

    def _take_events(self) -> None:
        """The engine's new release and touchdown events into ``events``."""
        self.events += self.engine.events_since(len(self.events), self.t0_ns)

    # -- unilateral contacts ----------------------------------------------------------
    def set_active(self, active: np.ndarray) -> None:
        """Which contacts hold a force (bilateral ones always do); e.g. a unilateral contact
        that starts above its plane starts released."""
        active = np.asarray(active, dtype=bool)
        if active.shape != self._unilateral.shape or np.any(~active & ~self._unilateral):
            raise ValueError("only unilateral contacts can be released")
        if np.any(active & ~self._enforced):
            raise ValueError("a contact that is only watched never holds a force")
        self.engine.set_active(active.tolist())
