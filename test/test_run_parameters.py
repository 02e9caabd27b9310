"""Per-run parameters without DDS (``bracing_core.run_parameters``): which changes a running node takes and which
it refuses (with the reason, a bad value with the message a start with it prints), and that a run built anew
from a changed per-run parameter (the simulator's reset, the controller's states going back in time) is, bit for
bit, the run of a fresh core built with it."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from conftest import build_scenario, node_params
from test_answering import Q0, answerer
from test_reset_simulation import answer_run, run_lockstep, state_bytes, step_bytes
from test_stepping import stepper

from bracing_core import run_parameters, schema
from bracing_core.config import SimulatorConfig, build_simulator
from bracing_core.controller_config import ControllerConfig
from bracing_core.params import ConfigError
from bracing_core.variants import FREE_SPACE, PASSIVE

STEPS = 60


def test_per_run_parameters_are_bracing_and_free_space_and_the_reference_says_so() -> None:
    per_run = {p.name for p in (*schema.SHARED, *schema.CONTACT, *schema.SIMULATOR, *schema.CONTROLLER) if p.per_run}
    assert per_run == {"bracing", "free_space"}
    rows = [line for line in schema.reference_markdown().splitlines() if line.startswith("| `")]
    marked = {row.split("`")[1] for row in rows if row.split(" | ")[6] == "yes"}  # the per-run column
    assert marked == per_run
    assert "| tunable | per run | meaning |" in schema.reference_markdown()


@pytest.mark.parametrize("node", run_parameters.NODES)
def test_a_node_takes_per_run_changes_and_refuses_any_other_with_the_reason(node: str) -> None:
    assert run_parameters.refusal(node, ["bracing", "free_space"]) is None
    refused = run_parameters.refusal(node, ["bracing", "robot.urdf"])
    assert refused == (
        f"robot.urdf: cannot change while running: it needs a fresh start (a new {node} process started with the "
        "new value)"
    )
    tunable = run_parameters.refusal(node, ["contacts.elbow.desired_normal_force"])  # both nodes read it
    assert (tunable is None) == (node == "controller")  # the controller's tunable one; the simulator's needs a start
    other = "hand.kp" if node == "simulator" else "step"
    assert (
        run_parameters.refusal(node, [other]) == f"{other}: cannot change while running: not a parameter of the {node}"
    )


@pytest.mark.parametrize("node", ["bracing_simulator", "bracing_controller"])
def test_a_bad_per_run_value_is_refused_with_the_message_of_a_start_with_it(node: str) -> None:
    kind = node.removeprefix("bracing_")
    params = node_params(node)
    with pytest.raises(ConfigError) as at_start:
        schema.read(kind, {**params, "free_space": "yes"})
    with pytest.raises(ConfigError) as changed:
        run_parameters.next_run_values(kind, params, [("free_space", "yes")])
    assert str(changed.value) == str(at_start.value) == "free_space: expected true or false, got 'yes'"


def test_a_retune_is_checked_against_the_running_run_s_per_run_values() -> None:
    params = {**node_params("bracing_controller"), "bracing": False}  # set, for the next run
    running = run_parameters.per_run_values("controller", node_params("bracing_controller"))
    assert running == {"bracing": True, "free_space": False}
    assert run_parameters.running_values("controller", params, running)["bracing"] is True


def simulator_run(core: Any, outlet: Any, clock: Any) -> tuple[list[Any], list[Any]]:
    """The states and step reports of ``STEPS`` lockstep steps from the state just sent (the same commands each run)."""
    outlet.states.clear(), outlet.steps.clear()
    run_lockstep(core, clock, STEPS)
    return [state_bytes(s) for s in outlet.states], [step_bytes(s) for s in outlet.steps]


@pytest.mark.parametrize("variant", [PASSIVE, FREE_SPACE], ids=lambda v: v.name)
def test_a_reset_with_changed_per_run_parameters_runs_as_a_fresh_simulator_built_with_them(variant: Any) -> None:
    core, log, outlet, clock = stepper()
    core.send_state()
    braced = simulator_run(core, outlet, clock)
    held = [(c.unilateral, c.enforced) for c in core.plant.contact_set.contacts]
    changes = list(variant.overrides().items())
    values = run_parameters.next_run_values("simulator", node_params("bracing_simulator"), changes)
    config = SimulatorConfig.from_values(values)
    outlet.states.clear()
    core.reset((config, *build_simulator(config)))
    assert [s.t_ns for s in outlet.states] == [0] and core.now_ns == 0  # the initial state out again
    first = state_bytes(outlet.states[0])
    again = simulator_run(core, outlet, clock)
    fresh, _, fresh_outlet, fresh_clock = stepper(variant.overrides())
    fresh.send_state()
    assert state_bytes(fresh_outlet.states[0]) == first
    expected = simulator_run(fresh, fresh_outlet, fresh_clock)
    assert again == expected  # every state and report, bit for bit
    # and it is another run: the elbow's plane an obstacle (passive), or only watched (free space: no force)
    assert [(c.unilateral, c.enforced) for c in core.plant.contact_set.contacts] != held
    assert (again != braced) == variant.free_space
    assert core.config.shared.free_space == variant.free_space and core.config.shared.bracing == variant.bracing
    assert not log.reports


@pytest.mark.parametrize("variant", [PASSIVE, FREE_SPACE], ids=lambda v: v.name)
def test_states_back_in_time_after_a_rebuild_are_answered_as_a_fresh_controller_built_with_it(variant: Any) -> None:
    core, log, _, _ = answerer()
    states = [(k * 1_000_000, Q0 + 0.002 * k, np.full(4, 0.1)) for k in range(30)]
    braced = answer_run(core, states)
    changes = list(variant.overrides().items())
    values = run_parameters.next_run_values("controller", node_params("bracing_controller"), changes)
    core.rebuild(ControllerConfig.from_values(values))
    again = answer_run(core, states)
    assert any("joint_states went back in time, from t = 0.029000 s to 0.000000 s" in line for line in log.lines)
    fresh, _, _, _ = answerer(variant.overrides())
    expected = answer_run(fresh, states)

    def answers(sent: list[Any]) -> list[Any]:
        fields = ("command", "hand_desired", "hand_actual", "brace_desired", "brace_actual")
        return [
            [a.stamp_ns, a.desired_normal_force.tobytes(), *(getattr(a.output, f).tobytes() for f in fields)]
            for a in sent
        ]

    assert answers(again) == answers(expected)
    assert len(braced[0].desired_normal_force) == 1 and len(again[0].desired_normal_force) == 0  # no brace task
    assert [t.what for t in core.targets.tasks] == [t.what for t in fresh.targets.tasks] == ["hand_target"]
    assert core.measurements is None


def test_bracing_and_free_space_change_none_of_the_simulator_s_topics() -> None:
    from bracing_sim.topics import topics_key

    scenario = build_scenario(with_controller=False)
    assert scenario.sim_config is not None
    braced = topics_key(scenario.sim_config, scenario.plant)
    for variant in (PASSIVE, FREE_SPACE):
        other = build_scenario(variant.overrides(), with_controller=False)
        assert other.sim_config is not None
        assert topics_key(other.sim_config, other.plant) == braced
