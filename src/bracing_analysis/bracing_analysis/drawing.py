"""A report's files from a bag already read: summary.json here, the figures and the animation
in processes that have the plotting libraries loaded already (this module imports none).

``report_series`` writes them; ``prepare_drawing`` starts the drawing processes ahead of time
(bracing-pair does when the simulation has ended: matplotlib loads while the nodes exit and
the bag is read). Started with the run instead, their imports slowed a 4 s lockstep run by
10-15 % (two imports, niced), and one niced import at the first step gave no clear gain in
side-by-side 10 s runs (report 1.40 / 1.80 s against 1.44 / 1.53 s).
"""

from __future__ import annotations

import json
import multiprocessing
import os
import sys
import threading
import time
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import ProcessPoolExecutor
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from bracing_analysis.axes import brace_axes, hand_axes
from bracing_analysis.series import BagSeries, touched_kept_out
from bracing_analysis.summary import compute_summary
from bracing_core.contact_roles import BRACED, by_role
from bracing_core.workers import ignore_sigint

SUMMARY_FILE = "summary.json"

Mark = Callable[..., None]
"""Called with what was just written and when (``timeline.Timeline.mark``)."""

DRAWING_PROCESSES = 2
_pool: ProcessPoolExecutor | None = None
_preparing: threading.Thread | None = None  # prepare_drawing's, once started


def drawing_pool() -> ProcessPoolExecutor:
    """The processes that draw reports, made once per process.

    They fork from a forkserver that has imported ``bracing_analysis.figures`` (matplotlib, the
    animation) once, so a report's drawing starts at once and uses both cores: a 10 s run's
    report takes about max(animation, plots) instead of their sum."""
    global _pool
    if _pool is None:
        context = multiprocessing.get_context("forkserver")
        context.set_forkserver_preload(["bracing_analysis.figures"])
        _pool = ProcessPoolExecutor(DRAWING_PROCESSES, mp_context=context, initializer=ignore_sigint)
    return _pool


def prepare_drawing() -> threading.Thread:
    """Start ``drawing_pool``'s processes in the background (its forkserver imports the plotting
    libraries meanwhile: ~0.8 s of one core), once per process; the thread that starts them."""
    global _preparing
    if _preparing is not None:
        return _preparing

    def start() -> None:
        pool = drawing_pool()
        for _ in range(DRAWING_PROCESSES):
            pool.submit(time.time)

    _preparing = threading.Thread(target=start, name="prepare-drawing", daemon=True)
    _preparing.start()
    return _preparing


def report_series(
    series: BagSeries,
    out: Path,
    wall_time_s: float | None = None,
    animation_interval_s: float | None = None,
    urdf: str | None = None,
    mark: Mark | None = None,
    parallel: bool = True,
    warnings: Sequence[str] = (),
    outcome: Mapping[str, str | None] | None = None,
    fed_back: Sequence[str] = (),
) -> dict[str, Any]:
    """Write summary.json, the plots and (unless ``animation_interval_s`` is None) the animation of
    ``series`` into ``out``; the summary.

    With ``parallel`` (and a second core) ``drawing_pool`` draws the files, else this process.
    ``mark(what, wall time)`` is called for each file written. ``warnings``: the run's that the
    bag cannot show, ``outcome`` a failed run's status, error and hint, ``fed_back`` the contacts under force
    feedback (``compute_summary``)."""
    out.mkdir(parents=True, exist_ok=True)
    summary = compute_summary(series, wall_time_s=wall_time_s, warnings=warnings, outcome=outcome, fed_back=fed_back)
    (out / SUMMARY_FILE).write_text(json.dumps(summary, indent=2) + "\n", encoding="utf-8")
    if mark is not None:
        mark(SUMMARY_FILE)
    names = file_names(series, animation=animation_interval_s is not None)
    draw = partial(_draw, series=series, out=out, animation_interval_s=animation_interval_s, urdf=urdf)
    written = list(drawing_pool().map(draw, names) if parallel and (os.cpu_count() or 1) > 1 else map(draw, names))
    for stamp, label, wrote in written:
        if not wrote:
            print(f"bracing-report: {label}", file=sys.stderr, flush=True)
        elif mark is not None:
            mark(label, stamp)
    return summary


def file_names(series: BagSeries, animation: bool) -> list[str]:
    """The report's files but summary.json that ``series`` allows, by name (``figures.draw_file``):
    the animation (the longest, first), then each plot that has data."""
    names = ["animation"] if animation else []
    if series.t.size:
        names += [f"hand_{axis}" for axis in hand_axes(series)]
    if series.hand_orientation_error.shape[1] and series.hand_orientation_error.shape[0] == series.t.size:
        names.append("hand_orientation")
    names += [f"brace_{axis}" for axis in brace_axes(series)]
    if any(cs.t_ctrl.size or cs.t.size for cs in by_role(series.contacts, BRACED).values()):
        names.append("normal_force")
    if touched_kept_out(series):
        names.append("kept_out_force")
    if series.motor_t.size:
        names.append("energy")
    if series.motor_temperature.shape[1] and np.isfinite(series.motor_temperature).any():  # the thermal model's
        names.append("motor_temperature")
    return names


def _draw(
    name: str, series: BagSeries, out: Path, animation_interval_s: float | None, urdf: str | None
) -> tuple[float, str, bool]:
    # Imported here, not above: loaded already in the drawing processes (their forkserver's preload),
    # and kept out of bracing-pair's process, which imports this module (see the module's docstring).
    from bracing_analysis.figures import draw_file  # imported where used: matplotlib ~460 ms (python -X importtime)

    label, wrote = draw_file(name, series, out, animation_interval_s, urdf)
    return time.time(), label, wrote
