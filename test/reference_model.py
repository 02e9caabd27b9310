"""A plain reference of the model and of the control law (docs/model.md; SPEC section 2), for test_oracle.py.

Written to be read, not to be fast: no fast paths, no caching, pinocchio's Python API and numpy
only. It is an independent formulation of what the project computes:

- the constrained dynamics solve the full (n + p) KKT system with ``np.linalg.solve``
  (the project uses the p x p Schur complement through a Cholesky factor of Mc);
- M comes from ``pin.crba`` on a model without armature, and the reflected rotor inertia J_m is
  added here (the project puts J_m into pinocchio's armature);
- the law uses ``np.linalg.pinv`` for B^+ (the project: B^T (B B^T)^-1) and inverts Mc explicitly,
  and samples the task paths here (hold, circle, waypoints).

Everything is in model joint order (pinocchio's), SI units.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pinocchio as pin

WORLD = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED


# -- descriptions ------------------------------------------------------------------------------


@dataclass(frozen=True)
class Surface:
    """plane: C = n . r - offset; sphere: C = |r - center| - radius; cylinder (axis through
    ``center``): C = |(I - a a^T)(r - center)| - radius; ``inside`` flips the sign (not planes)."""

    kind: str  # plane | sphere | cylinder
    normal: np.ndarray = field(default_factory=lambda: np.zeros(3))  # plane
    offset: float = 0.0  # plane
    center: np.ndarray = field(default_factory=lambda: np.zeros(3))  # sphere centre, or a point on the cylinder's axis
    axis: np.ndarray = field(default_factory=lambda: np.zeros(3))  # cylinder
    radius: float = 0.0  # sphere, cylinder
    inside: bool = False  # sphere, cylinder


@dataclass(frozen=True)
class ContactSpec:
    frame: str
    surface: Surface
    mu: float  # friction coefficient


@dataclass(frozen=True)
class Motors:
    """Per joint, model order: K [V s/rad], R [ohm] (at 20 degC), L [H], I_m [kg m^2], gear ratio k, gear
    damping d_m (motor side), transmission radius rho [m] (0: revolute). Thermal (voltage mode): winding
    to ambient R_th [K/W], capacity C_th [J/K], ambient T_a [degC], copper's alpha [1/K]."""

    K: np.ndarray
    R: np.ndarray
    L: np.ndarray
    I_m: np.ndarray
    k: np.ndarray
    d_m: np.ndarray
    rho: np.ndarray
    R_th: np.ndarray
    C_th: np.ndarray
    thermal: bool = False
    T_a: float = 20.0
    alpha: float = 0.0

    def resistance(self, T: np.ndarray) -> np.ndarray:
        """R(T) = R_20 (1 + alpha (T - 20 degC)); R_20 without the thermal model."""
        return self.R * (1.0 + self.alpha * (T - 20.0)) if self.thermal else self.R

    def heating(self, i: np.ndarray, T: np.ndarray) -> np.ndarray:
        """dT/dt = (R(T) i^2 - (T - T_a) / R_th) / C_th; 0 without the thermal model."""
        if not self.thermal:
            return np.zeros_like(T)
        return (self.resistance(T) * i * i - (T - self.T_a) / self.R_th) / self.C_th


@dataclass(frozen=True)
class Task:
    """A PD task on a frame's origin along some world axes (eq. 39)."""

    frame: str
    axes: tuple[int, ...]  # world axis indices
    kp: tuple[float, ...]  # one per axis
    kd: tuple[float, ...]
    target: np.ndarray  # r_d (3,)
    target_velocity: np.ndarray  # dr_d (3,)


@dataclass
class Answer:
    """The reference's answer at one state and input (p rows per contact quantity)."""

    ddq: np.ndarray
    di: np.ndarray
    f_n: np.ndarray
    effort: np.ndarray
    positions: np.ndarray  # (p, 3)
    normals: np.ndarray  # (p, 3)
    residual: np.ndarray  # C (p,)
    drift: np.ndarray  # gamma (p,)
    curvature: np.ndarray  # the v^T H v part of gamma (p,)
    slip: np.ndarray  # (p, 3)
    J_c: np.ndarray  # (p, n)
    J_t: np.ndarray  # (p, n)


# -- pieces ------------------------------------------------------------------------------------


