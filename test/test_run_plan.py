"""A run's plan: the scenario file parsed once, each node's typed values read from what its params file holds,
and every consumer of the run (the configurations' checks, the diagnosis of a failure, a recovered bag's notes,
the report's fed-back contacts) given those values, nothing read again."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest
from conftest import PAPER_YAML

from bracing_bringup.run_plan import PARAMS_FILE, RunOptions, RunPlan, check_configs, plan_run, write_params
from bracing_bringup.supervision import diagnose_pair
from bracing_core import rcl_yaml, schema
from bracing_core.failures import fed_back
from bracing_core.overrides import CONTROLLER, SIMULATOR
from bracing_core.rcl_yaml import load_params_file
from bracing_core.rollout import build_scenario_from_params
from bracing_recorder.bag_notes import bag_notes, bag_notes_of_values

_KINDS = {SIMULATOR: "simulator", CONTROLLER: "controller"}


class Reads:
    """How often a params file is parsed and a node's parameters are read into typed values."""

    def __init__(self, monkeypatch: pytest.MonkeyPatch) -> None:
        self.documents = 0
        self.values = 0
        parse, read = rcl_yaml.read_document, schema.read

        def counted_parse(*args: Any, **kwargs: Any) -> Any:
            self.documents += 1
            return parse(*args, **kwargs)

        def counted_read(*args: Any, **kwargs: Any) -> Any:
            self.values += 1
            return read(*args, **kwargs)

        monkeypatch.setattr(rcl_yaml, "read_document", counted_parse)
        monkeypatch.setattr(schema, "read", counted_read)


def _plan(tmp_path: Path, **given: Any) -> RunPlan:
    return plan_run(RunOptions(config=PAPER_YAML, output=tmp_path / "run", duration=0.05, **given))


def _series(plan: RunPlan) -> SimpleNamespace:
    """What a bag of a run that diverged before its first state holds (no joint states, no warnings)."""
    names = list(plan.sim_values.params.robot.joint_names)
    return SimpleNamespace(
        joint_t=np.zeros(0), joint_names=names, joint_position=np.zeros((0, len(names))), warnings=[]
    )


def test_the_scenario_is_parsed_once_and_the_runs_consumers_read_nothing_again(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    reads = Reads(monkeypatch)
    plan = _plan(tmp_path, parameters={"hand.kp": [150.0, 150.0]})
    assert reads.documents == 1  # both nodes' sections from one parse (two before)
    planned = reads.values
    check_configs(plan)
    failure = diagnose_pair(plan, _series(plan), "the simulation diverged", [])
    notes = bag_notes_of_values(plan.sim_values, plan.ctl_values, "paper_4link", plan.ground_truth, plan.search)
    fed_back(plan.ctl_values)
    assert (reads.documents, reads.values) == (1, planned)  # checks, diagnosis, notes: the plan's values
    assert failure.error and notes


def test_the_plans_values_are_what_the_nodes_params_file_gives_them(tmp_path: Path) -> None:
    plan = _plan(tmp_path, parameters={"hand.kp": [150.0, 150.0]}, real_time=True)
    params_file = tmp_path / PARAMS_FILE
    write_params(params_file, plan.node_params)
    given = {node: schema.read(kind, load_params_file(params_file, node)) for node, kind in _KINDS.items()}
    assert given == {SIMULATOR: plan.sim_values, CONTROLLER: plan.ctl_values}
    assert plan.ctl_values.params.hand.kp == (150.0, 150.0)  # the command line's value, typed
    assert plan.sim_values.params.stepping == "real_time"  # the pair's, over the scenario's
    assert Path(plan.sim_values.params.robot.urdf).is_absolute()  # pinned for the nodes' working directory
    # Every consumer's result equals the one read again from the params file (one path: values).
    scenario = build_scenario_from_params(plan.node_params[SIMULATOR], plan.node_params[CONTROLLER], plan.search)
    assert scenario.controller is not None
    from bracing_core.checks import reach_warnings

    assert check_configs(plan) == reach_warnings(scenario.controller.config, scenario.controller.plant)
    for ground_truth in (False, True):
        from_file = bag_notes([str(params_file)], "paper_4link", ground_truth)
        from_plan = bag_notes_of_values(plan.sim_values, plan.ctl_values, "paper_4link", ground_truth, plan.search)
        assert from_plan == from_file


def test_fed_back_contacts_are_those_with_a_force_gain(tmp_path: Path) -> None:
    plan = _plan(tmp_path)
    assert fed_back(plan.ctl_values) == []
    contact = next(iter(plan.ctl_values.contacts))
    fed = _plan(tmp_path, parameters={f"contacts.{contact}.force_feedback.ki": 2.0})
    assert fed_back(fed.ctl_values) == [contact]


def test_a_refusal_names_the_users_value_even_where_the_pair_overrides_it(tmp_path: Path) -> None:
    """min_subscribers is the pair's to set; a wrong one given is refused as before, not overridden silently."""
    from bracing_core.params import ConfigError

    with pytest.raises(ConfigError, match="min_subscribers"):
        _plan(tmp_path, parameters={"min_subscribers": -1})
