"""The leader's route round a gap its formation cannot fly through [add] (spec 6a.8, docs/iaapf-smc-spec.md).

Every vehicle keeps off an obstacle by its own repulsion (l0 = 20 m). Where two obstacles stand close, the
repulsion of both fills the gap between them: with the field's defaults a leader heading into a gap under
about 13 m between two spheres is held in front of it, where attraction and repulsion balance (the paper's
local minimum), and in flight breaks out only after 10-20 s by sinking under the spheres to where the gap is
wider, its followers coming through one by one, far from their slots (generated course gap-17).

So such a leg goes round. The still obstacles' footprints at the leg's height (a sphere's circle there, a
cylinder's circle, a prism's polygon) are grown by a clearance plus the half-width of the narrowest shape the
formation may fly; footprints that then overlap close a gap, and form a cluster. A leg whose straight line
crosses the convex hull of a cluster of two obstacles or more gets via points on the hulls, the shortest way
round (a visibility graph over the hulls' corners, scipy's Dijkstra); a leg past a single obstacle is left to
the field, whose circulation takes it round, and so is a leg that starts or ends inside a hull (no way round
to plan). The hulls' corners are thinned (Douglas-Peucker, `corner_tolerance` m, on a hull grown by as much
first, so the thinned hull still contains the grown footprints), so the route bends a few times, not at
every facet of a circle. Whether the leader's own field would hold it in front of the cluster (and the
detour is taken) is FleetController's question (leader_path.leader_stalls).

Shapes: points (2,) or (3,) ENU m; footprints and hulls shapely polygons in the horizontal plane.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import shapely
from scipy.sparse.csgraph import dijkstra

from swarm_common.obstacle_shapes import CYLINDER, PRISM, SPHERE, ShapeArrays


@dataclass(frozen=True)
class Detour:
    """A leg flown round a gap: planned at vehicle time t_s s, to the mission's waypoint of index `waypoint`
    (0-based), through the via points `via` (V, 3) ENU m."""

    t_s: float
    waypoint: int
    via: np.ndarray

    def as_json(self) -> dict[str, object]:
        """flight.json's row: t_s, waypoint (0-based), via [[x, y, z], ...] m, to the centimetre."""
        return {"t_s": round(self.t_s, 3), "waypoint": self.waypoint, "via": np.round(self.via, 2).tolist()}


CIRCLE_SEGMENTS = 16  # segments of a quarter circle in a footprint polygon
INSIDE_TOLERANCE_M = 1e-6  # m: a line along a hull's edge does not cross it


def footprints(obstacles: ShapeArrays, z: float, grow: float) -> list[shapely.Polygon]:
    """The horizontal cross-sections at height z m of the obstacles that reach it, each grown by `grow` m:
    a sphere's circle of radius sqrt(r^2 - (z - cz)^2), a cylinder's circle, a prism's footprint (cylinders
    and prisms between their bottom and top)."""
    out = []
    kinds, params, vertices = obstacles
    for kind, row in zip(kinds, params, strict=True):
        if kind == SPHERE:
            half = row[3] ** 2 - (z - row[2]) ** 2
            if half > 0.0:
                out.append(
                    shapely.Point(row[0], row[1]).buffer(np.sqrt(half) + grow, quad_segs=CIRCLE_SEGMENTS)
                )
        elif row[4] <= z <= row[5]:
            if kind == CYLINDER:
                out.append(shapely.Point(row[0], row[1]).buffer(row[2] + grow, quad_segs=CIRCLE_SEGMENTS))
            elif kind == PRISM:
                first, count = int(row[0]), int(row[1])
                ring = shapely.Polygon(vertices[first : first + count])
                out.append(ring.buffer(grow, quad_segs=CIRCLE_SEGMENTS))
    return out


def blocking_hulls(grown: list[shapely.Polygon], corner_tolerance: float) -> list[shapely.Polygon]:
    """The convex hulls, corners thinned (module docstring), of the clusters of two or more of the grown
    footprints that overlap one another; hulls that overlap merge, so the hulls returned are disjoint."""
    if len(grown) < 2:
        return []
    union = shapely.union_all(grown)
    parts = list(getattr(union, "geoms", [union]))
    hulls = [part.convex_hull for part in parts if sum(part.contains(g.centroid) for g in grown) >= 2]
    merged = True
    while merged and len(hulls) > 1:  # hulls of separate clusters can still overlap: merge them
        merged = False
        for i in range(len(hulls)):
            for j in range(i + 1, len(hulls)):
                if hulls[i].intersects(hulls[j]):
                    hulls[i] = shapely.union(hulls[i], hulls.pop(j)).convex_hull
                    merged = True
                    break
            if merged:
                break
    return [hull.buffer(corner_tolerance, join_style="mitre").simplify(corner_tolerance) for hull in hulls]


def _crosses(a: np.ndarray, b: np.ndarray, interiors: list[shapely.Polygon]) -> bool:
    line = shapely.LineString([a, b])
    return any(line.intersects(inner) for inner in interiors)


def route_round(a: np.ndarray, b: np.ndarray, hulls: list[shapely.Polygon]) -> np.ndarray | None:
    """The via points (V, 2) of the shortest way from a to b (2,) round the hulls (their corners), or None
    when the straight line crosses none of them, or when a or b lies inside one (nothing to plan)."""
    interiors = [hull.buffer(-INSIDE_TOLERANCE_M) for hull in hulls]
    if not _crosses(a, b, interiors):
        return None
    if any(hull.contains(shapely.Point(*a)) or hull.contains(shapely.Point(*b)) for hull in hulls):
        return None
    corners = [np.asarray(hull.exterior.coords)[:-1] for hull in hulls]
    nodes = np.vstack([a[None, :], b[None, :], *corners])
    n = len(nodes)
    lengths = np.full((n, n), np.inf)
    for i in range(n):
        for j in range(i + 1, n):
            if not _crosses(nodes[i], nodes[j], interiors):
                lengths[i, j] = lengths[j, i] = float(np.linalg.norm(nodes[i] - nodes[j]))
    graph = np.where(np.isfinite(lengths), lengths, 0.0)
    distance, previous = dijkstra(graph, directed=False, indices=0, return_predecessors=True)
    if not np.isfinite(distance[1]):
        return None
    path, k = [], int(previous[1])
    while k != 0:
        path.append(nodes[k])
        k = int(previous[k])
    return np.array(path[::-1]).reshape(-1, 2)


def detour(
    a: np.ndarray, b: np.ndarray, obstacles: ShapeArrays, clearance: float, half_width: float,
    corner_tolerance: float,
) -> np.ndarray | None:  # fmt: skip
    """The via points (V, 3) of the leg from a to b (3,) ENU m round the clusters of the still `obstacles`
    that close a gap narrower than 2 (clearance + half_width) m across it (module docstring), at b's height;
    None when the leg crosses no such cluster (or starts or ends inside one)."""
    grown = footprints(obstacles, float(b[2]), clearance + half_width)
    via = route_round(
        np.asarray(a, dtype=float)[:2],
        np.asarray(b, dtype=float)[:2],
        blocking_hulls(grown, corner_tolerance),
    )
    if via is None:
        return None
    return np.column_stack([via, np.full(len(via), float(b[2]))])
