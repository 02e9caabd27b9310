"""The summary table of a recorded run (``summary.json``; no rclpy needed).

``compute_summary(series, wall_time_s)`` returns the ``summary.json`` dict of a ``series.BagSeries``
(keys: README, Topics and messages): SUMMARY_KEYS, then SUMMARY_EXTRA_KEYS (per-contact metrics
``contact_metrics`` of the scenario's contacts, ``contacts``, and of the frames and links kept out of
the surfaces, ``kept_out`` (``bracing_core.contact_roles``), the input mode, whether the controller
braced, the run's ``warnings``, the targets the controller refused per topic, ``targets_refused``). A metric
that does not apply to the run is None (null): the brace and force errors of a run with no braced
contact, the copper loss of a torque-input run (no motor circuit), the constraint residual of a run
where no contact ever held.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from bracing_analysis.series import BagSeries, ContactSeries, FloatArray
from bracing_core import checks
from bracing_core.contact_roles import BRACED, KEPT_OUT, by_role
from bracing_core.failures import succeeded

HAND_ERROR_T_MIN_S = 2.0
"""Hand errors are taken over t >= this [s] (after the initial transient)."""
WINDOWED_KEYS = ("hand_rms_error_m", "hand_max_error_m", "hand_orientation_rms_error_rad")
"""summary.json's metrics taken over t >= HAND_ERROR_T_MIN_S only: null for a run no longer than that, and over
the run's last (duration - HAND_ERROR_T_MIN_S) s otherwise (the output reference and the studies' reports say so)."""

SUMMARY_KEYS = (
    "hand_rms_error_m",
    "hand_max_error_m",
    "brace_rms_error_m",
    "normal_force_rms_error_n",
    "energy_consumed_j",
    "copper_loss_j",
    "constraint_residual_max_m",
    "sim_time_s",
    "wall_time_s",
    "real_time_factor",
)
SUMMARY_EXTRA_KEYS = (
    "contacts",
    "max_penetration_m",
    "input_mode",
    "bracing",
    "warnings",
    "motor_temperature_max_c",
    "motor_temperature_max_c_by_joint",
    "targets_refused",
    "saturation_fraction",
    "hand_orientation_rms_error_rad",
    "status",
    "error",
    "hint",
    "kept_out",
    "base_travel_m",
    "base_rolling_residual_max_m_s",
    "link_penetration_max_m",
)
"""summary.json's keys after SUMMARY_KEYS (added later: tools that read SUMMARY_KEYS by position keep working)."""

LABELS: dict[str, str] = {
    "hand_rms_error_m": "hand RMS error (t >= 2 s)",
    "hand_max_error_m": "hand max error (t >= 2 s)",
    "brace_rms_error_m": "brace RMS error",
    "normal_force_rms_error_n": "normal force RMS error",
    "energy_consumed_j": "energy consumed",
    "copper_loss_j": "copper loss",
    "motor_temperature_max_c": "hottest motor max temp",
    "constraint_residual_max_m": "max constraint residual",
    "sim_time_s": "sim time",
    "wall_time_s": "wall time",
    "real_time_factor": "real-time factor",
    "max_penetration_m": "max penetration",
    "input_mode": "input mode",
}
"""The metrics' names in the tables that set runs side by side (compare.md, make run's)."""
UNITS = {"m": "m", "n": "N", "j": "J", "s": "s", "c": "degC"}
"""The units of summary.json's keys, by their names' suffix (``_m``, ``_n``, ...)."""


def heading(key: str) -> tuple[str, str]:
    """``key``'s label in a table (LABELS, or the key itself) and its unit ("" where its name has none)."""
    return LABELS.get(key, key), UNITS.get(key.rpartition("_")[2], "")


OUTCOME_KEYS_DOC = (
    "`status` is `ok` for a run that ran to its end, `failed` for one the simulator stopped (a divergence: "
    "bracing-pair exits 3) or a node's exception ended (its per-state path's on rcl, or its loop's: exit 1); "
    "a failed run still writes every key, measured up to the failure, and its bag holds every state up to it. "
    "`error` (null for ok): what stopped it, the joints that ran away (their speed 0.05 s before the failure "
    "and at it) and, near a singular posture, the joints along the tasks' lost direction; or the node, where "
    "its exception was raised and its message (rcl's, for an rcl error). `hint` (or null): what to change, for "
    "a known cause (`bracing_core.failures`): a joint at its limit that no task sees (`null_space_posture`), a "
    "target out of reach, a singular posture, a stiff motor circuit (`substeps`), a braced contact lost under "
    "force feedback (its `force_feedback` gains); an ok run carries the hint of a target out of reach or a "
    "contact lost under force feedback when its warnings name them. An in-process run gives the same three "
    "(`bracing_core.rollout.run_recorded(..., keep_failure=True)`)."
)
"""What summary.json's status, error and hint mean (the output reference's text)."""

