"""Python's cyclic garbage collector kept out of a lockstep loop's states (``SteppingCollector``).

An automatic collection runs wherever an allocation crosses its threshold, on a state's answer as likely as
anywhere: in the controller's loop a young collection took ~0.1 ms and an older one ~1.3 ms (the
start-up's objects, rclpy's, numpy's and the model's, traversed again each time). As a real-time loop does, the
objects of the start-up are frozen (never traversed again) and the automatic collections are off while
stepping; the loop collects the young generations itself at its safe points, between states, and the oldest
every ``FULL_EVERY`` safe points (cyclic garbage promoted there would otherwise wait for the run's end).
"""

from __future__ import annotations

import gc

FULL_EVERY = 100
"""Safe points per full collection (the controller's: one every 100 states, so one per 10,000 states)."""


class SteppingCollector:
    """``start`` before the first state, ``safe_point`` where the loop has time (between states), ``stop`` after
    the last; each a no-op where it does not apply."""

    def __init__(self) -> None:
        self._paused = False
        self._safe_points = 0

    def start(self) -> None:
        """The start-up's garbage collected and what survives frozen; no automatic collection from now on."""
        if gc.isenabled():
            gc.collect()
            gc.freeze()
            gc.disable()
            self._paused = True

    def safe_point(self) -> None:
        """The objects since the start (the young generations, every ``FULL_EVERY``-th time all of them; never the
        frozen start-up) collected now."""
        if self._paused:
            self._safe_points += 1
            gc.collect(2 if self._safe_points % FULL_EVERY == 0 else 1)

    def stop(self) -> None:
        """Automatic collection as before ``start`` (the frozen objects stay out of it)."""
        if self._paused:
            gc.enable()
            self._paused = False
