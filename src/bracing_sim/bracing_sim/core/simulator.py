"""Time integration of the constrained dynamics: classic RK4 with the input held.

The state is (q, dq, i) plus running energy integrals, integrated together so the
integrals are as accurate as the trajectory. ``Simulator.step(command)`` advances one
configured step (optionally in sub-steps) and returns the model's answer at the start
of the step, which is what the simulator reports for that step (forces, effort).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bracing_sim.core.dynamics import ConstrainedDynamics, Derivative, InputMode
from bracing_sim.core.types import Vector

# Order of the energy integrals appended to the state vector.
ENERGY_KEYS = ("consumed", "net", "copper_loss", "viscous_loss", "friction_loss", "constraint_work")


class DivergenceError(RuntimeError):
    """The integration produced a non-finite state; the state was left as it was."""


@dataclass(frozen=True)
class Energy:
    """Energy integrals since the start [J].

    consumed = int sum |v i| dt, net = int sum v i dt, copper_loss = int sum R i^2 dt
    (voltage mode; torque mode uses the mechanical power tau dq and no copper loss);
    viscous_loss = int dq^T Dc dq dt, friction_loss = int sum mu f_n (dir . slip) dt,
    constraint_work = int f_n . (J_c dq) dt (zero for an ideal, satisfied constraint).
    """

    consumed: float
    net: float
    copper_loss: float
    viscous_loss: float
    friction_loss: float
    constraint_work: float


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
        self.dynamics = dynamics
        self.step_size = float(step)
        self.substeps = int(substeps)
        self.n = n
        self.steps_taken = 0
        self.t0 = 0.0
        # y = [q, dq, i, energies]
        self._y = np.concatenate([q0, dq0, np.zeros(n), np.zeros(len(ENERGY_KEYS))])
        self._voltage = dynamics.mode is InputMode.VOLTAGE
        self._resistance = dynamics.motors.resistance

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
        n, y = self.n, self._y
        return self.dynamics.evaluate(y[:n], y[n : 2 * n], y[2 * n : 3 * n], command)

    def _rate(self, y: Vector, command: Vector) -> tuple[Vector, Derivative]:
        n = self.n
        q, dq, i = y[:n], y[n : 2 * n], y[2 * n : 3 * n]
        d = self.dynamics.evaluate(q, dq, i, command)
        if self._voltage:
            power = command * i
            copper = float(self._resistance @ (i * i))
        else:
            power = command * dq
            copper = 0.0
        terms = d.contacts
        friction_loss = float(np.sum(terms.friction * d.normal_force * np.einsum("pi,pi->p", terms.slip_direction, terms.slip_velocity)))
        constraint_work = float(d.normal_force @ (terms.normal_jacobian @ dq)) if terms.count else 0.0
        rates = np.concatenate([
            dq,
            d.acceleration,
            d.current_rate,
            [
                float(np.abs(power).sum()),
                float(power.sum()),
                copper,
                float(dq @ (self.dynamics.total_damping * dq)),
                friction_loss,
                constraint_work,
            ],
        ])
        return rates, d

    # -- integration ------------------------------------------------------------------
    def step(self, command: Vector) -> Derivative:
        """Advance one step with ``command`` held (zero-order hold); RK4 per sub-step.

        Returns the model's answer at the start of the step. Raises ValueError for a
        command of the wrong shape or with non-finite values, DivergenceError if the new
        state is not finite; in both cases the state is unchanged.
        """
        u = np.asarray(command, dtype=float)
        if u.shape != (self.n,) or not np.all(np.isfinite(u)):
            raise ValueError(f"command: expected {self.n} finite values, got {np.ravel(u).tolist()}")
        h = self.step_size / self.substeps
        y = self._y
        first: Derivative | None = None
        for _ in range(self.substeps):
            k1, d1 = self._rate(y, u)
            if first is None:
                first = d1
            k2, _ = self._rate(y + 0.5 * h * k1, u)
            k3, _ = self._rate(y + 0.5 * h * k2, u)
            k4, _ = self._rate(y + h * k3, u)
            y = y + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
        if not np.all(np.isfinite(y)):
            raise DivergenceError(f"non-finite state after the step at t = {self.time:.6f} s; state kept")
        self._y = y
        self.steps_taken += 1
        assert first is not None
        return first
