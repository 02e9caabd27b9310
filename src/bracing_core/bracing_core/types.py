"""Shared type aliases, and the descriptor of an attribute forwarded to a compiled engine."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Generic, NewType, TypeVar, overload

import numpy as np
import numpy.typing as npt

Vector = npt.NDArray[np.float64]
Array = npt.NDArray[Any]
Mask = npt.NDArray[np.bool_]  # per contact or joint: whether it holds (a flag array)
T = TypeVar("T")

TaskIndex = NewType("TaskIndex", int)  # the law's task as the engine numbers it: HAND_TASK, then brace_task(j)
HAND_TASK = TaskIndex(0)


def brace_task(brace: int) -> TaskIndex:
    """The task of braced contact ``brace`` (0-based, in the configuration's order): after the hand's."""
    return TaskIndex(1 + brace)


class EngineField(Generic[T]):
    """An attribute its owner forwards to its compiled ``engine`` under the same name, converted by ``kind`` as it
    is read (and as it is written, where the engine's attribute is writable): one line per forwarded attribute."""

    def __init__(self, kind: Callable[[Any], T]) -> None:
        self.kind = kind
        self.name = ""

    def __set_name__(self, owner: type, name: str) -> None:
        self.name = name

    @overload
    def __get__(self, instance: None, owner: type | None = None) -> EngineField[T]: ...
    @overload
    def __get__(self, instance: object, owner: type | None = None) -> T: ...
    def __get__(self, instance: object | None, owner: type | None = None) -> T | EngineField[T]:
        if instance is None:  # on the class (documentation, introspection): the field itself
            return self
        return self.kind(getattr(instance.engine, self.name))  # type: ignore[attr-defined]

    def __set__(self, instance: object, value: T) -> None:
        setattr(instance.engine, self.name, self.kind(value))  # type: ignore[attr-defined]


def as_vector(value: Any) -> Vector:
    """``value`` as it is (the engine's arrays are float64 already): the ``kind`` of a forwarded array."""
    return value  # type: ignore[no-any-return]
