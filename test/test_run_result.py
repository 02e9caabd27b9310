"""run_recorded's RunResult: the engine's Recording itself (its arrays views of the engine's memory, in their
final shapes), with the run's names and outcome beside them."""

from __future__ import annotations

import sys

import numpy as np
from conftest import CONFIG_DIR, REPO_ROOT

import bracing_engine as engine
from bracing_core.rollout import RECORDED_ARRAYS, RunResult, build_scenario, run_recorded

sys.path.insert(0, str(REPO_ROOT / "tools"))
from tiago_cmd_vel import wheeled_tiago


def test_the_run_is_the_engines_recording_with_its_points_per_contact() -> None:
    """contact_position is (rows, p, 3) per named contact: the elbow's recorded point is the law's brace_actual
    (one model, exact sensors) and lies on its plane (residual, the contact's C, near zero while held); a
    (rows, 3, p) or flat reading would put other numbers there."""
    run = run_recorded(build_scenario(CONFIG_DIR / "wall_7link.yaml"), 0.05)
    assert isinstance(run, engine.Recording) and isinstance(run, RunResult)
    rows, p, b = run.time.size, len(run.contact_names), len(run.braced_names)
    assert run.contact_position.shape == (rows, p, 3) and run.slip_velocity.shape == (rows, p, 3)
    assert run.brace_desired.shape == (rows, b, 3) and run.brace_actual.shape == (rows, b, 3)
    assert b >= 1
    for j, name in enumerate(run.braced_names):
        i = run.contact_names.index(name)
        np.testing.assert_allclose(run.contact_position[:, i], run.brace_actual[:, j], rtol=0, atol=1e-12)
        assert np.all(run.active[:, i]) and np.max(np.abs(run.residual[:, i])) < 1e-6


def test_the_arrays_are_read_only_views_of_the_engine_memory() -> None:
    """No second copy: the energy columns are strided views of one (rows, 3) block; nothing can be written
    through the arrays (one memory shared by every view)."""
    run = run_recorded(build_scenario(CONFIG_DIR / "paper_4link.yaml"), 0.05)
    columns = (run.energy_consumed, run.energy_net, run.copper_loss)
    start = run.energy_consumed.ctypes.data
    assert [(c.ctypes.data - start, c.strides) for c in columns] == [(0, (24,)), (8, (24,)), (16, (24,))]
    assert np.all(run.energy_consumed >= run.copper_loss) and run.energy_consumed[-1] > 0.0  # consumed: copper + rest
    for name in RECORDED_ARRAYS:  # an empty one (measured_position under exact sensors) holds nothing to write
        array = getattr(run, name)
        assert array.size == 0 or not array.flags.writeable, name
    assert list(run.arrays())[: len(RECORDED_ARRAYS)] == list(RECORDED_ARRAYS)


def test_temperature_and_orientation_columns_only_where_the_model_has_them() -> None:
    """As motor_state and the controller state carry them: the windings' temperatures with a thermal drive
    (hyper_7link, voltage input), none in torque mode; the hand's orientation error with an orientation
    task (ur5_table: two axes held, its error small), none without (paper_4link)."""
    hot = run_recorded(build_scenario(CONFIG_DIR / "hyper_7link.yaml"), 0.05)
    assert hot.temperature.shape == hot.position.shape and np.all(hot.temperature[-1] > hot.temperature[0])
    cold = run_recorded(build_scenario(CONFIG_DIR / "hyper_7link.yaml", shared={"input_mode": "torque"}), 0.05)
    assert cold.temperature.shape == (cold.time.size, 0)
    held = run_recorded(build_scenario(CONFIG_DIR / "ur5_table.yaml"), 0.05)
    assert held.hand_orientation_error.shape == (held.time.size, 3)
    assert 0.0 < np.max(np.abs(held.hand_orientation_error)) < 0.1
    free = run_recorded(build_scenario(CONFIG_DIR / "paper_4link.yaml"), 0.05)
    assert free.hand_orientation_error.shape == (free.time.size, 0)


def test_the_rolling_residual_is_each_states_largest_rolling_velocity() -> None:
    """A differential drive's (TIAGo on its turning wheels): per recorded state, max |A v| of the plant's rolling
    rows at that (q, v), bit for bit; none for a braked base or an arm without wheels."""
    scenario = wheeled_tiago()
    run = run_recorded(scenario, 0.05)
    dynamics = scenario.sim.dynamics.engine
    states = zip(run.position, run.velocity, strict=True)
    expected = [np.max(np.abs(dynamics.terms(q, v).rolling_velocity)) for q, v in states]
    assert run.rolling_residual.shape == run.time.shape
    assert run.rolling_residual.tolist() == expected and max(expected) > 0.0
    assert run_recorded(build_scenario(CONFIG_DIR / "tiago_table.yaml"), 0.01).rolling_residual.size == 0
    assert run_recorded(build_scenario(CONFIG_DIR / "paper_4link.yaml"), 0.01).rolling_residual.size == 0
