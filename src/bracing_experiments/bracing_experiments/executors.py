"""Where the runs of a sweep execute, behind one interface: worker processes on this machine
(concurrent.futures) or a Dask distributed cluster (a scheduler address, or a LocalCluster).

    with make_executor(workers=2) as executor:              # or scheduler="tcp://host:8786"
        for item, result, error in executor.run(execute_run, specs):
            ...

``run`` yields each item as it completes, with its result or the executor's error (a lost
worker pool, a task the cluster gave up on). ``cancel`` drops what has not finished (Ctrl-C).
"""

from __future__ import annotations

import multiprocessing
import os
import threading
from abc import ABC, abstractmethod
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import Future, ProcessPoolExecutor, as_completed
from types import TracebackType
from typing import Any, Self, TypeVar

from bracing_core.params import ConfigError
from bracing_core.workers import ignore_sigint

Item = TypeVar("Item")
Result = TypeVar("Result")


STOP_REQUESTED = threading.Event()
"""Set by the commands' Ctrl-C/SIGTERM handler (cli.handle_stop_signals) besides raising
KeyboardInterrupt: a signal that lands while Python runs a finalizer (a weakref callback, __del__)
has its KeyboardInterrupt printed and dropped ("Exception ignored in"), seen once in CI as a
bracing-optimize that ran all its trials after Ctrl-C. ``Executor.run`` raises it again at the next result."""


class Executor(ABC):
    description = ""

    def run(
        self, fn: Callable[[Item], Result], items: Sequence[Item], keys: Sequence[str] | None = None
    ) -> Iterator[tuple[Item, Result | None, BaseException | None]]:
        """Submit ``fn(item)`` for every item; yield (item, result, None) or (item, None, error) as each
        completes. ``keys``: a unique name per item (Dask task keys). A stop requested (STOP_REQUESTED)
        raises KeyboardInterrupt before the next item is yielded."""
        for outcome in self._run(fn, items, keys):
            if STOP_REQUESTED.is_set():
                raise KeyboardInterrupt
            yield outcome

    @abstractmethod
    def _run(
        self, fn: Callable[[Item], Result], items: Sequence[Item], keys: Sequence[str] | None
    ) -> Iterator[tuple[Item, Result | None, BaseException | None]]: ...

    @abstractmethod
    def cancel(self) -> None:
        """Drop pending and running work (the caller stops iterating)."""

    @abstractmethod
    def close(self) -> None: ...

    @property
    @abstractmethod
    def workers(self) -> int: ...

    def __enter__(self) -> Self:
        return self

    def __exit__(self, kind: type[BaseException] | None, value: BaseException | None, tb: TracebackType | None) -> None:
        if kind is not None:
            self.cancel()
        self.close()


class LocalExecutor(Executor):
    """``workers`` processes on this machine (spawned: no threads or locks inherited from the parent)."""

    def __init__(self, workers: int | None = None) -> None:
        self._workers = workers or os.cpu_count() or 1
        self._pool = ProcessPoolExecutor(
            self._workers, mp_context=multiprocessing.get_context("spawn"), initializer=ignore_sigint
        )
        self._futures: list[Future[Any]] = []
        self.description = f"{self._workers} local worker process{'es' if self._workers > 1 else ''}"

    @property
    def workers(self) -> int:
        return self._workers

    def _run(
        self, fn: Callable[[Item], Result], items: Sequence[Item], keys: Sequence[str] | None = None
    ) -> Iterator[tuple[Item, Result | None, BaseException | None]]:
        futures = {self._pool.submit(fn, item): item for item in items}
        self._futures = list(futures)
        for future in as_completed(futures):
            error = future.exception()
            yield futures[future], None if error else future.result(), error

    def cancel(self) -> None:
        for future in self._futures:
            future.cancel()
        # Running runs cannot be cancelled; their processes are ended (Python 3.11 has no public
        # terminate for a pool, hence the private mapping).
        processes = dict(getattr(self._pool, "_processes", None) or {})
        self._pool.shutdown(wait=False, cancel_futures=True)
        for process in processes.values():
            if process.is_alive():
                process.terminate()
        for process in processes.values():
            process.join(5.0)

    def close(self) -> None:
        self._pool.shutdown(wait=True, cancel_futures=True)


class DaskExecutor(Executor):
    """A Dask distributed cluster: ``address`` (tcp://host:port of a running ``dask scheduler``), or,
    with ``address=None``, a LocalCluster of ``workers`` single-threaded processes.

    The scheduler re-runs the tasks of a worker that dies on another worker; a task is given up
    (its error yielded) only after ``distributed.scheduler.allowed-failures`` lost workers.
    """

    def __init__(self, address: str | None = None, workers: int | None = None, timeout: float = 30.0) -> None:
        from distributed import Client, LocalCluster  # imported where used: distributed ~340 ms (python -X importtime)

        self._cluster = None
        if address is None:
            self._cluster = LocalCluster(
                n_workers=workers or os.cpu_count() or 1,
                threads_per_worker=1,  # the runs are GIL-bound numerics: one process per core
                processes=True,
                dashboard_address=None,
                host="127.0.0.1",
            )
            self._client = Client(self._cluster, timeout=timeout)
        else:
            self._client = Client(address, timeout=timeout)
        self._futures: list[Any] = []
        where = address or "a Dask LocalCluster"
        self.description = f"{where} ({self.workers} worker thread(s))"

    @property
    def client(self) -> Any:
        return self._client

    @property
    def workers(self) -> int:
        info = self._client.scheduler_info(n_workers=-1)
        return sum(int(w.get("nthreads", 1)) for w in info.get("workers", {}).values()) or 1

    def _run(
        self, fn: Callable[[Item], Result], items: Sequence[Item], keys: Sequence[str] | None = None
    ) -> Iterator[tuple[Item, Result | None, BaseException | None]]:
        from distributed import as_completed as dask_as_completed  # distributed ~340 ms, where used

        names = list(keys) if keys is not None else [None] * len(items)
        futures = {
            self._client.submit(fn, item, key=name, pure=False): item for item, name in zip(items, names, strict=True)
        }
        self._futures = list(futures)
        for future in dask_as_completed(futures):
            try:
                result = future.result()
            except Exception as exc:  # KilledWorker, a lost connection: the caller decides
                yield futures[future], None, exc
            else:
                yield futures[future], result, None
            future.release()  # the result is the client's now; free the worker's memory

    def cancel(self) -> None:
        if self._futures:
            self._client.cancel(self._futures, force=True)

    def close(self) -> None:
        self._client.close()
        if self._cluster is not None:
            self._cluster.close()


def make_executor(workers: int | None = None, scheduler: str | None = None) -> Executor:
    """Local processes by default; ``scheduler``: a Dask scheduler address, or ``local`` for a LocalCluster.

    Raises ConfigError naming ``--scheduler`` when there is no scheduler at that address.
    """
    if scheduler is None:
        return LocalExecutor(workers)
    try:
        return DaskExecutor(None, workers) if scheduler == "local" else DaskExecutor(scheduler)
    except (OSError, TimeoutError) as exc:
        raise ConfigError(f"--scheduler {scheduler}: {exc}") from None
