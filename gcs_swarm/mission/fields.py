"""Typed reading of YAML values: numbers, vectors, choices and checked mappings, each failure a MissionError.

Numbers must be real YAML numbers (a quoted "10" or `true` is refused), finite, and inside the stated range.
"""

from __future__ import annotations

import dataclasses
import difflib
import math
import re
from collections.abc import Iterable, Mapping
from typing import TypeVar

import numpy as np

from gcs_swarm.mission.model import frozen_vector
from gcs_swarm.mission.yaml_tree import MissionError, Node

P = TypeVar("P")


def describe(value: object) -> str:
    """How a YAML value reads in an error message."""
    if value is None:
        return "nothing (null)"
    if isinstance(value, bool):
        return f"the boolean {str(value).lower()}"
    if isinstance(value, float):
        return f"the number {value:g}"
    if isinstance(value, int):
        digits = str(value)
        return f"the number {digits}" if len(digits) <= 20 else f"a {len(digits)}-digit number"
    if isinstance(value, str):
        shown = value if len(value) <= 40 else value[:37] + "..."
        return f"the text {shown!r}"
    if isinstance(value, list):
        return f"a list of {len(value)}"
    return "a mapping"


def _fmt(x: float) -> str:
    return f"{x:g}"


def number(
    node: Node,
    *,
    above: float | None = None,
    at_least: float | None = None,
    below: float | None = None,
    at_most: float | None = None,
    unit: str = "",
) -> float:
    """A finite number within bounds (`above`/`below` strict, `at_least`/`at_most` inclusive)."""
    value = node.value
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise node.error(f"expected a number, got {describe(value)}")
    try:
        x = float(value)
    except OverflowError:
        raise node.error("the number is too large") from None
    if not math.isfinite(x):
        raise node.error(f"expected a finite number, got {describe(x)}")
    u = f" {unit}" if unit else ""
    if above is not None and not x > above:
        raise node.error(f"must be > {_fmt(above)}{u}, got {_fmt(x)}")
    if at_least is not None and not x >= at_least:
        raise node.error(f"must be >= {_fmt(at_least)}{u}, got {_fmt(x)}")
    if below is not None and not x < below:
        raise node.error(f"must be < {_fmt(below)}{u}, got {_fmt(x)}")
    if at_most is not None and not x <= at_most:
        raise node.error(f"must be <= {_fmt(at_most)}{u}, got {_fmt(x)}")
    return x


def integer(node: Node, *, at_least: int | None = None, at_most: int | None = None) -> int:
    """A whole number (no fraction, not a boolean) within inclusive bounds."""
    value = node.value
    if isinstance(value, bool) or not isinstance(value, int):
        raise node.error(f"expected a whole number, got {describe(value)}")
    if at_least is not None and value < at_least:
        raise node.error(f"must be >= {at_least}, got {describe(value)}")
    if at_most is not None and value > at_most:
        raise node.error(f"must be <= {at_most}, got {describe(value)}")
    return value


def text(node: Node, *, pattern: str | None = None, hint: str = "") -> str:
    """A non-empty string, optionally matching `pattern` (then `hint` says what is expected)."""
    value = node.value
    if not isinstance(value, str):
        raise node.error(f"expected text, got {describe(value)}")
    if not value.strip():
        raise node.error("must not be empty")
    if pattern is not None and not re.fullmatch(pattern, value):
        raise node.error(f"{hint}, got {describe(value)}")
    return value


def choice(node: Node, options: Iterable[str]) -> str:
    """One of `options` (exact spelling)."""
    options = tuple(options)
    value = node.value
    if isinstance(value, str) and value in options:
        return value
    listed = ", ".join(repr(o) for o in options)
    close = difflib.get_close_matches(value, options, n=1) if isinstance(value, str) else []
    suggestion = f"; did you mean {close[0]!r}?" if close else ""
    raise node.error(f"expected one of {listed}, got {describe(value)}{suggestion}")


def flag(node: Node) -> bool:
    """true or false."""
    if not isinstance(node.value, bool):
        raise node.error(f"expected true or false, got {describe(node.value)}")
    return node.value


def items(node: Node) -> list[Node]:
    """The elements of a YAML list."""
    if not isinstance(node.value, list):
        raise node.error(f"expected a list, got {describe(node.value)}")
    return node.value


def vector(node: Node, size: int = 3) -> np.ndarray:
    """A read-only float array of exactly `size` finite numbers, shape (size,)."""
    value = node.value
    if not isinstance(value, list) or len(value) != size:
        got = f"{len(value)}" if isinstance(value, list) else describe(value)
        raise node.error(f"expected {size} numbers, got {got}")
    return frozen_vector([number(element) for element in value])


