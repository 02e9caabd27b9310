"""One in-process run of a sweep or study, as a worker executes it: the nodes' core objects
(bracing_core.rollout), the metrics of summary.json (bracing_analysis.summary), the arrays.

A worker may be another machine (a Dask cluster): a ``RunSpec`` carries each node's complete
parameters and the URDF's text, and ``execute_run`` returns everything (row, summary, arrays as
.npz bytes) to the client, which alone writes files. It never raises for a failing run: the
error is the row's.
"""

from __future__ import annotations

import hashlib
import io
import json
import os
import socket
import tempfile
import time
import traceback
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from bracing_analysis.series import BagSeries, ContactSeries
from bracing_analysis.summary import compute_summary, flat_summary
from bracing_core.checks import reach_warnings
from bracing_core.rollout import RunResult, build_scenario_from_params, run_recorded

STATUS_OK = "ok"
STATUS_FAILED = "failed"
FORCE_MAX_ERROR_KEY = "normal_force_max_error_n"
"""max |f_n - f_nd| over every contact and sample [N]: the gain study's measure of decoupling."""


@dataclass(frozen=True)
class RunSpec:
    run_id: str
    varied: dict[str, Any]  # the values that make this run (table columns)
    sim_params: dict[str, Any]  # the simulator's complete flat parameters
    ctl_params: dict[str, Any]  # the controller's
    duration: float  # [s] of sim time
    urdf_text: str = ""  # robot.urdf's content, for a worker that does not have the file
    labels: dict[str, Any] = field(default_factory=dict)  # extra table columns (a study's labels)


@dataclass
class RunOutcome:
    row: dict[str, Any]
    summary: dict[str, Any] | None = None
    arrays: bytes | None = None  # .npz of the RunResult


def series_from_recording(rec: RunResult) -> BagSeries:
    """The time series a bag of the same run holds, so that summary.compute_summary applies as is."""
    series = BagSeries(
        joint_t=rec.time,
        joint_names=list(rec.joint_names),
        joint_position=rec.position,
        base_rolling_residual=rec.rolling_residual,
        t=rec.time,
        hand_desired=rec.hand_desired,
        hand_actual=rec.hand_actual,
        motor_t=rec.time,
        energy_consumed=rec.energy_consumed,
        energy_net=rec.energy_net,
        copper_loss=rec.copper_loss,
        motor_names=list(rec.joint_names),
        motor_temperature=rec.temperature,
        warnings=list(rec.warnings),  # what the simulator node would have said on run_status
        input_mode=rec.input_mode,
        command=rec.command,
        hand_orientation_error=rec.hand_orientation_error,
        command_limit=dict(zip(rec.joint_names, rec.command_limit.tolist(), strict=True)),
    )
    braced = {name: b for b, name in enumerate(rec.braced_names)}
    for j, name in enumerate(rec.contact_names):
        contact = ContactSeries(
            name=name,
            t=rec.time,
            normal_force=rec.normal_force[:, j],
            friction_force=rec.friction_force[:, j],
            residual=rec.residual[:, j],
            active=rec.active[:, j],
            position=rec.contact_position[:, j],
            slip_velocity=rec.slip_velocity[:, j],
        )
        if name in braced:  # the controller's side: what controller_state holds for it
            b = braced[name]
            desired = np.full(rec.time.size, rec.desired_normal_force[b])
            contact.t_ctrl = contact.t_matched = rec.time
            contact.normal_force_desired = desired
            contact.brace_desired, contact.brace_actual = rec.brace_desired[:, b], rec.brace_actual[:, b]
            contact.normal_force_error = rec.normal_force[:, j] - desired
        series.contacts[name] = contact
    return series


def summarize(rec: RunResult, wall_time_s: float, warnings: Sequence[str] = ()) -> dict[str, Any]:
    """summary.json of an in-process run: summary.compute_summary on the recorded series (``warnings``:
    those found before the run), plus the largest force error (not in summary.json, which has the RMS)."""
    series = series_from_recording(rec)
    summary = compute_summary(series, wall_time_s=wall_time_s, warnings=warnings)
    if FORCE_MAX_ERROR_KEY not in summary:
        errors = [np.abs(c.normal_force_error) for c in series.contacts.values() if c.normal_force_error.size]
        summary[FORCE_MAX_ERROR_KEY] = float(np.max(np.concatenate(errors))) if errors else None
    return summary


_URDF_COPIES: dict[str, str] = {}


def _local_urdf(path: str, text: str) -> str:
    """``path`` if this machine has it, else a private copy of the URDF the client sent."""
    if not text or Path(path).is_file():
        return path
    digest = hashlib.sha1(text.encode()).hexdigest()[:16]
    if digest not in _URDF_COPIES:
        copy = Path(tempfile.gettempdir()) / f"bracing-{digest}-{os.getpid()}" / Path(path).name
        copy.parent.mkdir(parents=True, exist_ok=True)
        copy.write_text(text)
        _URDF_COPIES[digest] = str(copy)
    return _URDF_COPIES[digest]


def execute_run(spec: RunSpec) -> RunOutcome:
    """Build, run, summarise one run; a failure (bad value, infeasible start, divergence) is a row."""
    start = time.perf_counter()
    row: dict[str, Any] = {"run_id": spec.run_id, **spec.labels, **spec.varied}
    row["worker"] = f"{socket.gethostname()}:{os.getpid()}"
    try:
        sim_params, ctl_params = dict(spec.sim_params), dict(spec.ctl_params)
        urdf = _local_urdf(str(sim_params.get("robot.urdf", "")), spec.urdf_text)
        sim_params["robot.urdf"] = ctl_params["robot.urdf"] = urdf
        scenario = build_scenario_from_params(sim_params, ctl_params)
        assert scenario.controller is not None  # built with the controller's parameters
        warnings = reach_warnings(scenario.controller.config, scenario.controller.plant)  # as the node says
        recording = run_recorded(scenario, spec.duration)
        wall = time.perf_counter() - start
        summary = summarize(recording, wall, warnings)
        buffer = io.BytesIO()
        np.savez_compressed(buffer, allow_pickle=False, **recording.arrays())
    except Exception as exc:  # the run's failure, whatever it is, belongs to its row
        row.update(status=STATUS_FAILED, error=f"{type(exc).__name__}: {exc}", wall_time_s=time.perf_counter() - start)
        row["traceback"] = traceback.format_exc(limit=6)
        return RunOutcome(row)
    for key, value in flat_summary(summary).items():
        if not isinstance(value, dict):  # an empty contacts: {} has no column
            # A list (the warnings) as the table holds it: JSON text, "[]" for none.
            row.setdefault(key, json.dumps(value) if isinstance(value, list) else value)  # a varied value keeps its own
    row.update(status=STATUS_OK, error=None, wall_time_s=wall)
    return RunOutcome(row, summary, buffer.getvalue())
