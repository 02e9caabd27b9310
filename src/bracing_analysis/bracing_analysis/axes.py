"""The axes a run's report draws the hand and each brace point along (``hand_<axis>.png``,
``brace_<axis>.png``): the tasks' own (``hand.axes``, ``contacts.<name>.brace_axes``, which the recorder
keeps in the bag's metadata), else what the recorded positions show. No plotting library."""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

from bracing_analysis.series import BagSeries, ContactSeries

BRACE_MOVES_M = 1e-6
"""A brace point moves along an axis when its values there (desired and actual) span more than this [m];
a desired hand path the same."""

DEFAULT_HAND_AXES = ("y", "z")
"""The hand plots of a run that says no hand axes and whose desired path holds still (schema's hand.axes)."""


def _moves(values: np.ndarray) -> bool:
    values = values[np.isfinite(values)]
    return bool(values.size and np.ptp(values) > BRACE_MOVES_M)


def _in_order(axes: Iterable[str]) -> list[str]:
    return [axis for axis in "xyz" if axis in axes]


def hand_axes(series: BagSeries) -> list[str]:
    """The axes ("x", "y", "z") the report draws the hand along, ``hand_<axis>.png`` each: its task's
    (``hand.axes``, kept in the bag's metadata by the recorder; the paper's y and z). A run that says none
    (an older bag, an in-process series) or has no hand task: the axes its desired path moves along, y
    and z if it holds still."""
    if series.hand_axes:
        return _in_order(series.hand_axes)
    moving = [axis for k, axis in enumerate("xyz") if _moves(series.hand_desired.reshape(-1, 3)[:, k])]
    return moving or list(DEFAULT_HAND_AXES)


def contact_brace_axes(series: BagSeries, cs: ContactSeries) -> list[str]:
    """The axes a braced contact's brace point is drawn along: its task's (``contacts.<name>.brace_axes``,
    kept in the bag's metadata); a contact whose run says none, or whose task has none (a force only):
    the axes along which its brace point moves. Desired and actual count together: a steady offset
    between them is worth a plot, one value along an axis is not."""
    own = series.brace_task_axes.get(cs.name)
    if own:
        return _in_order(own)
    both = np.concatenate([cs.brace_desired, cs.brace_actual]).reshape(-1, 3)
    return [axis for k, axis in enumerate("xyz") if _moves(both[:, k])]


def brace_axes(series: BagSeries) -> list[str]:
    """The axes ("x", "y", "z") some braced contact is drawn along (``contact_brace_axes``): the brace
    plots a run gets (the paper's elbow: y only)."""
    braced = [cs for cs in series.contacts.values() if cs.t_ctrl.size]
    drawn = {axis for cs in braced for axis in contact_brace_axes(series, cs)}
    return _in_order(drawn)
