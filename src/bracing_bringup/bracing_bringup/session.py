"""Runs in turn through one simulator, controller and recorder (``Session``): make run's three.

The first run starts the processes as bracing-pair does, but the simulator stays at its run's end
(``wait_for_reset``) and the recorder waits for its next bag (``--stay``). A next run whose plan differs
only in its per-run parameters (``bracing``, ``free_space``, the output) is begun through them: its bag asked
of the recorder, the parameters set on both nodes (applied at the reset), reset_simulation called. Each run is
supervised, checked and reported as a fresh one (``supervision``). A run that needs other processes (another
URDF, engine, duration...) ends the session cleanly and starts fresh ones; so does any run after a failed one.
The session holds its ROS domain id until it is closed.

A service response can be lost (Fast DDS drops one whose reader the server has not matched yet): a parameter
set is asked again after PARAMETER_ANSWER_S without answer (it is idempotent); the reset is not (a second
one would cut the run short), and is confirmed by its effect, the simulator stepping (the stall timeout).
"""

from __future__ import annotations

import dataclasses
import time
from contextlib import ExitStack
from pathlib import Path
from types import TracebackType
from typing import TYPE_CHECKING, Any

from bracing_bringup.domains import hold_domain
from bracing_bringup.processes import Pair
from bracing_bringup.run_plan import MUJOCO, PARAMS_FILE, RunOptions, RunPlan
from bracing_bringup.supervision import RunResult, _Failure, _run_pair
from bracing_bringup.timeline import Timeline
from bracing_core.overrides import CONTROLLER, SIMULATOR

if TYPE_CHECKING:
    from bracing_ros.status import StatusWatcher

PER_RUN = ("bracing", "free_space")
"""The options a run may change in a session: parameters the nodes take at a reset."""
UNCOUNTED = ("output", "command_start", "animation", "show_timeline", "rrd", "quiet")
"""The options no process depends on (this process's own)."""
PARAMETER_ANSWER_S = 3.0  # [s] wall before a parameter set is asked again (its response lost)
PARAMETER_ATTEMPTS = 10
RESET_ANSWER_S = 10.0  # [s] wall the reset's response is waited for (not needed: its effect is watched)
SERVICE_START_S = 30.0  # [s] wall a node's service may take to appear
NEXT_BAG = "/bracing_recorder_next_bag"


def processes_of(options: RunOptions) -> RunOptions:
    """What of ``options`` the processes depend on, beyond the per-run parameters: two runs with equal ones can
    share them."""
    defaults = RunOptions(options.config, Path())
    return dataclasses.replace(options, **{key: getattr(defaults, key) for key in (*PER_RUN, *UNCOUNTED)})


def reusable(options: RunOptions) -> bool:
    """Whether a run of ``options`` can go through kept processes: a lockstep run of our simulator, unwatched
    (--view's viewer follows one run)."""
    return options.engine != MUJOCO and not options.real_time and not options.view