KEPT_OUT_DOC = (
    "`contacts` holds the scenario's own contacts (`contacts.<name>`: braced or obstacle), `kept_out` the frames "
    "of `robot.collision_frames` and the links of `robot.collision_links` kept on the free side of each surface, "
    "one entry per frame or link and surface, named `<frame or link>@<contact>` (the contact whose surface it "
    "is), with the same keys (`braced` false); `kept_out` is null when the scenario keeps nothing out. "
    "`max_penetration_m` and `constraint_residual_max_m` count both (`bracing_core.contact_roles`)."
)
"""What summary.json's contacts and kept_out hold (the output reference's text)."""

CONTACT_KEYS = (
    "braced",
    "normal_force_rms_error_n",
    "brace_rms_error_m",
    "normal_force_mean_n",
    "normal_force_max_n",
    "slip_m",
    "residual_max_m",
    "active_fraction",
    "penetration_m",
)
"""The keys of each contact in summary.json's ``contacts`` (``contact_metrics``)."""


def _rms(values: FloatArray) -> float:
    return float(np.sqrt(np.mean(np.square(values))))


def _braced(cs: ContactSeries) -> bool:
    """The controller keeps a desired force on the contact (it names it in controller_state)."""
    return bool(cs.t_ctrl.size)


def _active(cs: ContactSeries) -> NDArray[np.bool_]:
    """Which of the contact's samples are active; all of them for a series made without the flags
    (by hand, in tests and tools), as the summary counted every sample before it knew of them."""
    return cs.active if cs.active.shape == cs.t.shape else np.ones(cs.t.shape, dtype=bool)


def _brace_errors(cs: ContactSeries) -> FloatArray:
    """|r_dj - r_j| [m] at each controller_state sample that has both (none for an unbraced contact)."""
    error = np.linalg.norm(cs.brace_desired - cs.brace_actual, axis=1)
    return error[np.isfinite(error)]


def _force_errors(cs: ContactSeries) -> FloatArray:
    """f_n - f_nd [N] where both are known (none for an unbraced contact)."""
    return cs.normal_force_error[np.isfinite(cs.normal_force_error)]


def _slip(cs: ContactSeries, active: NDArray[np.bool_]) -> float | None:
    """How far the contact point slid while active [m]: the trapezoid rule on the contacts stamps
    of |s| (0 where inactive, so touchdown and lift-off intervals count half). None if the series
    has no slip velocities (a series not read from a bag)."""
    if cs.slip_velocity.shape != (cs.t.size, 3):
        return None
    speed = np.where(active, np.linalg.norm(cs.slip_velocity, axis=1), 0.0)
    # By hand: np.trapezoid is numpy >= 2 only (a Jazzy workspace's system numpy is 1.26).
    return float(np.sum(np.diff(cs.t) * (speed[1:] + speed[:-1]) / 2))


def _rms_or_none(values: FloatArray) -> float | None:
    return _rms(values) if values.size else None


def contact_metrics(cs: ContactSeries) -> dict[str, Any]:
    """One contact's entry of summary.json's ``contacts`` (keys: CONTACT_KEYS); None where a metric
    does not apply: the errors of a contact the controller does not brace, the force and residual
    of a contact never active."""
    braced, active = _braced(cs), _active(cs)
    force, residual = cs.normal_force[active], cs.residual[active]
    return {
        "braced": braced,
        "normal_force_rms_error_n": _rms_or_none(_force_errors(cs)) if braced else None,
        "brace_rms_error_m": _rms_or_none(_brace_errors(cs)) if braced else None,
        "normal_force_mean_n": float(np.mean(force)) if force.size else None,
        "normal_force_max_n": float(np.max(force)) if force.size else None,
        "slip_m": _slip(cs, active),
        "residual_max_m": float(np.max(np.abs(residual))) if residual.size else None,
        "active_fraction": float(np.mean(active)) if active.size else None,
        # Over every sample: an obstacle's frame below its surface has penetrated, active or not.
        "penetration_m": max(0.0, -float(np.min(cs.residual))) if cs.residual.size else None,
    }


