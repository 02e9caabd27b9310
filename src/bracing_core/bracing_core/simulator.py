"""Time integration of the constrained dynamics: classic RK4 with the input held.

The state is (q, dq, i) plus running energy integrals, integrated together so the
integrals are as accurate as the trajectory. ``Simulator.step(command)`` advances one
configured step (optionally in sub-steps) and returns the model's answer at the start
of the step, which is what the simulator reports for that step (forces, effort).

Speed (the step is ~4 model evaluations of a few microseconds each, so Python/numpy call
overhead dominates): the four stages work in rows of one preallocated array (a stage's state
and rates side by side), only the first stage builds a full ``Derivative``, and the step's
increment of the state and of the energy integrals is formed at once after the last stage,
in a few whole-array operations. ``evaluate`` keeps its answer so that the next ``step`` from the same
state reuses it as its first stage (in voltage mode ddq and f_n do not depend on the held
voltage, only di does); the result is bit-for-bit the same as without it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from bracing_core.contacts import ContactTerms, project_onto_contacts
from bracing_core.dynamics import ConstrainedDynamics, Derivative, InputMode, Stage
from bracing_core.types import Vector

# Order of the energy integrals appended to the state vector.
ENERGY_KEYS = ("consumed", "net", "copper_loss", "viscous_loss", "friction_loss", "constraint_work", "impact_loss")


class DivergenceError(RuntimeError):
    """The integration produced a non-finite state; the state was left as it was."""


class JointLimitError(DivergenceError):
    """A step would take a joint past its URDF position limit; the state was left as it was."""


@dataclass(frozen=True)
class Energy:
    """Energy integrals since the start [J].

    consumed = int sum |v i| dt, net = int sum v i dt, copper_loss = int sum R i^2 dt
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
class ContactEvent:
    """A unilateral contact letting go (``release``) or landing (``touchdown``)."""

    time: float  # [s]
    contact: str
    kind: str  # release | touchdown
    impact_loss: float = 0.0  # [J], touchdown only