def surface_terms(surface: Surface, r: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """C(r), its unit gradient n(r) and its Hessian H(r) (docs/model.md, Contacts)."""
    if surface.kind == "plane":
        n = surface.normal / np.linalg.norm(surface.normal)
        return float(n @ r - surface.offset), n, np.zeros((3, 3))
    if surface.kind == "sphere":
        P = np.eye(3)
    elif surface.kind == "cylinder":
        a = surface.axis / np.linalg.norm(surface.axis)
        P = np.eye(3) - np.outer(a, a)
    else:
        raise ValueError(f"unknown surface {surface.kind!r}")
    d = P @ (r - surface.center)
    distance = float(np.linalg.norm(d))
    n = d / distance
    C = distance - surface.radius
    H = (P - np.outer(n, n)) / distance
    if surface.inside:
        return -C, -n, -H
    return C, n, H


def reflected(motors: Motors) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """K_m = K k / rho, J_m = I_m k^2 / rho^2, D_m = d_m k^2 / rho^2 (rho = 1 for a revolute joint)."""
    rho = np.where(motors.rho > 0.0, motors.rho, 1.0)
    ratio = motors.k / rho
    return motors.K * ratio, motors.I_m * ratio**2, motors.d_m * ratio**2


def mass_matrix(model: pin.Model, data: pin.Data, q: np.ndarray) -> np.ndarray:
    """M(q) from crba (upper triangle), without any armature."""
    assert not np.any(model.armature), "the reference adds the rotor inertia itself"
    M = pin.crba(model, data, q)
    return np.triu(M) + np.triu(M, 1).T


def contact_rows(
    model: pin.Model, data: pin.Data, contacts: Sequence[ContactSpec], q: np.ndarray, dq: np.ndarray, eps: float
) -> Answer:
    """Every contact's geometry at (q, dq); ddq, di, f_n, effort left empty."""
    n = model.nv
    pin.computeJointJacobians(model, data, q)
    pin.forwardKinematics(model, data, q, dq, np.zeros(n))  # ddq = 0: the drift
    pin.updateFramePlacements(model, data)
    rows: dict[str, list] = {k: [] for k in ("r", "n", "C", "gamma", "curv", "s", "jc", "jt")}
    for contact in contacts:
        frame = model.getFrameId(contact.frame)
        r = data.oMf[frame].translation.copy()
        J = pin.getFrameJacobian(model, data, frame, WORLD)[:3]
        acceleration = pin.getFrameClassicalAcceleration(model, data, frame, WORLD).linear
        C, normal, H = surface_terms(contact.surface, r)
        v = J @ dq
        slip = v - normal * (normal @ v)
        direction = slip / math.sqrt(slip @ slip + eps**2)
        rows["r"].append(r)
        rows["n"].append(normal)
        rows["C"].append(C)
        rows["curv"].append(v @ H @ v)
        rows["gamma"].append(normal @ acceleration + v @ H @ v)
        rows["s"].append(slip)
        rows["jc"].append(normal @ J)
        rows["jt"].append(direction @ J)
    p = len(contacts)
    return Answer(
        ddq=np.zeros(n),
        di=np.zeros(n),
        f_n=np.zeros(p),
        effort=np.zeros(n),
        positions=np.array(rows["r"]).reshape(p, 3),
        normals=np.array(rows["n"]).reshape(p, 3),
        residual=np.array(rows["C"]),
        drift=np.array(rows["gamma"]),
        curvature=np.array(rows["curv"]),
        slip=np.array(rows["s"]).reshape(p, 3),
        J_c=np.array(rows["jc"]).reshape(p, n),
        J_t=np.array(rows["jt"]).reshape(p, n),
    )


# -- the model ---------------------------------------------------------------------------------


def reference_derivative(
    model: pin.Model,
    data: pin.Data,
    contacts: Sequence[ContactSpec],
    q: np.ndarray,
    dq: np.ndarray,
    i: np.ndarray,
    u: np.ndarray,
    mode: str,
    motors: Motors,
    damping: np.ndarray,
    baumgarte: float,
    slip_epsilon: float,
    T: np.ndarray | None = None,
) -> Answer:
    """ddq, di, f_n (and the effort) at state (q, dq, i, T) under input u (v or tau), every contact
    held (T: the windings' temperatures, default ambient):

    [ Mc   -W^T ] [ ddq ]   [ drive - (h + g) - Dc dq             ]
    [ J_c    0  ] [ f_n ] = [ -gamma - 2 a J_c dq - a^2 C         ],   W = J_c - mu J_t
    """
    n = model.nv
    K_m, J_m, D_m = reflected(motors)
    if mode == "voltage":
        Mc = mass_matrix(model, data, q) + np.diag(J_m)
        Dc = np.diag(damping + D_m)
        drive = K_m * i
    else:
        Mc = mass_matrix(model, data, q)
        Dc = np.diag(damping)
        drive = np.array(u, dtype=float)
    h_plus_g = pin.nonLinearEffects(model, data, q, dq).copy()
    answer = contact_rows(model, data, contacts, q, dq, slip_epsilon)
    p = len(contacts)
    mu = np.diag([c.mu for c in contacts])
    W = answer.J_c - mu @ answer.J_t
    a = baumgarte
    kkt = np.zeros((n + p, n + p))
    kkt[:n, :n] = Mc
    kkt[:n, n:] = -W.T
    kkt[n:, :n] = answer.J_c
    rhs = np.concatenate(
        [drive - h_plus_g - Dc @ dq, -answer.drift - 2.0 * a * (answer.J_c @ dq) - a**2 * answer.residual]
    )
    solution = np.linalg.solve(kkt, rhs)
    answer.ddq, answer.f_n = solution[:n], solution[n:]
    if mode == "voltage":
        T = np.full(n, motors.T_a) if T is None else T
        answer.di = (u - motors.resistance(T) * i - K_m * dq) / motors.L
        answer.effort = K_m * i - D_m * dq - J_m * answer.ddq
    else:
        answer.di = np.zeros(n)
        answer.effort = np.array(u, dtype=float)
    return answer


ENERGY_NAMES = ("consumed", "net", "copper_loss", "viscous_loss", "friction_loss", "constraint_work")


def energy_rates(
    answer: Answer,
    contacts: Sequence[ContactSpec],
    dq: np.ndarray,
    i: np.ndarray,
    u: np.ndarray,
    mode: str,
    motors: Motors,
    damping: np.ndarray,
    eps: float,
    T: np.ndarray,
) -> np.ndarray:
    """d/dt of ENERGY_NAMES (docs/model.md, Integrator and energy) from an answer of reference_derivative."""
    _, _, D_m = reflected(motors)
    if mode == "voltage":
        power, copper, Dc = u * i, float(motors.resistance(T) @ (i * i)), damping + D_m
    else:
        power, copper, Dc = u * dq, 0.0, damping
    friction = sum(
        c.mu * f * (s @ s) / math.sqrt(s @ s + eps**2)
        for c, f, s in zip(contacts, answer.f_n, answer.slip, strict=True)
    )
    work = float(answer.f_n @ (answer.J_c @ dq))
    return np.array([np.abs(power).sum(), power.sum(), copper, dq @ (Dc * dq), friction, work])


def reference_rk4_step(
    model: pin.Model,
    data: pin.Data,
    contacts: Sequence[ContactSpec],
    q: np.ndarray,
    dq: np.ndarray,
    i: np.ndarray,
    u: np.ndarray,
    mode: str,
    motors: Motors,
    damping: np.ndarray,
    baumgarte: float,
    slip_epsilon: float,
    step: float,
    substeps: int = 1,
    T: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(q, dq, i, T, energy increments) after one step of ``step`` seconds with u held: ``substeps``
    classic RK4 steps of x = (q, dq, i, T, E) (T: the windings' temperatures, default ambient)."""
    n = model.nv

    def f(x: np.ndarray) -> np.ndarray:
        q, dq, i, T = x[:n], x[n : 2 * n], x[2 * n : 3 * n], x[3 * n : 4 * n]
        d = reference_derivative(model, data, contacts, q, dq, i, u, mode, motors, damping, baumgarte, slip_epsilon, T)
        rates = energy_rates(d, contacts, dq, i, u, mode, motors, damping, slip_epsilon, T)
        heating = motors.heating(i, T) if mode == "voltage" else np.zeros(n)
        return np.concatenate([dq, d.ddq, d.di, heating, rates])

    T0 = np.full(n, motors.T_a) if T is None else T
    x = np.concatenate([q, dq, i, T0, np.zeros(len(ENERGY_NAMES))])
    h = step / substeps
    for _ in range(substeps):
        k1 = f(x)
        k2 = f(x + h / 2 * k1)
        k3 = f(x + h / 2 * k2)
        k4 = f(x + h * k3)
        x = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return x[:n], x[n : 2 * n], x[2 * n : 3 * n], x[3 * n : 4 * n], x[4 * n :]


# -- the law -----------------------------------------------------------------------------------


def reference_target(trajectory: Any, start: np.ndarray, t: float) -> tuple[np.ndarray, np.ndarray]:
    """r_d(t), dr_d(t) of a task path (docs/model.md, Control law: hold, circle, waypoints).

    ``trajectory`` has the fields of bracing_core's TrajectoryConfig; ``start`` is the task
    point's first measured position."""
    if trajectory.kind == "circle":
        rate = trajectory.direction * 2 * math.pi / trajectory.period
        angle = rate * t + trajectory.phase
        e_u, e_v = np.eye(3)[trajectory.plane[0]], np.eye(3)[trajectory.plane[1]]
        r = np.array(trajectory.center) + trajectory.radius * (math.cos(angle) * e_u + math.sin(angle) * e_v)
        dr = trajectory.radius * rate * (-math.sin(angle) * e_u + math.cos(angle) * e_v)
        return r, dr
    if trajectory.kind == "waypoints":
        points = [np.array(start)] + [np.array(w, dtype=float) for w in trajectory.waypoints]
        T = trajectory.segment_time
        segment = math.floor(t / T) if t > 0 else 0
        if segment >= len(points) - 1:
            return points[-1], np.zeros(3)
        a, b = points[segment], points[segment + 1]
        u = t / T - segment
        s = 10 * u**3 - 15 * u**4 + 6 * u**5  # minimum jerk, rest to rest
        ds = (30 * u**2 - 60 * u**3 + 30 * u**4) / T
        return a + s * (b - a), ds * (b - a)
    point = trajectory.point if trajectory.point is not None else start
    return np.array(point, dtype=float), np.zeros(3)


def reference_law(
    model: pin.Model,
    data: pin.Data,
    contacts: Sequence[ContactSpec],
    tasks: Sequence[Task],
    f_nd: np.ndarray,
    q: np.ndarray,
    dq: np.ndarray,
    mode: str,
    motors: Motors,
    damping: np.ndarray,
    K_V: np.ndarray,
    gravity_compensation: bool,
    null_space: str,
    slip_epsilon: float,
) -> tuple[np.ndarray, np.ndarray]:
    """(command, tau) of eqs. 36-41 at the measured (q, dq):

    B = J_c Mc^-1,  A = B (J_c - mu J_t)^T,  a = B (h + g + Dc dq) - gamma
    tau = B^+ (a - A f_nd) + (I - B^+ B) l,   l = sum over tasks of J^T [Kp (r_d - r) + Kd (dr_d - dr)]
    command = K_V tau (voltage) | tau (torque)
    """
    n = model.nv
    _, J_m, D_m = reflected(motors)
    if mode == "voltage":
        Mc, Dc = mass_matrix(model, data, q) + np.diag(J_m), np.diag(damping + D_m)
    else:
        Mc, Dc = mass_matrix(model, data, q), np.diag(damping)
    h_plus_g = pin.nonLinearEffects(model, data, q, dq).copy()
    rows = contact_rows(model, data, contacts, q, dq, slip_epsilon)

    task_torque = np.zeros(n)  # l of eq. 39
    for task in tasks:
        frame = model.getFrameId(task.frame)
        r = data.oMf[frame].translation
        J = pin.getFrameJacobian(model, data, frame, WORLD)[:3]
        dr = J @ dq
        F = np.zeros(3)
        for axis, kp, kd in zip(task.axes, task.kp, task.kd, strict=True):
            F[axis] = kp * (task.target[axis] - r[axis]) + kd * (task.target_velocity[axis] - dr[axis])
        task_torque += J.T @ F
    if gravity_compensation:
        task_torque += pin.computeGeneralizedGravity(model, data, q)

    if contacts:
        mu = np.diag([c.mu for c in contacts])
        B = rows.J_c @ np.linalg.inv(Mc)
        A = B @ (rows.J_c - mu @ rows.J_t).T
        a = B @ (h_plus_g + Dc @ dq) - rows.drift
        if null_space == "dynamically_consistent":
            B_inv = rows.J_c.T @ np.linalg.inv(rows.J_c @ np.linalg.inv(Mc) @ rows.J_c.T)
        else:
            B_inv = np.linalg.pinv(B)
        tau = B_inv @ (a - A @ f_nd) + (np.eye(n) - B_inv @ B) @ task_torque
    else:
        tau = task_torque
    command = K_V * tau if mode == "voltage" else tau
    return command, tau