class Session:
    """The processes kept between runs (see the module's docstring); use as a context manager."""

    def __init__(self) -> None:
        self.pair: Pair | None = None
        self.watcher: StatusWatcher | None = None
        self.options: RunOptions | None = None  # processes_of the running processes' first run
        self._domain = ExitStack()
        self._clients: dict[str, Any] = {}

    def __enter__(self) -> Session:
        return self

    def __exit__(self, kind: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None) -> None:
        self.close()

    @property
    def running(self) -> bool:
        """Whether processes are kept for the next run."""
        return self.watcher is not None

    def run(self, options: RunOptions) -> RunResult:
        """One run, through the kept processes if they can make it, else fresh ones (kept for the next run)."""
        if not self.running or processes_of(options) != self.options:
            self.close()  # another URDF, duration, engine... (or none kept): fresh processes
        if not reusable(options):
            from bracing_bringup.supervision import run_pair

            return run_pair(options)
        if self.options is None:
            domain = self._domain.enter_context(hold_domain(options.domain_id))
            self.domain_id, self.options = domain.domain_id, processes_of(options)
        try:
            return _run_pair(options, self.domain_id, self)
        except BaseException:  # a ConfigError, Ctrl-C...: the processes are not left for a next run
            self.close()
            raise

    def prepare(self, plan: RunPlan) -> None:
        """The run's parameters as the kept processes need them: the simulator stays at its run's end."""
        plan.node_params[SIMULATOR]["wait_for_reset"] = True

    def pair_for(self, options: RunOptions, timeline: Timeline) -> Pair:
        """The run's processes: the kept ones, or a new Pair that starts them."""
        if self.pair is None or not self.running:
            self.pair = Pair(options, timeline)
        else:
            self.pair.next_run(options, timeline)
        return self.pair

    def started(self, watcher: StatusWatcher) -> None:
        """The processes are started and ``watcher`` follows them: kept for the next run."""
        self.watcher = watcher

    def begin(self, plan: RunPlan) -> None:
        """The next run through the kept processes: its per-run parameters set on both nodes, its bag asked of the
        recorder (waited for until open), the simulation reset."""
        assert self.pair is not None
        out = plan.options.output
        for node in (SIMULATOR, CONTROLLER):  # before the bag opens: their parameter events are no run's
            self._set("/" + node, {key: getattr(plan.options, key) for key in PER_RUN})
        self._set(NEXT_BAG, {"output": str(out / "bag"), "params_files": [str(out / PARAMS_FILE)]})
        while "recorder ready" not in self.pair.seen:
            if self.pair.exit_code("recorder") is not None:
                raise _Failure("recorder", "the recorder exited before it opened the next bag")
            self.pair.wait_for_change(0.1)
        from std_srvs.srv import Empty

        self._call(Empty, "/reset_simulation", Empty.Request(), RESET_ANSWER_S, 1)

    def _set(self, node: str, values: dict[str, Any]) -> None:
        """Set ``node``'s parameters; _Failure if it refuses one or never answers."""
        from rcl_interfaces.srv import SetParameters
        from rclpy.parameter import Parameter

        request = SetParameters.Request()
        request.parameters = [Parameter(key, value=value).to_parameter_msg() for key, value in values.items()]
        name = node + "/set_parameters"
        response = self._call(SetParameters, name, request, PARAMETER_ANSWER_S, PARAMETER_ATTEMPTS)
        if response is None:
            raise _Failure(_process(node), f"{name}: no answer")
        refused = [result.reason for result in response.results if not result.successful]
        if refused:
            raise _Failure(_process(node), f"{name}: refused: {'; '.join(refused)}")

    def _call(self, kind: Any, name: str, request: Any, answer_s: float, attempts: int) -> Any:
        """``request`` to service ``name`` through the watcher's node, asked up to ``attempts`` times, each
        answer waited for ``answer_s`` [s]; the response, or None."""
        assert self.watcher is not None
        if not self.watcher.ready.wait(SERVICE_START_S) or self.watcher.node is None:
            raise _Failure("simulator", "the run's status watcher did not start")
        if name not in self._clients:
            self._clients[name] = self.watcher.node.create_client(kind, name)
        client = self._clients[name]
        if not client.wait_for_service(timeout_sec=SERVICE_START_S):
            raise _Failure(_process(name), f"no service {name}")
        for _ in range(attempts):
            future, deadline = client.call_async(request), time.monotonic() + answer_s
            while not future.done() and time.monotonic() < deadline:
                time.sleep(0.005)  # the watcher's thread spins the node and completes the future
            if future.done():
                return future.result()
        return None

    def close(self) -> dict[str, int | None]:
        """Stop the kept processes (in order) and free the domain; their exit codes."""
        codes: dict[str, int | None] = {}
        if self.pair is not None and self.running:
            codes = self.pair.stop_all()
        if self.watcher is not None:
            self.watcher.stop()
        self.pair, self.watcher, self.options, self._clients = None, None, None, {}
        self._domain.close()
        return codes


def _process(node: str) -> str:
    """The process that serves ``node``'s (or its service's) requests."""
    return next((name for name in ("simulator", "controller") if name in node), "recorder")
