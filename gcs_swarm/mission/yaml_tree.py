"""YAML text -> a tree of plain values that remember their line and field path.

Uses `yaml.compose` (node marks) instead of `yaml.safe_load`, so every later complaint can name file, line and
field. Reads `1e5` as a float (YAML 1.2 rule; PyYAML's YAML 1.1 resolver would give the string '1e5'), rejects
duplicate keys, and turns every parser failure into a `MissionError`.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass

import yaml
from yaml.nodes import MappingNode, ScalarNode, SequenceNode

MAX_NODES = 100_000  # bounds alias expansion ("billion laughs") and absurd files

_TAG = "tag:yaml.org,2002:"
_MERGE = _TAG + "merge"


class MissionError(Exception):
    """A mistake in a mission file; str(e) is one sentence naming the file, the line and the field."""


@dataclass(frozen=True)
class Node:
    """One YAML value: None, bool, int, float, str, list[Node] or dict[str, Node], with where it came from."""

    value: object
    line: int  # 1-based; for a mapping entry, the line of its key
    path: str  # field path such as "vehicles[2].start.position"; "" for the whole file
    source: str  # the file name as given

    def error(self, message: str) -> MissionError:
        """A MissionError "source:line: path: message"."""
        where = f"{self.path}: " if self.path else ""
        return MissionError(f"{self.source}:{self.line}: {where}{message}")

    def plain(self) -> object:
        """The value as plain Python data (lists and dicts of values), without lines."""
        if isinstance(self.value, list):
            return [item.plain() for item in self.value]
        if isinstance(self.value, dict):
            return {key: item.plain() for key, item in self.value.items()}
        return self.value

    def at(self, loc: Sequence[str | int]) -> Node:
        """The node at `loc` (mapping keys and list indexes) below this one. Where the file does not give that
        value, a stand-in named by the full path at the line of the closest node that is given (to blame a
        missing or defaulted key)."""
        node = self
        for depth, step in enumerate(loc):
            value = node.value
            if isinstance(value, dict) and isinstance(step, str) and step in value:
                node = value[step]
            elif isinstance(value, list) and isinstance(step, int) and 0 <= step < len(value):
                node = value[step]
            else:
                return Node(None, node.line, loc_path(loc[depth:], node.path), self.source)
        return node


def child_path(parent: str, key: str) -> str:
    """Field path of `key` inside the mapping at `parent` ("a.b", or "a['odd key']")."""
    if re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", key):
        return f"{parent}.{key}" if parent else key
    return f"{parent}[{key!r}]"


def loc_path(loc: Sequence[str | int], parent: str = "") -> str:
    """Field path of `loc` (mapping keys and list indexes) below `parent`: ("a", 2, "b") -> "a[2].b"."""
    path = parent
    for step in loc:
        path = child_path(path, step) if isinstance(step, str) else f"{path}[{step}]"
    return path


class YamlLoader(yaml.SafeLoader):
    """SafeLoader that also resolves YAML 1.2 floats such as 1e5, 1.5e5 and 2E-3 (for every YAML file the
    ground station reads: missions, Monte Carlo ranges)."""


YamlLoader.add_implicit_resolver(
    _TAG + "float",
    re.compile(r"^[-+]?(?:[0-9][0-9_]*(?:\.[0-9_]*)?|\.[0-9_]+)[eE][-+]?[0-9]+$"),
    list("-+0123456789."),
)


def parse_yaml(text: str, source: str) -> Node:
    """Parse one YAML document into a Node tree; MissionError for syntax errors, empty files, bad tags."""
    loader = None
    try:
        loader = YamlLoader(text)
        root = loader.get_single_node()
        if root is None:
            raise MissionError(
                f"{source}:1: the file is empty; a mission needs at least 'vehicles' and 'goal'"
            )
        return _Converter(loader, source).convert(root, "", root.start_mark.line + 1)
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        line = mark.line + 1 if mark is not None else 1
        parts = [part for part in (exc.context, exc.problem) if part]
        problem = " ".join(", ".join(parts).split()) or "invalid YAML"
        raise MissionError(f"{source}:{line}: YAML syntax error: {problem}") from None
    except yaml.reader.ReaderError as exc:
        line = text.count("\n", 0, max(exc.position, 0)) + 1
        code = exc.character if isinstance(exc.character, int) else ord(str(exc.character)[:1] or "\0")
        raise MissionError(f"{source}:{line}: the character U+{code:04X} is not allowed in YAML") from None
    except yaml.YAMLError as exc:
        problem = " ".join(str(exc).split())
        raise MissionError(f"{source}:1: YAML error: {problem}") from None
    except RecursionError:
        raise MissionError(f"{source}:1: the YAML is nested too deeply") from None
    finally:
        if loader is not None:
            loader.dispose()


class _Converter:
    """Walks composed YAML nodes into `Node`s (aliases expanded, merges `<<` applied)."""

    def __init__(self, loader: YamlLoader, source: str) -> None:
        self._loader = loader
        self._source = source
        self._count = 0
        self._active: set[int] = set()  # node ids on the current path, to catch recursive aliases

    def convert(self, node: yaml.Node, path: str, line: int) -> Node:
        self._count += 1
        if self._count > MAX_NODES:
            raise MissionError(f"{self._source}:{line}: the file has more than {MAX_NODES} values")
        if id(node) in self._active:
            raise self._error(line, path, "an alias refers to a value that contains it")
        self._active.add(id(node))
        try:
            if isinstance(node, ScalarNode):
                return Node(self._scalar(node, path, line), line, path, self._source)
            if isinstance(node, SequenceNode) and node.tag == _TAG + "seq":
                items = [
                    self.convert(item, f"{path}[{i}]", item.start_mark.line + 1)
                    for i, item in enumerate(node.value)
                ]
                return Node(items, line, path, self._source)
            if isinstance(node, MappingNode) and node.tag == _TAG + "map":
                return Node(self._mapping(node, path), line, path, self._source)
            raise self._error(line, path, f"unsupported YAML tag {node.tag!r}")
        finally:
            self._active.discard(id(node))

    def _scalar(self, node: ScalarNode, path: str, line: int) -> object:
        kind = node.tag.removeprefix(_TAG)
        constructors = {
            "null": lambda n: None,
            "bool": self._loader.construct_yaml_bool,
            "int": self._loader.construct_yaml_int,
            "float": self._loader.construct_yaml_float,
            "str": lambda n: n.value,
            "timestamp": lambda n: n.value,  # dates are not mission values; keep the text for the message
        }
        if not node.tag.startswith(_TAG) or kind not in constructors:
            raise self._error(line, path, f"unsupported YAML tag {node.tag!r}")
        try:
            return constructors[kind](node)
        except Exception:  # PyYAML's constructors raise assorted errors on e.g. `!!int ''` or `!!float x`
            raise self._error(line, path, f"{node.value!r} is not a valid {kind}") from None

    def _mapping(self, node: MappingNode, path: str) -> dict[str, Node]:
        first_line: dict[str, int] = {}
        for key_node, _ in node.value:
            if key_node.tag == _MERGE:
                continue
            key = self._key(key_node, path)
            if key in first_line:
                line = key_node.start_mark.line + 1
                raise self._error(
                    line, child_path(path, key), f"duplicate key (first given on line {first_line[key]})"
                )
            first_line[key] = key_node.start_mark.line + 1
        self._loader.flatten_mapping(node)  # applies `<<: *anchor` merges; explicit keys come last and win
        entries: dict[str, Node] = {}
        for key_node, value_node in node.value:
            key = self._key(key_node, path)
            entries[key] = self.convert(value_node, child_path(path, key), key_node.start_mark.line + 1)
        return entries

    def _key(self, key_node: yaml.Node, path: str) -> str:
        if not isinstance(key_node, ScalarNode):
            raise self._error(key_node.start_mark.line + 1, path, "mapping keys must be plain words")
        return str(key_node.value)

    def _error(self, line: int, path: str, message: str) -> MissionError:
        return Node(None, line, path, self._source).error(message)
