"""Time integration of the constrained dynamics: classic RK4 with the input held.

The state is (q, dq, i) plus running energy integrals, integrated together so the
integrals are as accurate as the trajectory. ``Simulator.step(command)`` advances one
configured step (optionally in sub-steps) and returns the model's answer at the start
of the step, which is what the simulator reports for that step (forces, effort).

Speed (the step is ~4 model evaluations of a few microseconds each, so Python/numpy call
overhead dominates): the four stages work in preallocated arrays, only the first stage
builds a full ``Derivative``, and the energy rates of the four stages are formed at once
after the last one. ``evaluate`` keeps its answer so that the next ``step`` from the same
state reuses it as its first stage (in voltage mode ddq and f_n do not depend on the held
voltage, only di does); the result is bit-for-bit the same as without it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from bracing_sim.core.contacts import ContactTerms
from bracing_sim.core.dynamics import ConstrainedDynamics, Derivative, InputMode
from bracing_sim.core.types import Vector

_compute_all_terms = pin.computeAllTerms
_cholesky_decompose = pin.cholesky.decompose
_cholesky_solve = pin.cholesky.solve

# Order of the energy integrals appended to the state vector.
ENERGY_KEYS = ("consumed", "net", "copper_loss", "viscous_loss", "friction_loss", "constraint_work", "impact_loss")


class DivergenceError(RuntimeError):
    """The integration produced a non-finite state; the state was left as it was."""


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
        self.active = np.ones(len(contacts), dtype=bool)
        self._by_active: dict[tuple[bool, ...], ConstrainedDynamics] = {tuple(self.active.tolist()): dynamics}
        self.events: list[ContactEvent] = []
        self.step_size = float(step)
        self.substeps = int(substeps)
        self.n = n
        self.steps_taken = 0
        self.t0 = 0.0
        # y = [q, dq, i, energies]
        self._y = np.concatenate([q0, dq0, np.zeros(n), np.zeros(len(ENERGY_KEYS))])
        self._voltage = dynamics.mode is InputMode.VOLTAGE
        self._resistance = dynamics.motors.resistance
        # RK4 work arrays: stage states x = [q, dq, i, 1] and stage rates [dq, ddq, di, friction
        # power, constraint power]. The step's increment of y is (h/6) (k1 + 2 k2 + 2 k3 + k4) =
        # (w_h . [rates | |P| | P | x * x]) @ increment_map, with P the power command * (i or dq).
        m = 3 * n
        self._m = m
        self._stage_states = np.zeros((4, m + 1))
        self._stage_states[:, m] = 1.0
        self._stage_rates = np.zeros((4, m + 2))
        self._state_heads = [row[:m] for row in self._stage_states]
        self._rate_heads = [row[:m] for row in self._stage_rates]
        self._stages = [
            dynamics._stage(state, rates) for state, rates in zip(self._stage_states, self._rate_heads, strict=True)
        ]
        self._rate_rows = list(self._stage_rates)
        self._rk4_weights = np.array([1.0, 2.0, 2.0, 1.0])
        self._scaled_weights = (0.0, self._rk4_weights)
        self._power_slice = slice(2 * n, m) if self._voltage else slice(n, 2 * n)
        keys = {key: m + j for j, key in enumerate(ENERGY_KEYS)}
        squares = m + 2 + 2 * n  # where x * x starts in the work row
        increment_map = np.zeros((squares + m + 1, m + len(ENERGY_KEYS)))
        increment_map[:m, :m] = np.eye(m)
        increment_map[m, keys["friction_loss"]] = 1.0
        increment_map[m + 1, keys["constraint_work"]] = 1.0
        increment_map[m + 2 : m + 2 + n, keys["consumed"]] = 1.0  # sum |P|
        increment_map[m + 2 + n : squares, keys["net"]] = 1.0  # sum P
        if self._voltage:
            increment_map[squares + 2 * n : squares + m, keys["copper_loss"]] = self._resistance  # R i^2
        increment_map[squares + n : squares + 2 * n, keys["viscous_loss"]] = dynamics.total_damping  # Dc dq^2
        self._increment_map = increment_map
        # The model's answer at the current state, kept by ``evaluate`` for the next step.
        self._cached: tuple[Vector, float, Vector, Vector, float, float, Derivative] | None = None

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
        dynamics, n, m = self.dynamics, self.n, self._m
        u = np.array(command, dtype=float)
        state = np.empty(m + 1)
        state[:m] = self._y[:m]
        state[m] = 1.0
        rates = np.empty(m)
        dynamics._set_input(u)
        friction_power, constraint_power, d = dynamics._solve(dynamics._stage(state, rates), True)
        assert d is not None
        if u.shape == (n,):
            # The next step starts from this state: keep what it can reuse (see ``step``).
            self._cached = (state, dynamics.baumgarte, u, rates, friction_power, constraint_power, d)
        return self._report(d)

    def _reuse(self, u: Vector) -> tuple[Vector, float, float, Derivative] | None:
        """The cached answer of ``evaluate`` at the current state, if it holds for ``u``.

        Call after ``dynamics._set_input(u)``. In voltage mode ddq, f_n and the effort do
        not depend on the held voltage (only di does, and di is recomputed); in torque mode
        the command must be the same.
        """
        cached, self._cached = self._cached, None
        if cached is None:
            return None
        state, baumgarte, command, rates, friction_power, constraint_power, d = cached
        dynamics, m = self.dynamics, self._m
        if baumgarte != dynamics.baumgarte or not np.array_equal(state[:m], self._y[:m]):
            return None
        if np.array_equal(command, u):
            return rates, friction_power, constraint_power, d
        if not self._voltage:
            return None
        n2 = 2 * self.n
        current_rate = dynamics._linear.dot(state)[n2:]  # as _solve computes it (same product)
        rates = rates.copy()
        rates[n2:] = current_rate
        d = Derivative(d.acceleration, current_rate, d.normal_force, d.effort, d.contacts)
        return rates, friction_power, constraint_power, d

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
        unilateral = self._unilateral.any()
        if unilateral:
            self._release(u)
        dynamics = self.dynamics
        solve = dynamics._solve
        dynamics._set_input(u)
        reused = self._reuse(u) if self._cached is not None else None
        m = self._m
        h = self.step_size / self.substeps
        if self._scaled_weights[0] != h:
            self._scaled_weights = (h, (h / 6.0) * self._rk4_weights)
        weights = self._scaled_weights[1]
        increments = (0.5 * h, 0.5 * h, h)
        states, rates, rate_rows = self._stage_states, self._stage_rates, self._rate_rows
        state_heads, rate_heads, stages = self._state_heads, self._rate_heads, self._stages
        start = state_heads[0]
        y = self._y
        first: Derivative | None = None
        for _ in range(self.substeps):
            start[:] = y[:m]
            for k in range(4):
                row, rate = rate_rows[k], rate_heads[k]
                if reused is not None:
                    rate[:], row[m], row[m + 1], first = reused
                    reused = None
                else:
                    row[m], row[m + 1], d = solve(stages[k], first is None)
                    if d is not None:
                        first = d
                if k < 3:
                    following = state_heads[k + 1]
                    np.multiply(rate, increments[k], out=following)
                    following += start
            power = states[:, self._power_slice] * u
            work = np.concatenate((rates, np.abs(power), power, states * states), axis=1)
            y = y + weights.dot(work).dot(self._increment_map)
        if not math.isfinite(y.dot(y)) and not np.isfinite(y).all():
            raise DivergenceError(f"non-finite state after the step at t = {self.time:.6f} s; state kept")
        report = self._report(first) if first is not None else None  # contact terms at the step's start
        self._y = y
        self.steps_taken += 1
        if unilateral and not self.active.all():
            self._touchdown()
        assert report is not None
        return report

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
        self._set_active(active.copy())

    def _set_active(self, active: np.ndarray) -> None:
        self.active = active
        self.dynamics = self._dynamics_for(active)
        self._cached = None

    def _all_contact_terms(self) -> ContactTerms:
        """Terms of every contact (active or not) at the current state."""
        full = self.full_dynamics
        n = self.n
        q, dq = self._y[:n], self._y[n : 2 * n]
        _compute_all_terms(full._model, full._data, q, dq)
        return full.contacts.evaluate_data(full._model, full._data, dq)

    def _report(self, d: Derivative) -> Derivative:
        """A Derivative over all contacts (released ones: zero force, ``active`` False)."""
        if self.active.all():
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
        landing = ~self.active & (terms.residual <= 0.0) & (approach < 0.0)
        if landing.any():
            loss = self._impact(self.active | landing)
            for j in np.flatnonzero(landing):
                self.events.append(
                    ContactEvent(self.time, self.full_dynamics.contacts.contacts[int(j)].name, "touchdown", loss)
                )
            self._set_active(self.active | landing)

    def _impact(self, active: np.ndarray) -> float:
        """Inelastic, frictionless touchdown: put the active contact points back on their planes
        (mass-weighted projection of q) and remove their normal velocity with the impulse
        Mc^-1 J_c^T lambda. Returns the kinetic energy lost [J] (added to impact_loss)."""
        full, n = self.full_dynamics, self.n
        model, data = full._model, full._data
        rows = np.flatnonzero(active)
        q, dq = self._y[:n].copy(), self._y[n : 2 * n].copy()
        for _ in range(10):  # Newton on C(q) = 0 along the mass-weighted direction
            _compute_all_terms(model, data, q, dq)
            _cholesky_decompose(model, data)
            terms = full.contacts.evaluate_data(model, data, dq)
            residual, jc = terms.residual[rows], terms.normal_jacobian[rows]
            y = np.column_stack([_cholesky_solve(model, data, row) for row in jc])  # Mc^-1 J_c^T
            if np.max(np.abs(residual)) < 1e-13:
                break
            q = q + y.dot(np.linalg.solve(jc.dot(y), -residual))
        normal_velocity = jc.dot(dq)
        delassus = jc.dot(y)
        impulse = -np.linalg.solve(delassus, normal_velocity)
        dq = dq + y.dot(impulse)
        loss = 0.5 * float(normal_velocity.dot(-impulse))  # (J_c dq)^T (J_c Mc^-1 J_c^T)^-1 (J_c dq) / 2
        self._y[:n], self._y[n : 2 * n] = q, dq
        self._y[self._m + ENERGY_KEYS.index("impact_loss")] += loss
        self._cached = None
        return loss
