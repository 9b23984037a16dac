"""`world.import`: site files (gcs_swarm.site) merged into the mission file before it is validated
(docs/site.md).

Paths are relative to the mission file's folder. What the files give is added as if written in the mission:
fence polygon, exclusion zones, prisms, cylinders and rally points add to the mission's own (the fence
polygon and the route may be given once, by the mission or by one file); the files' home position is the
origin and their take-off altitude the formation altitude unless the mission gives them. An imported value
is named in messages by the import entry's line and "world.import[k] (file: feature)".
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from gcs_swarm.mission.yaml_tree import Node

# keys whose imported entries add to the mission's list
_LISTS = (
    ("safety", "geofence", "exclusions"),
    ("safety", "rally"),
    ("world", "prisms"),
    ("world", "cylinders"),
)
# keys the mission or one file may give; the mission's own wins for these (a frame and a default, not data)
_DEFAULTS = (("origin",), ("formation", "altitude"))
# keys given once: by the mission or by the files, not both
_ONCE = (("safety", "geofence", "polygon"), ("waypoints",))


def with_imports(root: Node, imports: list[str], source: str) -> Node:
    """`root` with the sites of the `imports` (world.import) merged in; MissionError naming the import entry
    and the file's feature on any mistake. gcs_swarm.site (fastkml, shapely) is imported only here, for the
    missions that import files."""
    from gcs_swarm.site import SiteError, merge_sites, mission_fragment, read_site

    folder = Path(source).parent if not source.startswith("<") else Path(".")
    sites = []
    for k, written in enumerate(imports):
        entry = root.at(("world", "import", k))
        path = Path(written).expanduser()
        try:
            sites.append(read_site(path if path.is_absolute() else folder / path, name=written))
        except SiteError as exc:
            raise entry.error(str(exc)) from None
    try:
        site = merge_sites(sites)
    except SiteError as exc:
        raise root.at(("world", "import")).error(str(exc)) from None
    fragment = mission_fragment(site)
    anchor = root.at(("world", "import"))
    merged = root
    for loc in _LISTS + _DEFAULTS + _ONCE:
        value = _get(fragment, loc)
        if value is None:
            continue
        given = root.at(loc)
        label = f"world.import ({site.source})"
        if loc in _LISTS:
            items = list(given.value) if isinstance(given.value, list) else []
            for entry in value:
                where = entry.get("name", label) if isinstance(entry, dict) else label
                items.append(_tree(entry, anchor.line, f"world.import ({where})", root.source))
            merged = _put(merged, loc, Node(items, given.line, given.path, root.source))
        elif given.value is not None and loc in _ONCE or (loc == ("waypoints",) and _has_goal(root)):
            raise given.error(f"is given here and by {label}; give it once")
        elif given.value is None:
            merged = _put(merged, loc, _tree(value, anchor.line, label, root.source))
    return merged


def _has_goal(root: Node) -> bool:
    return isinstance(root.value, dict) and "goal" in root.value


def _get(data: dict[str, Any], loc: tuple[str, ...]) -> Any:
    for key in loc:
        if not isinstance(data, dict) or key not in data:
            return None
        data = data[key]
    return data


def _tree(value: object, line: int, path: str, source: str) -> Node:
    """Plain data as Nodes at `line`, named `path` and below."""
    if isinstance(value, dict):
        children = {key: _tree(item, line, f"{path}.{key}", source) for key, item in value.items()}
        return Node(children, line, path, source)
    if isinstance(value, list):
        return Node(
            [_tree(item, line, f"{path}[{i}]", source) for i, item in enumerate(value)], line, path, source
        )
    return Node(value, line, path, source)


def _put(node: Node, loc: tuple[str, ...], value: Node) -> Node:
    """A copy of `node` with `value` at `loc` (mappings made where missing; a section written null is
    one)."""
    if not loc:
        return value
    entries = dict(node.value) if isinstance(node.value, dict) else {}
    if not isinstance(node.value, dict) and node.value is not None:
        raise node.error("expected a mapping of keys to values, to merge world.import into")
    key = loc[0]
    child = entries.get(key) or Node(None, node.line, f"{node.path}.{key}" if node.path else key, node.source)
    entries[key] = _put(child, loc[1:], value)
    return Node(entries, node.line, node.path, node.source)
