"""Controller core (docs/model.md, Control law; paper eqs. 36-41): the force law, its null-space
projection, the reduction to tau = l without bracing, the paper's bracing claims,
configuration errors and near-singular B.

B, A, a and l are recomputed here from pinocchio directly (own Model/Data from the URDF)
and from the scenario's parameters, not read back from the controller.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from bracing_core.controller_config import ControllerConfig
from bracing_core.law import DecoupledController
from bracing_core.params import ConfigError

REPO_ROOT = Path(__file__).resolve().parents[1]
CONFIG_DIR = REPO_ROOT / "config"
PAPER_URDF = CONFIG_DIR / "paper_4link.urdf"
WORLD = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
N = 4
LINK_DAMPING = 2.0
PAPER_Q0 = np.array([-0.2, -0.6, 0.8, -0.4]) * math.pi


class Reference:
    """Pinocchio on its own Model/Data: M (+ J_m), h + g, frame Jacobians, drifts."""

    def __init__(self, rotor_inertia: np.ndarray | None = None) -> None:
        self.model = pin.buildModelFromUrdf(str(PAPER_URDF))
        self.model.gravity.linear = np.array([0.0, 0.0, -9.81])
        self.data = self.model.createData()
        self.added = np.zeros(N) if rotor_inertia is None else rotor_inertia

    def at(self, q: np.ndarray, dq: np.ndarray) -> Reference:
        model, data = self.model, self.data
        mass = pin.crba(model, data, q)
        self.mass = np.triu(mass) + np.triu(mass, 1).T + np.diag(self.added)
        self.nle = pin.nonLinearEffects(model, data, q, dq).copy()
        pin.computeJointJacobians(model, data, q)
        pin.forwardKinematics(model, data, q, dq, np.zeros(N))  # a = 0: drifts
        pin.updateFramePlacements(model, data)
        return self

    def position(self, frame: str) -> np.ndarray:
        return self.data.oMf[self.model.getFrameId(frame)].translation.copy()

    def jacobian(self, frame: str) -> np.ndarray:
        return pin.getFrameJacobian(self.model, self.data, self.model.getFrameId(frame), WORLD)[:3].copy()

    def drift(self, frame: str) -> np.ndarray:
        frame_id = self.model.getFrameId(frame)
        return pin.getFrameClassicalAcceleration(self.model, self.data, frame_id, WORLD).linear.copy()


def paper_circle(t: float) -> tuple[np.ndarray, np.ndarray]:
    """The paper's hand path: y = 1.1 + 0.2 cos(-2 pi t / 10), z = 0.6 + 0.2 sin(-2 pi t / 10)."""
    w = -2.0 * math.pi / 10.0
    return (
        np.array([0.0, 1.1 + 0.2 * math.cos(w * t), 0.6 + 0.2 * math.sin(w * t)]),
        np.array([0.0, -0.2 * w * math.sin(w * t), 0.2 * w * math.cos(w * t)]),
    )


def controller_for(paper_params: Callable, shared: dict | None = None, own: dict | None = None) -> DecoupledController:
    params = paper_params("bracing_controller", shared, own)
    return DecoupledController(ControllerConfig.from_params(params, [CONFIG_DIR]))


def rotor_inertia_of(params: dict) -> np.ndarray:
    return np.array(params["motors.rotor_inertia"]) * np.array(params["motors.gear_ratio"]) ** 2


# -- 1. torque input: f_n == f_nd every step ----------------------------------------------
TILT = 0.3  # [rad]
# A floor sloped by TILT through the elbow's start. On the paper floor the constraint is
# linear in q (2 q1 + q2 = -pi, equal link lengths), so gamma = 0 along the motion; the
# sloped floor makes gamma != 0 and tests that term of eq. 37 as well.
SLOPED_FLOOR = {
    "contacts.elbow.normal": [0.0, math.sin(TILT), math.cos(TILT)],
    "contacts.elbow.offset": math.sin(TILT) * 0.5877852522924731,
}


