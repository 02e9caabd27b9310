"""SteppingCollector: no automatic collection while stepping, the young garbage collected at a safe point, and
the collector as before once stopped."""

from __future__ import annotations

import gc
import weakref

import pytest

from bracing_core.gc_policy import FULL_EVERY, SteppingCollector


class Cycle:
    """An object in a reference cycle: only the cyclic collector frees it."""

    def __init__(self) -> None:
        self.me = self


@pytest.fixture
def collector():
    was_enabled = gc.isenabled()
    gc.enable()
    stepping = SteppingCollector()
    yield stepping
    stepping.stop()
    gc.unfreeze()
    if not was_enabled:
        gc.disable()


def cyclic_garbage() -> weakref.ref[Cycle]:
    """A weak reference to a cycle no one holds any more."""
    return weakref.ref(Cycle())


def test_no_automatic_collection_while_stepping(collector: SteppingCollector) -> None:
    collector.start()
    assert not gc.isenabled()
    assert gc.get_freeze_count() > 0  # the start-up's objects are out of every later collection
    garbage = cyclic_garbage()
    for _ in range(50_000):  # far beyond the youngest generation's threshold: would trigger a collection
        [object()]
    assert garbage() is not None


def test_safe_point_collects_the_young_garbage(collector: SteppingCollector) -> None:
    collector.start()
    garbage = cyclic_garbage()
    collector.safe_point()
    assert garbage() is None


def test_every_full_every_th_safe_point_collects_the_oldest_generation(collector: SteppingCollector) -> None:
    """Cyclic garbage that reached the oldest generation alive is freed at a safe point, not only at the stop."""
    collector.start()
    held = Cycle()
    garbage = weakref.ref(held)
    collector.safe_point()
    collector.safe_point()  # two young collections: the cycle, still held, is in the oldest generation now
    del held
    for _ in range(FULL_EVERY - 3):
        collector.safe_point()
    assert garbage() is not None  # young collections leave it
    collector.safe_point()  # the FULL_EVERY-th
    assert garbage() is None


def test_stop_gives_back_automatic_collection(collector: SteppingCollector) -> None:
    collector.start()
    collector.stop()
    assert gc.isenabled()


def test_a_disabled_collector_is_left_alone(collector: SteppingCollector) -> None:
    gc.disable()
    collector.start()
    garbage = cyclic_garbage()
    collector.safe_point()  # not paused by it: not its to collect
    collector.stop()
    assert not gc.isenabled()
    assert garbage() is not None
    gc.collect()
