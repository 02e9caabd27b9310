"""Sweep throughput: in-process runs of the paper scenario per minute through bracing-sweep's
executors (1 and 2 local worker processes, a Dask LocalCluster of 2 single-threaded workers),
and the parallel efficiency rate(2 local) / (2 x rate(1 local)).

Each executor is warmed up first (its processes started, the model libraries imported), so the
rate is that of a long sweep; the start-up is reported apart. Measurements alternate between
the executors, repeats times, and the medians are kept: this machine's speed drifts.

    python bench/sweep_bench.py [--quick]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
PAPER = HERE.parent / "config" / "paper_4link.yaml"
EXECUTORS = {"local_1": (1, None), "local_2": (2, None), "dask_local_2": (2, "local")}


def _specs(runs: int, duration: float, tag: int) -> list[Any]:
    from bracing_experiments.sweep import build_specs

    # Distinct forces around the paper's 10 N: distinct runs of the same cost; ``tag`` makes ids unique.
    forces = ",".join(f"{10.0 + 0.01 * k + 1e-6 * tag:.6f}" for k in range(runs))
    return build_specs(PAPER, [f"contacts.elbow.desired_normal_force={forces}"], False, duration)


def sweep_throughput(runs: int = 16, duration: float = 10.0, repeats: int = 2) -> dict[str, Any]:
    # 16 runs a sweep: a sweep's fixed costs (validating every run's configuration, the results
    # table) are what a 2-worker sweep of 8 runs waits on (efficiency 0.82 on a quiet machine);
    # at 16 they weigh as in a real sweep (0.94 the same hour).
    from bracing_experiments.executors import make_executor
    from bracing_experiments.running import run_sweep

    load_before = os.getloadavg()[0]  # other work on the machine takes cores from the workers
    samples: dict[str, list[float]] = {name: [] for name in EXECUTORS}
    run_seconds: dict[str, list[float]] = {name: [] for name in EXECUTORS}  # each run's own wall time
    startup: dict[str, float] = {}
    executors = {}
    try:
        for name, (workers, scheduler) in EXECUTORS.items():  # all started first: idle workers cost nothing
            start = time.perf_counter()
            executors[name] = make_executor(workers, scheduler)
            with tempfile.TemporaryDirectory(prefix="bench_sweep_") as folder:
                run_sweep(_specs(2 * workers, 0.01, -1), Path(folder), executors[name], progress=False)  # warm-up
            startup[name] = time.perf_counter() - start
        tag = 0
        for _ in range(repeats):
            for name, executor in executors.items():
                tag += 1
                with tempfile.TemporaryDirectory(prefix="bench_sweep_") as folder:
                    result = run_sweep(_specs(runs, duration, tag), Path(folder), executor, progress=False)
                if result.ran != runs or result.failed or result.lost:
                    raise RuntimeError(f"sweep bench: {name}: {result.ran} of {runs} runs, {result.failed} failed")
                samples[name].append(60.0 * runs / result.wall_time_s)
                run_seconds[name] += [float(row["wall_time_s"]) for row in result.rows]
    finally:
        for executor in executors.values():
            executor.close()
    rates = {name: statistics.median(values) for name, values in samples.items()}
    return {
        "runs_per_min": rates,
        "parallel_efficiency": rates["local_2"] / (2.0 * rates["local_1"]),
        "dask_vs_local_2": rates["dask_local_2"] / rates["local_2"],
        "samples": samples,
        "startup_s": startup,
        # A run slower with 2 workers than with 1 means the cores were shared (other load), not overhead.
        "mean_run_s": {name: statistics.mean(values) for name, values in run_seconds.items()},
        "load_average_1min": [load_before, os.getloadavg()[0]],
        "runs": runs,
        "run_sim_time_s": duration,
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="4 runs of 2 s, once")
    args = parser.parse_args(argv)
    result = sweep_throughput(4, 2.0, 1) if args.quick else sweep_throughput()
    print(json.dumps(result, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