@pytest.mark.parametrize("plane", ["paper_floor", "sloped_floor"])
@pytest.mark.parametrize("friction", [0.0, 0.1, 0.3])
@pytest.mark.parametrize("force", [5.0, 10.0, 20.0])
def test_torque_input_force_is_exact_every_step(force: float, friction: float, plane: str, scenario: Callable) -> None:
    sc = scenario(
        {
            "input_mode": "torque",
            "contacts.elbow.friction": friction,
            "contacts.elbow.desired_normal_force": force,
            **(SLOPED_FLOOR if plane == "sloped_floor" else {}),
        }
    )
    sim, controller = sc.sim, sc.controller
    assert controller is not None
    errors, hand = [], []
    for _ in range(1000):  # 1 s
        out = controller.update(sim.time, sim.position, sim.velocity)
        d = sim.step(out.command)
        errors.append(abs(float(d.normal_force[0]) - force))
        hand.append(float(np.linalg.norm(out.hand_desired - out.hand_actual)))
    worst = max(errors)
    print(
        f"\n{plane}, f_nd = {force:g} N, mu = {friction:g}: max |f_n - f_nd| = {worst:.3g} N, "
        f"final hand error {hand[-1]:.4f} m"
    )
    assert worst < 1e-9
    assert np.all(np.isfinite(sim.position)) and hand[-1] < hand[0]  # the position task proceeds meanwhile


# -- 2. the null-space projector ----------------------------------------------------------
TWO_CONTACTS = {
    "contacts.names": ["elbow", "tip"],
    "contacts.tip.frame": "hand",
    "contacts.tip.normal": [0.0, 0.6, 0.8],
    "contacts.tip.offset": 0.0,
    "contacts.tip.friction": 0.2,
    "contacts.tip.desired_normal_force": 4.0,
    "contacts.elbow.brace_axes": [],
    "contacts.elbow.kp": [],
    "contacts.elbow.kd": [],
}


@pytest.mark.parametrize("contacts", ["paper", "two_contacts"])
@pytest.mark.parametrize("mode", ["voltage", "torque"])
def test_null_space_projection_leaves_contact_accelerations_alone(
    mode: str, contacts: str, paper_params: Callable
) -> None:
    """B (I - B^+ B) l = 0 and B B^+ = I, B = J_c Mc^-1 from pinocchio; and eq. 38 gives B tau = a - A f_nd
    (the paper's regularised friction: A's slip direction s / sqrt(|s|^2 + eps^2))."""
    shared = {"input_mode": mode, **(TWO_CONTACTS if contacts == "two_contacts" else {})}
    for name in shared.get("contacts.names", ["elbow"]):
        shared[f"contacts.{name}.friction_model"] = "regularized"
    params = paper_params("bracing_controller", shared)
    controller = controller_for(paper_params, shared)
    voltage = mode == "voltage"
    ref = Reference(rotor_inertia_of(params) if voltage else None)
    damping = LINK_DAMPING + (
        np.array(params["motors.gear_damping"]) * np.array(params["motors.gear_ratio"]) ** 2 if voltage else 0.0
    )
    names = params["contacts.names"]
    frames = [params[f"contacts.{c}.frame"] for c in names]
    normals = [np.array(params[f"contacts.{c}.normal"]) / np.linalg.norm(params[f"contacts.{c}.normal"]) for c in names]
    mu = np.array([params[f"contacts.{c}.friction"] for c in names])
    f_nd = np.array([params[f"contacts.{c}.desired_normal_force"] for c in names])
    eps = 1e-4
    rng = np.random.default_rng(7)
    worst_projection = worst_law = 0.0
    for _ in range(25):
        q, dq, l_rand = rng.uniform(-math.pi, math.pi, N), rng.uniform(-2.0, 2.0, N), rng.normal(0.0, 50.0, N)
        ref.at(q, dq)
        jc = np.array([nrm @ ref.jacobian(f) for nrm, f in zip(normals, frames, strict=True)])
        b = jc @ np.linalg.inv(ref.mass)
        b_pinv = np.linalg.pinv(b)
        np.testing.assert_allclose(b @ b_pinv, np.eye(len(names)), atol=1e-9)
        projected = b @ (np.eye(N) - b_pinv @ b) @ l_rand
        worst_projection = max(worst_projection, float(np.abs(projected).max()))
        assert np.abs(projected).max() < 1e-10 * np.linalg.norm(b) * np.linalg.norm(l_rand)
        # eq. 38 with the controller's own output: B tau = a - A f_nd (friction along the regularised slip).
        jt = []
        for nrm, f in zip(normals, frames, strict=True):
            jac = ref.jacobian(f)
            velocity = jac @ dq
            slip = velocity - nrm * (nrm @ velocity)
            jt.append((slip / math.sqrt(slip @ slip + eps**2)) @ jac)
        gamma = np.array([nrm @ ref.drift(f) for nrm, f in zip(normals, frames, strict=True)])
        a_matrix = b @ (jc - mu[:, None] * np.array(jt)).T
        a_vector = b @ (ref.nle + damping * dq) - gamma
        controller.reset()
        out = controller.update(rng.uniform(0.0, 10.0), q, dq)
        assert not out.damped
        residual = b @ out.torque - (a_vector - a_matrix @ f_nd)
        worst_law = max(worst_law, float(np.abs(residual).max()))
        assert np.abs(residual).max() < 1e-8 * max(1.0, float(np.abs(a_vector).max()))
    print(
        f"\n{mode}, {contacts}: max |B (I - B+B) l| = {worst_projection:.3g}, "
        f"max |B tau - (a - A f_nd)| = {worst_law:.3g}"
    )


