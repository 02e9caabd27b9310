"""What the recorder writes into a bag's metadata (custom_data): the scenario's name and contact surfaces,
the controller's task frames, axes and input mode, the motors' command limits. Read from the params files
the nodes run with; no rclpy (``bracing_analysis.bag_recovery`` gives a recovered bag the same notes)."""

from __future__ import annotations

import json
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path

from bracing_analysis import surfaces, truth
from bracing_core import schema


def scenario_surfaces(files: Sequence[str]) -> dict[str, surfaces.Shape]:
    """The contact surfaces of the scenario files (none given or unreadable: none, said so; the
    markers then draw each surface as its tangent plane)."""
    if not files:
        return {}
    try:
        return surfaces.read_scenario(files)
    except ValueError as exc:  # ConfigError: the nodes will say the same, more loudly
        print(f"recorder: warning: no contact surfaces from {', '.join(files)}: {exc}", file=sys.stderr, flush=True)
        return {}


def task_notes(files: Sequence[str], ground_truth: bool) -> dict[str, str]:
    """The controller's task frames (the report judges the truth at them: truth.py), task axes (the report
    draws each) and input mode, as the bag's custom_data; none if unreadable."""
    if not files:
        return {}
    try:
        return truth.read_task_notes(files, ground_truth)
    except ValueError as exc:  # ConfigError: the nodes will say the same, more loudly
        print(f"recorder: warning: no task frames or axes from {', '.join(files)}: {exc}", file=sys.stderr, flush=True)
        return {}


def scene_notes(scenario: str | None, shapes: Mapping[str, surfaces.Shape]) -> dict[str, str]:
    """The scenario's name and contact surfaces, as the bag's custom_data."""
    notes = {surfaces.SCENARIO_KEY: scenario} if scenario else {}
    if shapes:
        notes[surfaces.SURFACES_KEY] = surfaces.to_json(shapes)
    return notes


def bag_notes(params_files: Sequence[str], scenario: str | None, ground_truth: bool) -> dict[str, str]:
    """The custom_data the recorder writes into the bag's metadata when it closes the bag (run with these
    ``--params-file``, ``--scenario`` and ``--ground-truth``): what a bag recovered after its recorder died
    is given again (``bracing_analysis.bag_recovery``)."""
    scenario = scenario or (Path(params_files[0]).stem if params_files else None)
    notes = {**scene_notes(scenario, scenario_surfaces(params_files)), **task_notes(params_files, ground_truth)}
    return {**notes, **command_limit_notes(params_files)}


def bag_notes_of_values(
    sim_values: schema.Values, ctl_values: schema.Values, scenario: str, ground_truth: bool, search: Sequence[Path]
) -> dict[str, str]:
    """``bag_notes`` of the nodes' typed values read already (a run's plan holds them: the values of its params
    file): the same notes, nothing read again."""
    notes = {**scene_notes(scenario, surfaces.shapes_from_values(sim_values))}
    notes |= truth.task_notes_from_values(ctl_values, ground_truth)
    try:
        limits = truth.command_limits_from_values(sim_values, search)
    except (ValueError, OSError) as exc:  # an unreadable URDF: the nodes said so too
        print(f"recorder: warning: no command limits: {exc}", file=sys.stderr, flush=True)
        return notes
    return {**notes, **limit_notes(limits)}


def command_limit_notes(files: Sequence[str]) -> dict[str, str]:
    """The motors' |command| saturation by joint (truth.read_command_limits), where a joint has one, as the
    bag's custom_data (summary.json's saturation_fraction); none if unreadable."""
    if not files:
        return {}
    try:
        limits = truth.read_command_limits(files)
    except (ValueError, OSError) as exc:  # ConfigError, an unreadable URDF: the nodes will say so too
        print(f"recorder: warning: no command limits from {', '.join(files)}: {exc}", file=sys.stderr, flush=True)
        return {}
    return limit_notes(limits)


def limit_notes(limits: Mapping[str, float]) -> dict[str, str]:
    """The motors' |command| saturation by joint as the bag's custom_data; none where no joint has one."""
    if not any(limit > 0.0 for limit in limits.values()):
        return {}
    return {truth.COMMAND_LIMIT_KEY: json.dumps(limits, sort_keys=True)}