def compute_summary(
    series: BagSeries,
    wall_time_s: float | None = None,
    warnings: Sequence[str] = (),
    outcome: Mapping[str, str | None] | None = None,
    fed_back: Sequence[str] = (),
) -> dict[str, Any]:
    """The summary.json dict (keys: SUMMARY_KEYS, then SUMMARY_EXTRA_KEYS, in that order).

    A value that the recorded data cannot give (e.g. no controller_state after 2 s, no
    motor_state) or that does not apply is None. The brace and force errors count the braced
    contacts only (None for a run without any), the constraint residual every contact while
    active (None if none ever is); a torque-input run has no copper loss (None).
    ``contacts`` has every contact of the ``contacts`` topic the scenario names (``contact_metrics``),
    ``kept_out`` every ``<frame or link>@<contact>`` one (None without any); ``max_penetration_m`` and
    ``constraint_residual_max_m`` count both. ``warnings``:
    the given ones (what the data cannot show: a target out of reach), then ``data_warnings``, then
    what the nodes warned about during the run (``series.warnings``: the bag's run_status), each once.
    ``status``, ``error`` and ``hint``: ``outcome``'s (a failed run's, ``failures.diagnose``); without
    one, ok, no error, and the hint of a known cause the warnings name (``failures.succeeded``; ``fed_back``:
    the braced contacts under force feedback).
    """
    out: dict[str, Any] = dict.fromkeys(SUMMARY_KEYS + SUMMARY_EXTRA_KEYS)

    mask = series.t >= HAND_ERROR_T_MIN_S - 1e-9
    if np.any(mask):
        err = np.linalg.norm(series.hand_desired[mask] - series.hand_actual[mask], axis=1)
        out["hand_rms_error_m"] = _rms(err)
        out["hand_max_error_m"] = float(np.max(err))
        turn = series.hand_orientation_error
        if turn.shape[1] and turn.shape[0] == mask.size:  # |log(R_d R^T)|: the angle to the target orientation
            out["hand_orientation_rms_error_rad"] = _rms(np.linalg.norm(turn[mask], axis=1))

    contacts = list(series.contacts.values())
    braced = [c for c in contacts if _braced(c)]
    # Over every sample of every braced contact (an unbraced one has no target); None without any.
    for key, errors in (("brace_rms_error_m", _brace_errors), ("normal_force_rms_error_n", _force_errors)):
        out[key] = _rms_or_none(np.concatenate([np.zeros(0), *(errors(c) for c in braced)]))
    residual = np.concatenate([np.zeros(0), *(c.residual[_active(c)] for c in contacts)])
    out["constraint_residual_max_m"] = float(np.max(np.abs(residual))) if residual.size else None

    if series.motor_t.size:
        out["energy_consumed_j"] = float(series.energy_consumed[-1])
        # Torque input drives the joints directly: no motor circuit, so no copper loss to speak of.
        out["copper_loss_j"] = None if series.input_mode == "torque" else float(series.copper_loss[-1])
    # The hottest each winding got, and the hottest of all; None where no temperature was recorded.
    temperature = series.motor_temperature
    if temperature.shape[1] and np.isfinite(temperature).any():
        hottest = np.max(np.where(np.isfinite(temperature), temperature, -np.inf), axis=0)
        out["motor_temperature_max_c_by_joint"] = {
            name: float(value) if np.isfinite(value) else None
            for name, value in zip(series.motor_names, hottest, strict=True)
        }
        out["motor_temperature_max_c"] = float(np.max(hottest))

    if series.joint_t.size:
        out["sim_time_s"] = float(series.joint_t[-1] - series.joint_t[0])
    if wall_time_s is not None:
        out["wall_time_s"] = float(wall_time_s)
        if out["sim_time_s"] is not None and wall_time_s > 0:
            out["real_time_factor"] = out["sim_time_s"] / float(wall_time_s)

    measured = {c.name: contact_metrics(c) for c in contacts if c.t.size}
    out["contacts"] = by_role(measured, BRACED)
    out["kept_out"] = by_role(measured, KEPT_OUT) or None  # no collision frame or link: does not apply
    # Over braced and kept-out contacts alike: how far any frame went into any surface.
    penetrations = [m["penetration_m"] for m in measured.values() if m["penetration_m"] is not None]
    out["max_penetration_m"] = max(penetrations) if penetrations else None
    # robot.collision_geometry's link_penetration topic; None without it
    out["link_penetration_max_m"] = series.link_penetration_max
    out["input_mode"] = series.input_mode
    out["bracing"] = bool(braced) if series.t.size else None
    out["targets_refused"] = targets_refused(series)
    refusals = refusal_warnings(series)
    out["warnings"] = list(dict.fromkeys([*warnings, *data_warnings(series), *series.warnings, *refusals]))
    out["saturation_fraction"] = saturation_fraction(series)
    out["base_travel_m"] = base_travel(series)
    rolling = series.base_rolling_residual
    out["base_rolling_residual_max_m_s"] = float(np.max(rolling)) if rolling.size else None
    out.update(outcome if outcome is not None else succeeded(out["warnings"], fed_back).keys())
    return out