# -- 3. voltage input: transient force error -----------------------------------------------
def test_voltage_input_force_error_decays(closed_loop: Callable) -> None:
    """The paper's motors (R fixed: ``motors.thermal: false``): the circuit's lag leaves a start-up
    force error that decays. With the windings heating (the default), R(T) grows, the same v drives
    less current than the law's fixed K_V assumes, and the late error is larger."""
    run, warm = closed_loop({"motors.thermal": False}), closed_loop()
    error = np.abs(run.normal_force[:, 0] - run.desired_normal_force[0])
    early, late = error[run.window(0.0, 0.5)], error[run.window(5.0)]
    rms = float(np.sqrt(np.mean(error**2)))
    late_warm = np.abs(warm.normal_force[:, 0] - warm.desired_normal_force[0])[warm.window(5.0)]
    print(
        f"\nvoltage input |f_n - f_nd|: peak {error.max():.3g} N at t = {run.time[int(np.argmax(error))]:.3f} s; "
        f"max {early.max():.3g} N (t < 0.5 s), max {late.max():.3g} N (t >= 5 s); "
        f"RMS {rms:.3g} N over 10 s, {float(np.sqrt(np.mean(late**2))):.3g} N over t >= 5 s; "
        f"with the thermal model {float(np.sqrt(np.mean(late_warm**2))):.3g} N over t >= 5 s"
    )
    assert early.max() > 5.0 * late.max()  # measured 13.8 N vs 1.72 N
    assert run.time[int(np.argmax(error))] < 0.5  # the worst is in the start-up transient (L/R = 0.28 s)
    assert float(np.sqrt(np.mean(late**2))) < 1.0  # measured 0.87 N
    assert np.sqrt(np.mean(late_warm**2)) > 1.5 * np.sqrt(np.mean(late**2))  # measured 1.52 N


