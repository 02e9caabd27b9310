"""summary.json's per-contact metrics (``contacts``), ``max_penetration_m``, ``input_mode`` and
``bracing``; the brace plots along each axis the brace moves; make run's three-way table.

Series built by hand or bags written here, so that every expected number is known exactly; both
read paths (``bag.read_series``, column-wise, and ``reference_series``, rosbags' per-message decoding)
must give the same summary.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import reference_series
from test_columns import JOINTS, BagBuilder, same_series

from bracing_analysis.axes import BRACE_MOVES_M, brace_axes
from bracing_analysis.bag import read_series
from bracing_analysis.drawing import file_names, report_series
from bracing_analysis.series import BagSeries, ContactSeries
from bracing_analysis.summary import CONTACT_KEYS, SUMMARY_EXTRA_KEYS, SUMMARY_KEYS, compute_summary, format_summary
from bracing_bringup.paper_run import table

DT = 0.01
OBSTACLE = "box"  # a scenario contact without a desired force: reported by the simulator, not braced
KEPT_OUT = "link3_tip@floor"  # a collision frame kept above the floor's surface (contact_roles: kept_out)


def _time(n: int = 201) -> np.ndarray:
    return np.arange(n) * DT


def _braced(t: np.ndarray, name: str = "elbow") -> ContactSeries:
    """A braced contact, always active, at rest: brace error 0.003 m, force error +-1 N, f_n 11 / 9 N."""
    n = t.size
    cs = ContactSeries(name=name, t=t.copy(), t_ctrl=t.copy(), t_matched=t.copy())
    cs.active = np.ones(n, dtype=bool)
    cs.normal_force = np.where(np.arange(n) % 2 == 0, 11.0, 9.0)
    cs.normal_force_desired = np.full(n, 10.0)
    cs.normal_force_error = cs.normal_force - 10.0
    cs.residual = np.full(n, 1e-9)
    cs.slip_velocity = np.zeros((n, 3))
    cs.brace_desired = np.tile([0.0, 0.5, 0.0], (n, 1))
    cs.brace_actual = np.tile([0.0, 0.503, 0.0], (n, 1))
    return cs


def _obstacle(t: np.ndarray, touching: np.ndarray, residual: np.ndarray, name: str = OBSTACLE) -> ContactSeries:
    """A contact the controller does not name: simulator data only."""
    cs = ContactSeries(name=name, t=t.copy(), active=touching.copy(), residual=residual.copy())
    cs.normal_force = np.where(touching, 4.0, 0.0)
    cs.slip_velocity = np.zeros((t.size, 3))
    return cs


def _series(t: np.ndarray, *contacts: ContactSeries, controller: bool = True) -> BagSeries:
    s = BagSeries(joint_t=t.copy(), input_mode="torque")
    if controller:
        s.t = t.copy()
        s.hand_desired = s.hand_actual = np.zeros((t.size, 3))
    s.contacts = {c.name: c for c in contacts}
    return s


# --------------------------------------------------------------------------- per-contact metrics


def test_constant_slip_speed_integrates_to_speed_times_duration() -> None:
    t = _time()  # 2 s
    cs = _braced(t)
    cs.slip_velocity = np.tile([0.03, 0.04, 0.0], (t.size, 1))  # |s| = 0.05 m/s
    out = compute_summary(_series(t, cs))
    assert out["contacts"]["elbow"]["slip_m"] == pytest.approx(0.05 * 2.0, rel=1e-12)

    # Active for t <= 1 s only: the trapezoid rule counts 1 s and half of the interval to lift-off.
    cs.active = t <= 1.0 + 1e-9
    metrics = compute_summary(_series(t, cs))["contacts"]["elbow"]
    assert metrics["slip_m"] == pytest.approx(0.05 * (1.0 + DT / 2), rel=1e-12)
    assert metrics["active_fraction"] == pytest.approx(101 / 201)


def test_braced_contact_metrics() -> None:
    t = _time()
    cs = _braced(t)
    cs.residual = np.linspace(-3e-6, 1e-6, t.size)
    metrics = compute_summary(_series(t, cs))["contacts"]["elbow"]
    assert list(metrics) == list(CONTACT_KEYS)
    assert metrics["braced"] is True
    assert metrics["normal_force_rms_error_n"] == pytest.approx(1.0)
    assert metrics["brace_rms_error_m"] == pytest.approx(0.003)
    assert metrics["normal_force_mean_n"] == pytest.approx((101 * 11.0 + 100 * 9.0) / 201)
    assert metrics["normal_force_max_n"] == 11.0
    assert metrics["slip_m"] == 0.0
    assert metrics["residual_max_m"] == pytest.approx(3e-6)
    assert metrics["active_fraction"] == 1.0
    assert metrics["penetration_m"] == pytest.approx(3e-6)


def test_unbraced_contact_has_no_errors_and_stays_out_of_the_brace_totals() -> None:
    t = _time()
    touching = (t > 0.5) & (t < 1.0)
    residual = np.where(touching, -2e-4, 0.3)  # resting on the floor 2e-4 m deep, else 0.3 m above it
    residual[150] = -5e-4  # inactive and below the floor (an inelastic touchdown's step): still penetration
    out = compute_summary(_series(t, _braced(t), _obstacle(t, touching, residual)))

    assert list(out) == [*SUMMARY_KEYS, *SUMMARY_EXTRA_KEYS]
    assert list(out["contacts"]) == ["elbow", OBSTACLE]
    obstacle = out["contacts"][OBSTACLE]
    assert obstacle["braced"] is False
    assert obstacle["normal_force_rms_error_n"] is None and obstacle["brace_rms_error_m"] is None
    assert obstacle["normal_force_mean_n"] == obstacle["normal_force_max_n"] == 4.0  # over the active samples only
    assert obstacle["residual_max_m"] == pytest.approx(2e-4)  # the 0.3 m while away does not count
    assert obstacle["active_fraction"] == pytest.approx(touching.mean())
    assert obstacle["penetration_m"] == pytest.approx(5e-4)
    # The totals: errors of the braced contact only, the residual of every contact while active.
    assert out["brace_rms_error_m"] == pytest.approx(0.003)
    assert out["normal_force_rms_error_n"] == pytest.approx(1.0)
    assert out["constraint_residual_max_m"] == pytest.approx(2e-4)
    assert out["max_penetration_m"] == pytest.approx(5e-4)
    assert out["input_mode"] == "torque" and out["bracing"] is True
    json.dumps(out, allow_nan=False)


def test_kept_out_frames_are_reported_apart_from_the_contacts() -> None:
    """A collision frame's pseudo-contact (``<frame>@<contact>``) is under kept_out with the same metrics, not
    under contacts; the penetration and residual totals count it; a run without any has kept_out null."""
    t = _time()
    touching = (t > 0.5) & (t < 1.0)
    residual = np.where(touching, -2e-4, 0.3)
    residual[150] = -7e-4  # the deepest of the run: a kept-out frame's
    kept_out = _obstacle(t, touching, residual, KEPT_OUT)
    alone = compute_summary(_series(t, _braced(t), _obstacle(t, touching, np.where(touching, -1e-4, 0.3))))
    out = compute_summary(_series(t, _braced(t), _obstacle(t, touching, np.where(touching, -1e-4, 0.3)), kept_out))

    assert list(out) == [*SUMMARY_KEYS, *SUMMARY_EXTRA_KEYS]
    assert list(out["contacts"]) == ["elbow", OBSTACLE] and list(out["kept_out"]) == [KEPT_OUT]
    assert out["contacts"] == alone["contacts"]  # the scenario's contacts' numbers as without the frame
    frame = out["kept_out"][KEPT_OUT]
    assert list(frame) == list(CONTACT_KEYS) and frame["braced"] is False
    assert frame["normal_force_mean_n"] == 4.0 and frame["active_fraction"] == pytest.approx(touching.mean())
    assert frame["penetration_m"] == pytest.approx(7e-4)
    assert out["max_penetration_m"] == pytest.approx(7e-4)  # over both roles
    assert out["constraint_residual_max_m"] == pytest.approx(2e-4)  # the frame's, while it touched
    assert alone["kept_out"] is None  # nothing kept out: does not apply
    assert "kept_out.link3_tip@floor.penetration_m" in format_summary(out)


def test_run_without_braced_contacts_has_null_totals() -> None:
    t = _time()
    never = np.zeros(t.size, dtype=bool)
    out = compute_summary(_series(t, _obstacle(t, never, np.full(t.size, 0.2))))
    assert out["brace_rms_error_m"] is None and out["normal_force_rms_error_n"] is None  # no brace task
    assert out["constraint_residual_max_m"] is None  # never held
    assert out["bracing"] is False
    metrics = out["contacts"][OBSTACLE]
    assert metrics["normal_force_mean_n"] is None and metrics["normal_force_max_n"] is None
    assert metrics["residual_max_m"] is None
    assert metrics["slip_m"] == 0.0 and metrics["active_fraction"] == 0.0 and metrics["penetration_m"] == 0.0
    assert out["max_penetration_m"] == 0.0


def test_run_without_contacts_or_controller() -> None:
    t = _time()
    out = compute_summary(_series(t))
    assert out["contacts"] == {} and out["max_penetration_m"] is None and out["bracing"] is False
    assert out["brace_rms_error_m"] is out["normal_force_rms_error_n"] is out["constraint_residual_max_m"] is None
    out = compute_summary(_series(t, controller=False))
    assert out["bracing"] is None  # no controller_state recorded: unknown
    assert compute_summary(BagSeries())["input_mode"] is None


def test_series_without_slip_velocities_has_no_slip() -> None:
    """A series not read from a bag (e.g. an in-process run's) may lack them: null, not 0."""
    t = _time()
    cs = _braced(t)
    cs.slip_velocity = np.zeros((0, 3))
    assert compute_summary(_series(t, cs))["contacts"]["elbow"]["slip_m"] is None


def test_format_summary_prints_a_line_per_contact_metric() -> None:
    t = _time()
    text = format_summary(compute_summary(_series(t, _braced(t))))
    lines = dict(line.split(maxsplit=1) for line in text.splitlines())
    assert lines["contacts.elbow.braced"] == "True"
    assert float(lines["contacts.elbow.brace_rms_error_m"]) == pytest.approx(0.003)
    assert lines["contacts.elbow.slip_m"] == "0"
    assert lines["input_mode"] == "torque" and lines["wall_time_s"] == "n/a"
    assert "contacts" in format_summary(compute_summary(_series(t)))  # an empty contacts dict still shows


# --------------------------------------------------------------------------- read from bags, both paths


def _known_bag(path: Path, mode: int) -> Path:
    """0.5 s at 10 ms: the elbow braced and sliding at 0.02 m/s along y; an obstacle that touches
    down at 0.2 s, 1e-4 m deep, and never slides; motor commands in ``mode``."""
    b = BagBuilder()
    state = b.store.types["bracing_msgs/msg/ContactState"]
    command = b.store.types["bracing_msgs/msg/MotorCommand"]
    for k in range(51):
        ns = k * 10_000_000
        b.v = k
        b.joint(ns, JOINTS)
        touching = k >= 20
        depth = -1e-4 if touching else 0.1
        elbow = state(
            name="elbow",
            frame="link2_tip",
            active=True,
            position=b.point(0, 0.5 + 2e-4 * k, 0),
            normal=b.vector(0, 0, 1),
            normal_force=10.0,
            friction_force=1.0,
            slip_velocity=b.vector(0, 0.02, 0),
            residual=0.0,
        )
        other = state(
            name=OBSTACLE,
            frame="link3_tip",
            active=touching,
            position=b.point(0, 0.8, depth),
            normal=b.vector(0, 0, 1),
            normal_force=3.0 if touching else 0.0,
            friction_force=0.0,
            slip_velocity=b.vector(0, 0, 0),
            residual=depth,
        )
        contacts = b.store.types["bracing_msgs/msg/Contacts"](b.header(ns), [elbow, other])
        b.add("/contacts", "bracing_msgs/msg/Contacts", contacts)
        b.controller(ns, ["elbow"], forces=1, braces=1)
        b.add("/motor_command", "bracing_msgs/msg/MotorCommand", command(b.header(ns), mode, JOINTS, np.zeros(4)))
    return b.write(path)


@pytest.mark.parametrize(("mode", "name"), [(0, "voltage"), (1, "torque")])
def test_known_bag_read_both_ways(tmp_path: Path, mode: int, name: str) -> None:
    bag = _known_bag(tmp_path / "bag", mode)
    general, columnar = reference_series.read_series(bag), read_series(bag)
    same_series(general, columnar)  # slip_velocity and input_mode included
    out = compute_summary(columnar)
    assert json.dumps(compute_summary(general)) == json.dumps(out)
    assert out["input_mode"] == name and out["bracing"] is True
    elbow, obstacle = out["contacts"]["elbow"], out["contacts"][OBSTACLE]
    assert elbow["braced"] is True and obstacle["braced"] is False
    assert elbow["slip_m"] == pytest.approx(0.02 * 0.5, rel=1e-12)
    assert obstacle["slip_m"] == 0.0 and obstacle["normal_force_rms_error_n"] is None
    assert obstacle["active_fraction"] == pytest.approx(31 / 51)
    assert obstacle["penetration_m"] == pytest.approx(1e-4) and out["max_penetration_m"] == pytest.approx(1e-4)


def test_rclpy_serialized_bag_both_ways(tmp_path: Path) -> None:
    """The recorder tests' synthetic bag (messages serialized by rclpy): slip speed 1e-3 k m/s at
    t = k DT, so the trapezoid rule is exact: slip = slope T^2 / 2."""
    from test_recorder_report import DT as STEP
    from test_recorder_report import write_bag_directly

    n = 60
    write_bag_directly(tmp_path / "bag", n, ("elbow", "wrist"))
    general, columnar = reference_series.read_series(tmp_path / "bag"), read_series(tmp_path / "bag")
    same_series(general, columnar)
    out = compute_summary(columnar)
    assert json.dumps(compute_summary(general)) == json.dumps(out)
    duration = (n - 1) * STEP
    for name in ("elbow", "wrist"):
        assert out["contacts"][name]["slip_m"] == pytest.approx(1e-3 / STEP * duration**2 / 2, rel=1e-9)
    assert out["input_mode"] == "voltage"


def test_recorded_run_both_ways(runs: dict[str, Path]) -> None:
    """A real pair run's bag (the session's short braced run): both read paths, one summary."""
    bag = runs["braced"] / "bag"
    general, columnar = compute_summary(reference_series.read_series(bag)), compute_summary(read_series(bag))
    assert json.dumps(general["contacts"]) == json.dumps(columnar["contacts"])
    assert general["input_mode"] == columnar["input_mode"] in ("voltage", "torque")
    assert columnar["contacts"]["elbow"]["braced"] is True and columnar["bracing"] is True


# --------------------------------------------------------------------------- brace plots per moving axis


def test_brace_axes_follow_the_brace_points_movement() -> None:
    t = _time()
    still = _braced(t)
    assert brace_axes(_series(t, still)) == ["y"]  # desired 0.5 and actual 0.503: the plot shows the offset
    still.brace_actual = still.brace_desired.copy()
    assert brace_axes(_series(t, still)) == []
    moving = _braced(t, "wrist")
    moving.brace_desired = np.stack([0.1 * t, np.zeros(t.size), np.full(t.size, 0.2)], axis=1)
    moving.brace_actual = moving.brace_desired + np.array([0.0, BRACE_MOVES_M / 2, 0.0])
    assert brace_axes(_series(t, still, moving)) == ["x"]  # y: within the threshold, z: held
    # An obstacle slides along z: not braced, no brace plot.
    obstacle = _obstacle(t, np.ones(t.size, dtype=bool), np.zeros(t.size))
    obstacle.position = np.stack([np.zeros(t.size), np.zeros(t.size), t], axis=1)
    series = _series(t, still, moving, obstacle)
    assert brace_axes(series) == ["x"]
    assert file_names(series, animation=False) == ["hand_y", "hand_z", "brace_x", "normal_force"]


def test_report_draws_a_brace_plot_per_moving_axis(tmp_path: Path) -> None:
    t = _time(51)
    cs = _braced(t)
    cs.brace_desired = np.stack([0.1 * t, np.full(t.size, 0.5), 0.2 * t], axis=1)
    cs.brace_actual = cs.brace_desired.copy()
    summary = report_series(_series(t, cs), tmp_path, parallel=False)
    assert sorted(p.name for p in tmp_path.glob("brace_*.png")) == ["brace_x.png", "brace_z.png"]
    assert json.loads((tmp_path / "summary.json").read_text()) == summary


# --------------------------------------------------------------------------- make run's table


def _summary(energy: float, hand: float) -> dict[str, Any]:
    return {"energy_consumed_j": energy, "hand_rms_error_m": hand, "max_penetration_m": None}


def test_paper_table_has_three_columns_and_both_ratios() -> None:
    text = table({"braced": _summary(30.0, 0.01), "passive": _summary(60.0, 0.04), "free_space": _summary(100.0, 0.02)})
    lines = text.splitlines()
    assert lines[0].split() == ["braced", "passive", "free", "space"]
    penetration = next(line for line in lines if line.startswith("max penetration [m]"))
    assert penetration.split()[-3:] == ["n/a"] * 3
    assert "energy ratio braced / free space: 0.300" in lines
    assert "hand RMS error ratio braced / free space: 0.500" in lines
    assert "energy ratio braced / passive: 0.500" in lines
    assert "hand RMS error ratio braced / passive: 0.250" in lines