class Section:
    """A YAML mapping whose keys are checked against the allowed ones on construction; fields read by name."""

    def __init__(self, node: Node, allowed: Iterable[str], moved: Mapping[str, str] | None = None) -> None:
        """`moved` maps keys that belong elsewhere to their proper path, for a better hint."""
        if not isinstance(node.value, dict):
            raise node.error(f"expected a mapping of keys to values, got {describe(node.value)}")
        self.node = node
        self.entries: dict[str, Node] = node.value
        allowed = tuple(allowed)
        for key, child in self.entries.items():
            if key in allowed:
                continue
            if moved and key in moved:
                raise child.error(f"unknown key here; it belongs under '{moved[key]}'")
            close = difflib.get_close_matches(key, allowed, n=1, cutoff=0.6)
            if close:
                raise child.error(f"unknown key; did you mean {close[0]!r}?")
            raise child.error(f"unknown key (allowed here: {', '.join(allowed)})")

    @classmethod
    def within(cls, parent: Section, key: str, allowed: Iterable[str]) -> Section:
        """The sub-mapping `parent[key]`; absent or null reads as empty (all defaults)."""
        node = parent.get(key)
        if node is None or node.value is None:
            line = parent.node.line if node is None else node.line
            node = Node({}, line, _join(parent.node.path, key), parent.node.source)
        return cls(node, allowed)

    def get(self, key: str) -> Node | None:
        """The value node of `key`, or None when absent."""
        return self.entries.get(key)

    def require(self, key: str) -> Node:
        """The value node of `key`; a MissionError at the mapping's line when absent."""
        node = self.entries.get(key)
        if node is None:
            missing = Node(None, self.node.line, _join(self.node.path, key), self.node.source)
            raise missing.error("required key is missing")
        return node

    def number(
        self,
        key: str,
        default: float,
        *,
        above: float | None = None,
        at_least: float | None = None,
        below: float | None = None,
        at_most: float | None = None,
        unit: str = "",
    ) -> float:
        """`number(...)` of `key`, or `default` when absent."""
        node = self.get(key)
        if node is None:
            return default
        return number(node, above=above, at_least=at_least, below=below, at_most=at_most, unit=unit)

    def integer(
        self, key: str, default: int, *, at_least: int | None = None, at_most: int | None = None
    ) -> int:
        """`integer(...)` of `key`, or `default` when absent."""
        node = self.get(key)
        return default if node is None else integer(node, at_least=at_least, at_most=at_most)

    def text(self, key: str, default: str, *, pattern: str | None = None, hint: str = "") -> str:
        """`text(...)` of `key`, or `default` when absent."""
        node = self.get(key)
        return default if node is None else text(node, pattern=pattern, hint=hint)

    def choice(self, key: str, default: str, options: Iterable[str]) -> str:
        """`choice(...)` of `key`, or `default` when absent."""
        node = self.get(key)
        return default if node is None else choice(node, options)

    def flag(self, key: str, default: bool) -> bool:
        """`flag(...)` of `key`, or `default` when absent."""
        node = self.get(key)
        return default if node is None else flag(node)

    def vector(self, key: str, default: np.ndarray) -> np.ndarray:
        """A 3-vector, or `default` when absent."""
        node = self.get(key)
        return default if node is None else vector(node)

    def optional_vector(self, key: str) -> np.ndarray | None:
        """A 3-vector, or None when absent or null."""
        node = self.get(key)
        return None if node is None or node.value is None else vector(node)

    def line_of(self, key: str) -> Node:
        """The value node of `key` if given, else the mapping itself (to blame a cross-field mistake)."""
        return self.get(key) or self.node


def _join(parent: str, key: str) -> str:
    return f"{parent}.{key}" if parent else key


def param_fields(base: object) -> tuple[str, ...]:
    """Field names of a params dataclass instance: the YAML keys of its section."""
    return tuple(f.name for f in dataclasses.fields(base))  # type: ignore[arg-type]


def params(section: Section, base: P) -> P:
    """A copy of the params dataclass `base` (gcs_swarm.guidance.params) with the values the section gives.

    Keys are the field names; nested dataclasses are nested mappings (partial ones keep the other defaults).
    The dataclass's own ValueError (e.g. SMC k1*c1 <= 1/4) becomes a MissionError at the field it names.
    """
    values: dict[str, object] = {}
    for f in dataclasses.fields(base):  # type: ignore[arg-type]
        current = getattr(base, f.name)
        node = section.get(f.name)
        if node is None:
            values[f.name] = current
        elif dataclasses.is_dataclass(current):
            values[f.name] = params(Section.within(section, f.name, param_fields(current)), current)
        elif f.type == "bool":
            values[f.name] = flag(node)
        elif f.type == "str":
            values[f.name] = text(node)
        elif f.type == "float | None":
            values[f.name] = None if node.value is None else number(node)
        elif f.type == "float":
            values[f.name] = number(node)
        else:
            raise TypeError(f"params(): unsupported field type {f.type!r} of {type(base).__name__}.{f.name}")
    try:
        return type(base)(**values)
    except ValueError as exc:
        raise _blame(section, str(exc)) from None


def _blame(section: Section, message: str) -> MissionError:
    """The error of the first given key the message names, else of the whole section."""
    for key, node in section.entries.items():
        if re.search(rf"(?<![A-Za-z0-9_]){re.escape(key)}(?![A-Za-z0-9_])", message):
            return node.error(message)
    return section.node.error(message)


__all__ = [
    "MissionError",
    "Section",
    "choice",
    "describe",
    "flag",
    "integer",
    "items",
    "number",
    "param_fields",
    "params",
    "text",
    "vector",
]