# -- 4. no bracing: tau = l ---------------------------------------------------------------
@pytest.mark.parametrize("gravity_compensation", [False, True])
def test_unbraced_command_is_task_torque(gravity_compensation: bool, paper_params: Callable) -> None:
    gains = [0.5, 1.0, 2.0, 4.0]
    controller = controller_for(
        paper_params, {"contacts.names": []}, {"voltage_gain": gains, "gravity_compensation": gravity_compensation}
    )
    ref = Reference()
    rng = np.random.default_rng(3)
    kp, kd = 300.0, 50.0
    for _ in range(20):
        q, dq, t = rng.uniform(-math.pi, math.pi, N), rng.uniform(-2.0, 2.0, N), float(rng.uniform(0.0, 20.0))
        ref.at(q, dq)
        desired, desired_velocity = paper_circle(t)
        jac = ref.jacobian("hand")[1:]  # the y, z rows
        force = kp * (desired[1:] - ref.position("hand")[1:]) + kd * (desired_velocity[1:] - jac @ dq)
        expected = jac.T @ force
        if gravity_compensation:
            expected = expected + pin.computeGeneralizedGravity(ref.model, ref.data, q)
        out = controller.update(t, q, dq)
        np.testing.assert_allclose(out.torque, expected, rtol=1e-12, atol=1e-9)
        np.testing.assert_allclose(out.command, np.array(gains) * expected, rtol=1e-12, atol=1e-9)
        np.testing.assert_allclose(out.hand_desired, desired, atol=1e-12)
        assert not out.damped and controller.desired_normal_force.shape == (0,)


# -- 5. the paper's claim: bracing lowers energy and hand error ----------------------------
def test_bracing_lowers_energy_and_hand_error(closed_loop: Callable) -> None:
    braced, free = closed_loop(), closed_loop({"contacts.names": []})
    rms = {
        name: float(np.sqrt(np.mean(run.hand_error[run.window(2.0)] ** 2)))
        for name, run in (("braced", braced), ("unbraced", free))
    }
    print(
        f"\nbraced: hand RMS (t >= 2 s) {rms['braced']:.4f} m, consumed {braced.energy.consumed:.1f} J; "
        f"unbraced: {rms['unbraced']:.4f} m, {free.energy.consumed:.1f} J"
    )
    assert braced.energy.consumed < 0.8 * free.energy.consumed  # measured 3150 J vs 10932 J
    assert rms["braced"] < 0.9 * rms["unbraced"]  # measured 0.0506 m vs 0.0755 m
    assert braced.energy.consumed > 0.0 and np.all(np.isfinite(free.final_position))


# -- 6. configuration errors ---------------------------------------------------------------
def test_task_dimension_above_n_minus_p_is_rejected(ctl_params: dict) -> None:
    ctl_params.update(
        {
            "contacts.elbow.brace_axes": ["y", "z"],
            "contacts.elbow.kp": [100.0, 100.0],
            "contacts.elbow.kd": [20.0, 20.0],
        }
    )
    with pytest.raises(ConfigError, match=r"n - p") as info:
        ControllerConfig.from_params(ctl_params, [CONFIG_DIR])
    assert "4" in str(info.value) and "3" in str(info.value)


def test_task_dimension_equal_to_n_minus_p_is_accepted(ctl_params: dict) -> None:
    ControllerConfig.from_params(ctl_params, [CONFIG_DIR])  # 2 + 1 = 4 - 1
    ctl_params["contacts.names"] = []  # 2 <= 4
    ControllerConfig.from_params(ctl_params, [CONFIG_DIR])


def test_unknown_contact_frame_is_named(ctl_params: dict) -> None:
    ctl_params["contacts.elbow.frame"] = "no_such_elbow"
    with pytest.raises(ConfigError, match="no_such_elbow"):
        DecoupledController(ControllerConfig.from_params(ctl_params, [CONFIG_DIR]))


def test_unknown_hand_frame_is_a_config_error(ctl_params: dict) -> None:
    ctl_params["hand.frame"] = "no_such_hand"
    try:
        DecoupledController(ControllerConfig.from_params(ctl_params, [CONFIG_DIR]))
    except ConfigError as exc:
        assert "no_such_hand" in str(exc) and "hand.frame" in str(exc)
    except ValueError as exc:
        raise AssertionError(f"{type(exc).__name__} instead of ConfigError: {exc}") from exc
    else:
        raise AssertionError("no error for an unknown hand.frame")


