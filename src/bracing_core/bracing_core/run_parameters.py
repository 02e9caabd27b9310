"""Which parameter changes a running node takes, and when: the rule both nodes apply to a ``ros2 param set``.

A ``per_run`` parameter (``bracing``, ``free_space``) is accepted by either node while it runs and taken from its
next run on: the simulator builds that run at ``reset_simulation``, the controller when its states go back in time,
each from its parameters as they then are, as a fresh process started with them builds it. A ``tunable`` one the
controller takes from its next state on (``StateAnswerer.retune``). Any other change is refused with the reason
(it needs a fresh start). A value is checked as at start (``schema.read`` and the node's configuration): a bad one
is refused with the message a start with it would print. No ROS here: the nodes wire it to their parameter
services.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from typing import Any

from bracing_core import schema

NODES = ("simulator", "controller")


def takes_live(node: str, name: str) -> bool:
    """Whether ``node`` applies a new value of ``name`` while a run goes on (the controller's tunable ones)."""
    param = schema.find(node, name)
    return node == "controller" and param is not None and param.tunable


def is_per_run(node: str, name: str) -> bool:
    """Whether ``name`` is one of ``node``'s per-run parameters (taken from its next run on)."""
    param = schema.find(node, name)
    return param is not None and param.per_run


def refusal(node: str, names: Iterable[str]) -> str | None:
    """Why ``node`` refuses, while it runs, a change of these parameters (None: it takes every one of them)."""
    assert node in NODES, node
    for name in names:
        if schema.find(node, name) is None:
            return f"{name}: cannot change while running: not a parameter of the {node}"
        if not (is_per_run(node, name) or takes_live(node, name)):
            return (
                f"{name}: cannot change while running: it needs a fresh start (a new {node} process started with "
                "the new value)"
            )
    return None


def per_run_changes(node: str, changes: Sequence[tuple[str, Any]]) -> list[tuple[str, Any]]:
    """The changes of per-run parameters among ``changes`` ((name, value), in order)."""
    return [(name, value) for name, value in changes if is_per_run(node, name)]


def running_values(node: str, params: Mapping[str, Any], running: Mapping[str, Any]) -> dict[str, Any]:
    """``params`` (the node's parameters as they are now) with each per-run one as the running run has it
    (``running``): what a change that applies while this run goes on (a retune) is checked against."""
    return {**params, **{name: value for name, value in running.items() if is_per_run(node, name)}}


def per_run_values(node: str, params: Mapping[str, Any]) -> dict[str, Any]:
    """The per-run parameters among ``params``, by name: what a run was built with."""
    return {name: value for name, value in params.items() if is_per_run(node, name)}


def next_run_values(node: str, params: Mapping[str, Any], changes: Sequence[tuple[str, Any]]) -> schema.Values:
    """The node's typed values for a run started with ``params`` changed by ``changes``; a ConfigError, with the
    message a start with them would print, for a bad one."""
    given = dict(params)
    for name, value in changes:
        given[name] = value
    return schema.read(node, given)