@dataclass(frozen=True)
class Checkpoint:
    """A copy of the simulator's state (see :meth:`Simulator.checkpoint`)."""

    state: np.ndarray  # q, dq, i and the energy integrals
    steps_taken: int
    active: np.ndarray  # which contacts hold a force
    events: int  # length of the event log


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
        self.dynamics = dynamics  # of the contacts holding a force now (all, unless some released)
        self.full_dynamics = dynamics
        contacts = dynamics.contacts
        self._unilateral = np.array([c.unilateral for c in contacts.contacts], dtype=bool)
        self._enforced = np.array([c.enforced for c in contacts.contacts], dtype=bool)  # the rest are only watched
        self._any_unilateral = bool(self._unilateral.any())
        self.active = np.ones(len(contacts), dtype=bool)
        self._all_active = True
        self._by_active: dict[tuple[bool, ...], ConstrainedDynamics] = {tuple(self.active.tolist()): dynamics}
        self.events: list[ContactEvent] = []
        self.step_size = float(step)
        self.substeps = int(substeps)
        self.n = n
        robot = dynamics.robot
        # The URDF's limits per joint as floats: checking a few joints in Python costs 0.4 us a step,
        # numpy's ufuncs 2 us (measured side by side; 4% of the paper model's 52 us step).
        self._bounds = tuple(zip(robot.lower_limits.tolist(), robot.upper_limits.tolist(), strict=True))
        self._limited = bool(np.isfinite(robot.lower_limits).any() or np.isfinite(robot.upper_limits).any())
        j = self._first_outside_limits(q0)
        if j is not None:
            (lower, upper), position = self._bounds[j], float(q0[j])
            raise ValueError(
                f"initial_position: joint {robot.joint_names[j]!r} at {position:.6g} is outside its URDF limits "
                f"[{lower:g}, {upper:g}]"
            )
        self.steps_taken = 0
        self.t0 = 0.0
        # y = [q, dq, i, energies]; a step writes the next y into the spare buffer and swaps.
        self._y = np.concatenate([q0, dq0, np.zeros(n), np.zeros(len(ENERGY_KEYS))])
        self._y_next = np.empty_like(self._y)
        self._revision = 0  # counts the changes of the state (keys the cached answers below)
        self._all_terms: tuple[int, ContactTerms] | None = None  # (revision, every contact's terms)
        self._voltage = dynamics.mode is InputMode.VOLTAGE
        self._resistance = dynamics.motors.resistance
        # RK4 work, a row per stage k: [x_k | rates_k | friction power, constraint power] with
        # x = [q, dq, i, 1] and rates = [dq, ddq, di], followed by the same rows' absolute values
        # and squares (three contiguous bands, each written by one numpy call). The step's
        # increment of y is (h/6) (k1 + 2 k2 + 2 k3 + k4) and the energy rates' weighted sums:
        # (weights @ bands) @ increment_map, with the power P = command * (i or dq) summed
        # through the map's command columns (set per step).
        m = 3 * n
        self._m = m
        rate0 = m + 1
        # Padded to whole SIMD blocks: OpenBLAS may sum a matrix-vector product's remainder
        # columns in another order than the rest, and y must not depend on where a rate sits.
        width = -(-(2 * m + 3) // 16) * 16
        work = np.zeros((12, width))
        rows = work[:4]
        rows[:, m] = 1.0
        self._rows = rows
        self._abs_rows = work[4:8]
        self._squared_rows = work[8:]
        self._stages = [dynamics.stage(row) for row in rows]
        self._state_heads = [row[:m] for row in rows]
        self._rate_heads = [row[rate0 : rate0 + m] for row in rows]
        self._powers = (rate0 + m, rate0 + m + 1)  # columns of the friction and constraint powers
        self._first_stage = (self._state_heads[0], self._stages[0], rows[0])
        self._plan = self._plan_for(self.step_size / self.substeps)
        self._energy_rows = work[4:]
        self._weighted = np.zeros((3, width))
        self._weighted_rates, self._weighted_energy = self._weighted[0], self._weighted[1:]
        self._weighted_flat = self._weighted.reshape(-1)
        keys = {key: m + j for j, key in enumerate(ENERGY_KEYS)}
        increment_map = np.zeros((3 * width, m + len(ENERGY_KEYS)))
        increment_map[rate0 : rate0 + m, :m] = np.eye(m)
        increment_map[rate0 + m, keys["friction_loss"]] = 1.0
        increment_map[rate0 + m + 1, keys["constraint_work"]] = 1.0
        power = slice(2 * n, m) if self._voltage else slice(n, 2 * n)
        self._net_column = increment_map[power, keys["net"]]  # sum P = command . (i or dq)
        self._consumed_column = increment_map[width:][power, keys["consumed"]]  # sum |P|
        squares = increment_map[2 * width :]
        if self._voltage:
            squares[2 * n : m, keys["copper_loss"]] = self._resistance  # R i^2
        squares[n : 2 * n, keys["viscous_loss"]] = dynamics.total_damping  # Dc dq^2
        self._increment_map = increment_map
        self._increment = np.zeros(m + len(ENERGY_KEYS))
        # The answer of ``evaluate`` at the current state, left in the first stage's row for the
        # next step: (state revision, Baumgarte gain, command as a list, Derivative).
        self._cached: tuple[int, float, list[float], Derivative] | None = None

    # -- state ------------------------------------------------------------------------
    @property
    def time(self) -> float:
        return self.t0 + self.steps_taken * self.step_size

    @property
    def position(self) -> Vector:
        return self._y[: self.n].copy()

    @property
    def velocity(self) -> Vector:
        return self._y[self.n : 2 * self.n].copy()

    @property
    def current(self) -> Vector:
        return self._y[2 * self.n : 3 * self.n].copy()

    @property
    def energy(self) -> Energy:
        return Energy(*(float(e) for e in self._y[3 * self.n :]))

    # -- model answers ----------------------------------------------------------------
    def evaluate(self, command: Vector) -> Derivative:
        """The model at the current state under ``command`` (no time passes)."""
        dynamics, m = self.dynamics, self._m
        u = np.array(command, dtype=float)
        self._cached = None  # the first stage's row is overwritten here
        self._state_heads[0][:] = self._y[:m]
        dynamics.set_input(u)
        row, (friction, constraint) = self._rows[0], self._powers
        row[friction], row[constraint], d = dynamics.solve(self._stages[0], True)
        assert d is not None
        if u.shape == (self.n,):
            # The next step starts from this state: it reuses this answer (see ``_reuse``).
            self._cached = (self._revision, dynamics.baumgarte, u.tolist(), d)
        return self._report(d)

    def _reuse(self, cached: tuple[int, float, list[float], Derivative], u: Vector) -> Derivative | None:
        """The cached answer of ``evaluate`` as the step's first stage, if it holds for ``u``
        (its rates are still in the first stage's row).

        Call after ``dynamics.set_input(u)``. In voltage mode ddq, f_n and the effort do
        not depend on the held voltage (only di does, and di is recomputed); in torque mode
        the command must be the same.
        """
        revision, baumgarte, command, d = cached
        dynamics = self.dynamics
        if revision != self._revision or baumgarte != dynamics.baumgarte:
            return None
        if command == u.tolist():
            return d
        if not self._voltage:
            return None
        current_rate = self._rate_heads[0][2 * self.n :]
        np.dot(dynamics.current_rows, self._stages[0][0], out=current_rate)  # as solve computes it
        return Derivative(d.acceleration, current_rate.copy(), d.normal_force, d.effort, d.contacts)

    # -- checkpoints --------------------------------------------------------------------
    def checkpoint(self) -> Checkpoint:
        """The state as it is now, for :meth:`restore` (e.g. to take back a step whose result
        the caller refuses)."""
        return Checkpoint(self._y.copy(), self.steps_taken, self.active.copy(), len(self.events))

    def restore(self, checkpoint: Checkpoint) -> None:
        """Back to ``checkpoint``: state, step count, released contacts and event log."""
        self._y[:] = checkpoint.state
        self.steps_taken = checkpoint.steps_taken
        del self.events[checkpoint.events :]
        if not np.array_equal(self.active, checkpoint.active):
            self._set_active(checkpoint.active.copy())
        self._revision += 1  # a cached answer of ``evaluate`` belongs to another state
        self._cached = None

    # -- integration ------------------------------------------------------------------
    def step(self, command: Vector) -> Derivative:
        """Advance one step with ``command`` held (zero-order hold); RK4 per sub-step.

        Returns the model's answer at the start of the step. Raises ValueError for a
        command of the wrong shape or with non-finite values, DivergenceError if the new
        state is not finite; in both cases the state is unchanged.
        """
        u = np.asarray(command, dtype=float)
        # A finite u . u means every entry is finite; otherwise check exactly (u . u may overflow).
        if u.shape != (self.n,) or (not math.isfinite(u.dot(u)) and not np.isfinite(u).all()):
            raise ValueError(f"command: expected {self.n} finite values, got {np.ravel(u).tolist()}")
        if self._any_unilateral:
            self._release(u)
        dynamics = self.dynamics
        solve = dynamics.solve
        dynamics.set_input(u)
        cached, self._cached = self._cached, None
        first = self._reuse(cached, u) if cached is not None else None
        h = self.step_size / self.substeps
        if self._plan[0] != h:
            self._plan = self._plan_for(h)
        _, weights, band_weights, following_stages = self._plan
        start, first_stage, first_row = self._first_stage
        friction, constraint = self._powers
        np.copyto(self._net_column, u)
        np.abs(u, out=self._consumed_column)
        rows, m, multiply = self._rows, self._m, np.multiply
        y, y_next, increment = self._y, self._y_next, self._increment
        for substep in range(self.substeps):
            if substep or first is None:  # else the first stage is the cached answer, from y
                start[:] = y[:m]
                first_row[friction], first_row[constraint], d = solve(first_stage, first is None)
                if first is None:
                    first = d
            for previous_rates, c, following, stage, row in following_stages:
                multiply(previous_rates, c, out=following)  # x_k = x_1 + c_k k_(k-1)
                following += start
                row[friction], row[constraint], _ = solve(stage, False)
            np.abs(rows, out=self._abs_rows)
            np.multiply(rows, rows, out=self._squared_rows)
            # The rates' sum alone, as one matrix-vector product: so y is the same to the last bit
            # as with the rows in any other layout (a matrix-matrix product may sum differently).
            np.dot(weights, rows, out=self._weighted_rates)
            np.dot(band_weights, self._energy_rows, out=self._weighted_energy)
            np.dot(self._weighted_flat, self._increment_map, out=increment)
            np.add(y, increment, out=y_next)  # never into self._y: a diverged step keeps the state
            y = y_next
        if not math.isfinite(y.dot(y)) and not np.isfinite(y).all():
            raise DivergenceError(f"non-finite state after the step at t = {self.time:.6f} s; state kept")
        if self._limited:
            j = self._first_outside_limits(y[: self.n])
            if j is not None:
                (lower, upper), robot = self._bounds[j], self.dynamics.robot
                unit = "m" if robot.prismatic[j] else "rad"
                raise JointLimitError(
                    f"joint {robot.joint_names[j]!r} would leave its URDF limits [{lower:g}, {upper:g}] {unit} "
                    f"(q = {y[j]:.6g}) in the step at t = {self.time:.6f} s; state kept"
                )
        assert first is not None
        report = self._report(first)  # contact terms at the step's start
        self._y, self._y_next = y, self._y
        self._revision += 1
        self.steps_taken += 1
        if self._any_unilateral and not self._all_active:
            self._touchdown()
        return report

    def _first_outside_limits(self, q: Vector) -> int | None:
        """The first joint that ``q`` puts outside its URDF limits, or None."""
        for j, (value, (lower, upper)) in enumerate(zip(q.tolist(), self._bounds, strict=True)):
            if not lower <= value <= upper:
                return j
        return None

    def _plan_for(
        self, h: float
    ) -> tuple[float, Vector, Vector, tuple[tuple[Vector, float, Vector, Stage, Vector], ...]]:
        """What a sub-step of size ``h`` needs: (h, the RK4 weights h/6 [1, 2, 2, 1], the same per
        energy band, and per later stage (previous rates, c_k, state, stage views, row))."""
        weights = (h / 6.0) * np.array([1.0, 2.0, 2.0, 1.0])
        following = tuple(
            (self._rate_heads[k - 1], c, self._state_heads[k], self._stages[k], self._rows[k])
            for k, c in ((1, 0.5 * h), (2, 0.5 * h), (3, h))
        )
        return h, weights, np.asarray(np.kron(np.eye(2), weights), dtype=np.float64), following

    # -- unilateral contacts ----------------------------------------------------------
    def _dynamics_for(self, active: np.ndarray) -> ConstrainedDynamics:
        key = tuple(active.tolist())
        if key not in self._by_active:
            subset = self.full_dynamics.contacts.subset(np.flatnonzero(active).tolist())
            self._by_active[key] = self.full_dynamics.with_contacts(subset)
        return self._by_active[key]

    def set_active(self, active: np.ndarray) -> None:
        """Which contacts hold a force (bilateral ones always do); e.g. a unilateral contact
        that starts above its plane starts released."""
        active = np.asarray(active, dtype=bool)
        if active.shape != self.active.shape or np.any(~active & ~self._unilateral):
            raise ValueError("only unilateral contacts can be released")
        if np.any(active & ~self._enforced):
            raise ValueError("a contact that is only watched never holds a force")
        self._set_active(active.copy())

    def _set_active(self, active: np.ndarray) -> None:
        self.active = active
        self._all_active = bool(active.all())
        self.dynamics = self._dynamics_for(active)
        self._cached = None

    def _all_contact_terms(self) -> ContactTerms:
        """Terms of every contact (active or not) at the current state, computed once per state: a
        step's touchdown check and the next step's report (while a contact is released) read the same."""
        if self._all_terms is not None and self._all_terms[0] == self._revision:
            return self._all_terms[1]
        full = self.full_dynamics
        n = self.n
        q, dq = self._y[:n], self._y[n : 2 * n]
        pin.computeAllTerms(full._model, full._data, q, dq)
        terms = full.contacts.evaluate_data(full._model, full._data, dq)
        self._all_terms = (self._revision, terms)
        return terms

    def _report(self, d: Derivative) -> Derivative:
        """A Derivative over all contacts (released ones: zero force, ``active`` False)."""
        if self._all_active:
            return d
        force = np.zeros(self.active.size)
        force[self.active] = d.normal_force
        return Derivative(
            d.acceleration, d.current_rate, force, d.effort, self._all_contact_terms(), self.active.copy()
        )

    def _release(self, u: Vector) -> None:
        """At the start of a step: unilateral contacts whose force would pull let go, the
        most negative first, until every held force pushes."""
        while self.active.any():
            # ``evaluate`` keeps its answer: when nothing releases, it is the step's first stage.
            force = self.evaluate(u).normal_force  # over all contacts, zero where released
            pulling = [(force[j], j) for j in np.flatnonzero(self.active) if self._unilateral[j] and force[j] < 0.0]
            if not pulling:
                return
            j = min(pulling)[1]
            active = self.active.copy()
            active[j] = False
            self.events.append(ContactEvent(self.time, self.full_dynamics.contacts.contacts[int(j)].name, "release"))
            self._set_active(active)

    def _touchdown(self) -> None:
        """At the end of a step: released contacts that reached their plane while approaching
        land (inelastic impact), so no state the simulator shows is below a plane."""
        terms = self._all_contact_terms()
        approach = terms.normal_jacobian.dot(self._y[self.n : 2 * self.n])
        landing = ~self.active & self._enforced & (terms.residual <= 0.0) & (approach < 0.0)
        if landing.any():
            loss = self._impact(self.active | landing)
            for j in np.flatnonzero(landing):
                self.events.append(
                    ContactEvent(self.time, self.full_dynamics.contacts.contacts[int(j)].name, "touchdown", loss)
                )
            self._set_active(self.active | landing)

    def _impact(self, active: np.ndarray) -> float:
        """Inelastic, frictionless touchdown: put the active contact points back on their surfaces
        (mass-weighted projection of q) and remove their normal velocity with the impulse
        Mc^-1 J_c^T lambda. Returns the kinetic energy lost [J] (added to impact_loss)."""
        full, n = self.full_dynamics, self.n
        model, data = full._model, full._data
        rows = np.flatnonzero(active).tolist()
        q = project_onto_contacts(model, data, full.contacts, self._y[:n], rows)
        dq = self._y[n : 2 * n].copy()
        pin.computeAllTerms(model, data, q, dq)
        pin.cholesky.decompose(model, data)
        jc = full.contacts.evaluate_data(model, data, dq).normal_jacobian[rows]
        y = np.column_stack([pin.cholesky.solve(model, data, row) for row in jc])  # Mc^-1 J_c^T
        normal_velocity = jc.dot(dq)
        delassus = jc.dot(y)
        impulse = -np.linalg.solve(delassus, normal_velocity)
        dq = dq + y.dot(impulse)
        loss = 0.5 * float(normal_velocity.dot(-impulse))  # (J_c dq)^T (J_c Mc^-1 J_c^T)^-1 (J_c dq) / 2
        self._y[:n], self._y[n : 2 * n] = q, dq
        self._y[self._m + ENERGY_KEYS.index("impact_loss")] += loss
        self._revision += 1
        self._cached = None
        return loss