def base_travel(series: BagSeries) -> float | None:
    """How far a mobile base's root went in the plane [m]: the length of its (base_x, base_y) path over the
    joint_states; None without a moving base (no base_x and base_y among the joints)."""
    names = series.joint_names
    if "base_x" not in names or "base_y" not in names or series.joint_position.shape[0] == 0:
        return None
    path = series.joint_position[:, [names.index("base_x"), names.index("base_y")]]
    return float(np.sum(np.linalg.norm(np.diff(path, axis=0), axis=1)))


def targets_refused(series: BagSeries) -> dict[str, int]:
    """{target topic: how many targets of it the controller refused} ({} when none): the count its
    last recorded refusal gives (each says the count so far), or the refusals recorded if more."""
    out: dict[str, int] = {}
    for refused in series.targets_refused:
        out[refused.topic] = max(out.get(refused.topic, 0) + 1, refused.count)
    return out


def refusal_warnings(series: BagSeries) -> list[str]:
    """The first refused target of each topic and kind, with how many were refused so (a line each,
    never one per refusal: the counts are in ``targets_refused``)."""
    first: dict[tuple[str, str], tuple[float, str]] = {}
    counts: dict[tuple[str, str], int] = {}
    for refused in series.targets_refused:
        key = (refused.topic, refused.kind)
        first.setdefault(key, (refused.t, refused.why))
        counts[key] = counts.get(key, 0) + 1
    return [
        f"{why} (at t = {t:.3f} s; {counts[key]} {key[0]} target(s) refused so: summary.json's targets_refused)"
        for key, (t, why) in first.items()
    ]


def saturation_fraction(series: BagSeries) -> dict[str, float] | None:
    """Per joint, the fraction of the controller's commands at or beyond its saturation (|command| >= limit;
    0 for a joint without one); None where no joint has a limit or no command or limit was recorded."""
    limits = np.array([series.command_limit.get(name, 0.0) for name in series.motor_names], dtype=float)
    command = series.command
    if not np.any(limits > 0.0) or command.shape[0] == 0 or command.shape[1] != limits.size:
        return None
    at_limit = (np.abs(command) >= limits) & (limits > 0.0)
    return {name: float(np.mean(at_limit[:, j])) for j, name in enumerate(series.motor_names)}


def data_warnings(series: BagSeries) -> list[str]:
    """What the controller's recorded data shows to be amiss, once per contact (the texts of
    ``bracing_core.checks``, as the controller logs them): a braced contact's desired force <= 0, from
    the start or once retuned so. (What the simulator warns about it says itself: ``series.warnings``.)"""
    out = []
    for cs in series.contacts.values():
        if not _braced(cs):
            continue  # an obstacle is pushed or left as the arm goes
        desired = cs.normal_force_desired
        low = np.flatnonzero(np.isfinite(desired) & (desired <= 0.0))
        if low.size:
            k = int(low[0])
            out.append(str(checks.desired_force_warning(cs.name, float(desired[k]), float(cs.t_ctrl[k]))))
    return out


def flat_summary(summary: dict[str, Any], prefix: str = "") -> dict[str, Any]:
    """The summary with its nested dicts (per contact) as dotted keys: ``contacts.elbow.slip_m``."""
    out: dict[str, Any] = {}
    for key, value in summary.items():
        if isinstance(value, dict) and value:
            out.update(flat_summary(value, f"{prefix}{key}."))
        else:
            out[prefix + key] = value
    return out


def format_summary(summary: dict[str, Any]) -> str:
    """The summary as an aligned two-column table, a line per value (per contact metric too), then
    a line per warning."""
    flat = flat_summary(summary)
    warnings = flat.pop("warnings", None) or []
    width = max((len(k) for k in flat), default=0)
    lines = []
    for key, value in flat.items():
        text = "n/a" if value is None else f"{value:.6g}" if isinstance(value, float) else str(value)
        lines.append(f"{key:<{width}}  {text}")
    lines += [f"warning: {warning}" for warning in warnings]
    return "\n".join(lines)
