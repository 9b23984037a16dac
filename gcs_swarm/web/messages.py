"""The JSON the page reads over its WebSocket, one message each, built in one place for every source (a
recorded run folder now, a live flight later).

Server to page:
- `scene`: once per connection: the site (obstacles, prisms, cylinders, fence, goal, waypoints), the vehicle
  names in vehicle order, the events, the time span and whether the source can seek (`replay`).
- `frame`: one per update: t s, the flight phase, the formation's state (its last reshape), the leader's
  index, and per vehicle x, y, z (m ENU), yaw (rad, ENU: counter-clockwise from east), slot (the slot's
  point, m ENU x, y, or null), mode, lost, crashed; `obstacles`: centres (m ENU x, y) when any moves.
  A live frame (live_frame_message) adds: stamp (s since 1970, wall clock, when the flight thread copied
  the state: the page's latency is its receipt time minus this), per vehicle taken (over by someone else),
  up and down (MAVLink bytes/s each way over the latest second, null before one), the link budget (bytes/s
  up and down together, or null), progress (leader_to_goal_m, formation_rms_m, formation_s: s since
  formation flight began) and the flight's events from index first_event on (each {t, kind, text}).
- `status`: playing, speed, t (replay only).
- `error`: text (a command the source refused).
- `action`: line, ok, text: the outcome of an operator action from the page (live, docs/replay.md).

Page to server: replay: {"cmd": "play"}, {"cmd": "pause"}, {"cmd": "speed", "value": X},
{"cmd": "seek", "t": T}; live: {"cmd": "action", "line": "land left", "token": TOKEN}.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from gcs_swarm.mission import Mission
from gcs_swarm.mission.model import Zone

DECIMALS = 3  # positions to the millimetre, angles to the milliradian: what the page can show
MARGIN_M = 10.0  # m around everything the first view shows


def _xy(points: Any) -> list[list[float]]:
    """(K, >=2) m -> [[x, y], ...] rounded."""
    return [[round(float(p[0]), DECIMALS), round(float(p[1]), DECIMALS)] for p in np.asarray(points)]


def _number(value: float) -> float | None:
    """A float rounded for the page; None for NaN (JSON has no NaN)."""
    return None if not np.isfinite(value) else round(float(value), DECIMALS)


def _zone(zone: Zone) -> dict[str, Any]:
    """An exclusion zone: its polygon, or its circle's centre and radius (m ENU)."""
    if zone.polygon is not None:
        return {"name": zone.name, "polygon": _xy(zone.polygon)}
    centre = np.asarray(zone.center, dtype=float)
    return {"name": zone.name, "x": float(centre[0]), "y": float(centre[1]), "r": zone.radius}


def scene_message(
    mission: Mission,
    events: list[dict[str, Any]],
    t_span: tuple[float, float] | None,
    bounds: tuple[float, float, float, float],
) -> dict[str, Any]:
    """The site the page draws once. `events`: {t (s or None), kind, text} in time order; `t_span`: the
    first and last frame's t s when known (a replay; None: live); `bounds`: (x_min, y_min, x_max, y_max) m
    ENU the first view shows."""
    fence = mission.fence
    return {
        "type": "scene",
        "mission": mission.name,
        "vehicles": [v.name for v in mission.vehicles],
        "obstacles": [
            {
                "x": round(float(o.center[0]), DECIMALS),
                "y": round(float(o.center[1]), DECIMALS),
                "r": o.radius,
            }
            for o in mission.obstacles
        ],
        "prisms": [{"name": p.name, "footprint": _xy(p.footprint)} for p in mission.prisms],
        "cylinders": [
            {"name": c.name, "x": float(c.center[0]), "y": float(c.center[1]), "r": c.radius}
            for c in mission.cylinders
        ],
        "fence": {
            "polygon": None if fence.polygon is None else _xy(fence.polygon),
            "exclusions": [_zone(z) for z in fence.exclusions],
            "radius": mission.safety.geofence_radius,
        },
        "goal": _xy([mission.goal])[0],
        "waypoints": _xy(mission.waypoints),
        "events": events,
        "replay": t_span is not None,
        "t0": None if t_span is None else round(t_span[0], DECIMALS),
        "t1": None if t_span is None else round(t_span[1], DECIMALS),
        "bounds": [round(float(b), DECIMALS) for b in bounds],
    }


