"""A run's spec from a scenario file and flat overrides, validated as the nodes would (types, bounds, the
task's rank at the start posture), named by what it runs: what every command's runs are built from."""

from __future__ import annotations

import hashlib
import json
import re
from pathlib import Path
from typing import TYPE_CHECKING, Any

from bracing_core.config import Plant, project_initial_position
from bracing_core.controller_config import ControllerConfig
from bracing_core.law import check_task_rank
from bracing_core.overrides import CONTROLLER, NodeOverrides, format_value, node_params, route, validate
from bracing_core.params import ConfigError
from bracing_experiments.experiment import RunSpec

if TYPE_CHECKING:
    from bracing_core.config import SimulatorConfig


def run_id(varied: dict[str, Any], duration: float, overrides: dict[str, Any] | None = None) -> str:
    """Stable, readable and unique: the varied values in a short slug plus a hash of everything that
    makes the run (``overrides``: the parameters applied, when they are not the varied values)."""
    canonical = json.dumps({"varied": varied, "overrides": overrides, "duration": duration}, sort_keys=True)
    digest = hashlib.sha1(canonical.encode()).hexdigest()[:10]
    slug = "-".join(f"{key}={format_value(value)}" for key, value in varied.items())
    slug = re.sub(r"[^A-Za-z0-9_=.+-]+", "-", slug.replace("[", "").replace("]", "").replace(",", "+"))
    slug = slug.strip("-")[:80]
    return f"{slug}-{digest}" if slug else digest


def make_spec(
    config: Path,
    varied: dict[str, Any],
    duration: float | None = None,
    labels: dict[str, Any] | None = None,
    overrides: dict[str, Any] | None = None,
) -> RunSpec:
    """One run's spec, validated: a ConfigError names the parameter. ``overrides``: flat parameters
    applied (default: ``varied`` itself; a study labels its runs differently)."""
    node_overrides: NodeOverrides = route(varied if overrides is None else overrides)
    sim_config = validate(config, node_overrides)
    run_duration = duration if duration is not None else sim_config.duration
    if run_duration <= 0:
        raise ConfigError("duration: a sweep run needs a duration > 0 (set it in the file, --set or --duration)")
    params = node_params(config, node_overrides)
    check_task_rank_at_start(sim_config, params[CONTROLLER], config, node_overrides)
    urdf = sim_config.shared.urdf  # resolved now, against the config's directory
    for node in params.values():
        node["robot.urdf"] = str(urdf)
    return RunSpec(
        run_id=run_id(varied, run_duration, overrides),
        varied=dict(varied),
        sim_params=params["bracing_simulator"],
        ctl_params=params["bracing_controller"],
        duration=run_duration,
        urdf_text=urdf.read_text(),
        labels=dict(labels or {}),
    )


def check_task_rank_at_start(
    sim_config: SimulatorConfig, ctl_params: dict[str, Any], config: Path, node_overrides: NodeOverrides
) -> None:
    """A run's task-rank check (``bracing_core.law.check_task_rank``, at the start posture, as
    ``rollout.build_scenario_from_params`` runs it) before any run: a task direction the arm cannot
    move along is the scenario's error, not one run's. ConfigError names it and the overrides. A start
    the projection cannot make feasible is left to the run (a failed row, as before)."""
    try:
        plant = Plant(sim_config.shared, sim_config.slip_epsilon)
        controller = ControllerConfig.from_params(ctl_params, [config.resolve().parent])
        start = plant.to_model_order(sim_config.initial_position)
        if sim_config.project_initial_position:
            try:
                start = project_initial_position(plant, start)
            except ConfigError:
                return  # the run says so itself
        check_task_rank(controller, plant, start)
    except ConfigError as exc:
        given = ", ".join(f"{k}={format_value(v)}" for k, v in node_overrides.flat().items())
        raise ConfigError(f"{exc}" + (f" (with --set {given})" if given else "")) from None
