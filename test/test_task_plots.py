"""The report draws the hand and each brace point along every axis of its task, a plot per axis named by it
(``hand_<axis>.png``, ``brace_<axis>.png``): the axes come from the run (the recorder keeps the tasks' axes
in the bag's metadata), else from what the desired path does."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import ros_helpers

from bracing_analysis.axes import brace_axes, hand_axes
from bracing_analysis.bag import read_series
from bracing_analysis.drawing import file_names
from bracing_analysis.figures import plot_figure
from bracing_analysis.series import BagSeries, ContactSeries

WRITING_DESK = ros_helpers.REPO_ROOT / "config" / "writing_desk.yaml"
RADIUS_M = 0.01
XY_CIRCLE = (
    # The desk arm's pen as the hand, tracing a 1 cm circle in the desk's plane (x, y) once a second; the pen
    # still presses on the desk (its force only: no brace position task of its own).
    "--set",
    "hand.axes=[x,y]",
    "--set",
    "hand.kp=[300,300]",
    "--set",
    "hand.kd=[50,50]",
    "--set",
    "hand.trajectory.type=circle",
    "--set",
    f"hand.trajectory.center=[-{RADIUS_M},0.6,0.0]",  # the pen starts at (0, 0.6, 0): on the circle
    "--set",
    f"hand.trajectory.radius={RADIUS_M}",
    "--set",
    "hand.trajectory.period=1.0",
    "--set",
    "hand.trajectory.plane=[x,y]",
    "--set",
    "contacts.pen.brace_axes=[]",
    "--set",
    "contacts.pen.kp=[]",
    "--set",
    "contacts.pen.kd=[]",
    "--set",
    "contacts.pen.trajectory.type=hold",
)


def _lines(name: str, series: BagSeries) -> list[np.ndarray]:
    return [np.asarray(line.get_ydata()) for line in plot_figure(name, series).axes[0].get_lines()]


def test_an_xy_circle_gets_a_hand_plot_per_axis_of_its_task(tmp_path: Path) -> None:
    out = tmp_path / "xy"
    argv = ros_helpers.pair_argv(out, "--duration", "0.5", "--no-animation", *XY_CIRCLE, config=WRITING_DESK)
    done = ros_helpers.run(argv, timeout=300)
    assert done.returncode == 0, done.stdout + done.stderr
    series = read_series(out / "bag")
    assert series.hand_axes == ["x", "y"]  # the run's own task, from the bag's metadata
    assert series.brace_task_axes == {"elbow": [], "pen": []}
    assert sorted(p.name for p in out.glob("hand_*.png")) == ["hand_x.png", "hand_y.png"]
    # hand_x draws the target's x and the hand's x: the circle's 2 cm across x, followed.
    target, hand = _lines("hand_x", series)
    assert np.array_equal(target, series.hand_desired[:, 0]) and np.array_equal(hand, series.hand_actual[:, 0])
    assert np.ptp(target) == pytest.approx(2 * RADIUS_M, rel=0.05)
    assert np.max(np.abs(hand - target)) < RADIUS_M


def test_the_paper_run_keeps_its_plots(runs: dict[str, Path]) -> None:
    """The paper's tasks (hand y, z; the elbow's y) from the bag's metadata: the same files as ever."""
    series = read_series(runs["braced"] / "bag")
    assert series.hand_axes == ["y", "z"] and series.brace_task_axes == {"elbow": ["y"]}
    plots = [name for name in file_names(series, animation=False) if name.startswith(("hand_", "brace_"))]
    assert plots == ["hand_y", "hand_z", "brace_y"]
    assert sorted(p.name for p in runs["braced"].glob("*_[xyz].png")) == ["brace_y.png", "hand_y.png", "hand_z.png"]


def _circle_series(plane: tuple[int, int], hand: list[str] | None = None) -> BagSeries:
    t = np.linspace(0.0, 2.0, 201)
    desired = np.tile([0.0, 0.6, 0.1], (t.size, 1))
    desired[:, plane[0]] += 0.05 * np.cos(np.pi * t)
    desired[:, plane[1]] += 0.05 * np.sin(np.pi * t)
    return BagSeries(joint_t=t, t=t, hand_desired=desired, hand_actual=desired + 0.001, hand_axes=hand)


def test_axes_follow_the_task_else_the_desired_path() -> None:
    # The task says x, y and z: z is drawn too, though the circle holds it.
    assert hand_axes(_circle_series((0, 1), ["z", "x", "y"])) == ["x", "y", "z"]
    # A bag that does not say (recorded before, or a series made in-process): where the target moves.
    assert hand_axes(_circle_series((0, 1))) == ["x", "y"]
    assert file_names(_circle_series((0, 2)), animation=False)[:2] == ["hand_x", "hand_z"]
    # A hand target that holds still, or no hand task (the writing desk's): y and z, as ever.
    still = _circle_series((0, 1), [])
    still.hand_desired[:] = still.hand_desired[0]
    assert hand_axes(still) == ["y", "z"]


def test_each_brace_plot_draws_the_contacts_whose_task_has_its_axis() -> None:
    t = np.linspace(0.0, 1.0, 101)
    series = BagSeries(joint_t=t, t=t, hand_desired=np.zeros((t.size, 3)), hand_actual=np.zeros((t.size, 3)))
    for name, moving in (("elbow", 1), ("wrist", 0)):
        cs = ContactSeries(name=name, t=t, t_ctrl=t, t_matched=t)
        cs.brace_desired = np.tile([0.1, 0.2, 0.0], (t.size, 1))
        cs.brace_desired[:, moving] += 0.01 * t
        cs.brace_actual = cs.brace_desired.copy()
        series.contacts[name] = cs
    series.brace_task_axes = {"elbow": ["y"], "wrist": ["x", "z"]}
    assert brace_axes(series) == ["x", "y", "z"]  # the wrist's held z too: it is part of its task
    assert len(_lines("brace_y", series)) == 2  # the elbow's target and position only
    assert len(_lines("brace_z", series)) == 2  # the wrist's
    assert np.array_equal(_lines("brace_x", series)[1], series.contacts["wrist"].brace_actual[:, 0])