def frame_message(
    t: float,
    pos: np.ndarray,
    yaw: np.ndarray,
    slots: np.ndarray,
    modes: list[str | None],
    lost: np.ndarray,
    crashed: np.ndarray,
    leader: int,
    phase: str | None,
    formation: str | None,
    obstacles: np.ndarray | None,
) -> dict[str, Any]:
    """One update of the page. pos (N, 3) m ENU; yaw (N,) rad ENU; slots (N, 2) m ENU, NaN rows where a
    vehicle has no slot; modes: a name or None per vehicle; lost, crashed (N,) bool; leader: vehicle index;
    obstacles (K, 2) m ENU or None (none moves)."""
    vehicles = [
        {
            "x": _number(pos[i, 0]),
            "y": _number(pos[i, 1]),
            "z": _number(pos[i, 2]),
            "yaw": _number(yaw[i]),
            "slot": None if np.isnan(slots[i]).any() else _xy(slots[i : i + 1])[0],
            "mode": modes[i],
            "lost": bool(lost[i]),
            "crashed": bool(crashed[i]),
        }
        for i in range(len(pos))
    ]
    message: dict[str, Any] = {
        "type": "frame",
        "t": round(float(t), DECIMALS),
        "phase": phase,
        "formation": formation,
        "leader": int(leader),
        "vehicles": vehicles,
    }
    if obstacles is not None:
        message["obstacles"] = _xy(obstacles)
    return message


def view_bounds(mission: Mission, tracks: np.ndarray) -> tuple[float, float, float, float]:
    """(x_min, y_min, x_max, y_max) m ENU the first view shows: the vehicles' points `tracks` (K, 2) m ENU
    (NaN rows skipped), the goal, the waypoints, the obstacles, prisms, cylinders and fence, and MARGIN_M."""
    m = mission
    xy = [np.asarray(tracks, dtype=float), np.array([m.goal[:2]]), np.array([w[:2] for w in m.waypoints])]
    xy += [np.array([o.center[:2] - o.radius, o.center[:2] + o.radius]) for o in m.obstacles]
    xy += [p.footprint for p in m.prisms]
    xy += [np.array([c.center - c.radius, c.center + c.radius]) for c in m.cylinders]
    if m.fence.polygon is not None:
        xy.append(m.fence.polygon)
    points = np.concatenate([np.asarray(p, dtype=float).reshape(-1, 2) for p in xy])
    points = points[np.isfinite(points).all(axis=1)]
    low, high = points.min(axis=0) - MARGIN_M, points.max(axis=0) + MARGIN_M
    return float(low[0]), float(low[1]), float(high[0]), float(high[1])


def live_frame_message(
    frame: dict[str, Any],
    stamp: float,
    taken: np.ndarray,
    link: np.ndarray,
    budget: float | None,
    progress: dict[str, float | None],
    events: list[dict[str, Any]],
    first_event: int,
) -> dict[str, Any]:
    """A `frame` (frame_message) with what only a live flight has: stamp s since 1970 (wall clock); taken
    (N,) bool; link (N, 2) bytes/s up, down (NaN: not measured yet); budget bytes/s or None; progress: named
    figures (m, s; None when not known); events: the flight's events from index first_event on."""
    for i, vehicle in enumerate(frame["vehicles"]):
        vehicle["taken"] = bool(taken[i])
        vehicle["up"] = _number(link[i, 0])
        vehicle["down"] = _number(link[i, 1])
    frame.update(
        stamp=stamp,
        budget=budget,
        progress={k: None if v is None else _number(v) for k, v in progress.items()},
        events=events,
        first_event=first_event,
    )
    return frame