@pytest.mark.parametrize(
    "name, value, expected",
    [
        ("hand.kp", [300.0], "hand.kp"),
        ("hand.kd", [50.0, 50.0, 50.0], "hand.kd"),
        ("contacts.elbow.kp", [100.0, 1.0], "contacts.elbow.kp"),
        ("voltage_gain", [1.0, 1.0], "voltage_gain"),
        ("hand.gain", 3.0, "unknown parameter"),
        ("contacts.elbow.stiffness", 3.0, "unknown parameter"),
    ],
)
def test_bad_parameters_are_named(name: str, value: object, expected: str, ctl_params: dict) -> None:
    ctl_params[name] = value
    with pytest.raises(ConfigError, match=expected) as info:
        ControllerConfig.from_params(ctl_params, [CONFIG_DIR])
    assert name in str(info.value)


# -- 7. near-singular B ----------------------------------------------------------------------
def test_zero_contact_jacobian_is_damped_and_bounded(paper_params: Callable) -> None:
    """A plane x = 0 (normal perpendicular to the motion plane): J_c = 0, so B = 0 and tau = l (the
    regularised law's path: a Coulomb contact at rest would be a point constraint, and J_c = 0 is one a
    run refuses at the start)."""
    shared = {"contacts.elbow.normal": [1.0, 0.0, 0.0], "contacts.elbow.friction_model": "regularized"}
    controller = controller_for(paper_params, shared)
    ref = Reference(rotor_inertia_of(paper_params("bracing_controller")))
    brace_target = ref.at(PAPER_Q0, np.zeros(N)).position("elbow")
    rng = np.random.default_rng(11)
    states = [(PAPER_Q0, np.zeros(N))] + [(rng.uniform(-math.pi, math.pi, N), rng.uniform(-2, 2, N)) for _ in range(10)]
    for k, (q, dq) in enumerate(states):
        t = 0.1 * k
        out = controller.update(t, q, dq)  # the first call takes the brace target from PAPER_Q0
        assert out.damped
        assert np.all(np.isfinite(out.command)) and np.all(np.isfinite(out.torque))
        ref.at(q, dq)
        desired, desired_velocity = paper_circle(t)
        hand_jac, elbow_jac = ref.jacobian("hand"), ref.jacobian("elbow")
        hand_force = 300.0 * (desired - ref.position("hand"))[1:] + 50.0 * (desired_velocity - hand_jac @ dq)[1:]
        brace_force = 100.0 * (brace_target - ref.position("elbow"))[1] - 20.0 * (elbow_jac @ dq)[1]
        task = hand_jac[1:].T @ hand_force + elbow_jac[1] * brace_force
        np.testing.assert_allclose(out.torque, task, rtol=1e-9, atol=1e-9)
    assert float(np.abs(controller.update(0.0, PAPER_Q0, np.zeros(N)).command).max()) < 200.0


def test_nearly_dependent_contacts_are_damped_and_bounded(paper_params: Callable) -> None:
    """Two planes through the elbow with normals 1e-10 rad apart: B has two nearly equal rows."""
    tilt = 1e-10
    shared = {
        "contacts.names": ["elbow", "twin"],
        "contacts.twin.frame": "elbow",
        "contacts.twin.normal": [0.0, math.sin(tilt), math.cos(tilt)],
        "contacts.twin.offset": math.sin(tilt) * 0.5877852522924731,
        "contacts.twin.friction": 0.1,
        "contacts.twin.desired_normal_force": 5.0,
        "contacts.elbow.brace_axes": [],
        "contacts.elbow.kp": [],
        "contacts.elbow.kd": [],
    }
    controller = controller_for(paper_params, shared)
    rng = np.random.default_rng(5)
    worst = 0.0
    for q, dq in [(PAPER_Q0, np.zeros(N))] + [
        (rng.uniform(-math.pi, math.pi, N), rng.uniform(-2, 2, N)) for _ in range(10)
    ]:
        out = controller.update(1.0, q, dq)
        assert out.damped
        assert np.all(np.isfinite(out.command))
        worst = max(worst, float(np.abs(out.command).max()))
    print(f"\nnearly dependent contacts: max |command| = {worst:.3g} V")
    assert worst < 1e4
