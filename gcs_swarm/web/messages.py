"""The JSON the page reads over its WebSocket, one message each, built in one place for every source (a
recorded run folder now, a live flight later).

Server to page:
- `scene`: once per connection: the site (obstacles, prisms, cylinders, fence, goal, waypoints), the vehicle
  names in vehicle order, the events, the time span and whether the source can seek (`replay`).
- `frame`: one per update: t s, the flight phase, the formation's state (its last reshape), the leader's
  index, and per vehicle x, y, z (m ENU), yaw (rad, ENU: counter-clockwise from east), slot (the slot's
  point, m ENU x, y, or null), mode, lost, crashed; `obstacles`: centres (m ENU x, y) when any moves.
- `status`: playing, speed, t (replay only).
- `error`: text (a command the source refused).

Page to server (replay only): {"cmd": "play"}, {"cmd": "pause"}, {"cmd": "speed", "value": X},
{"cmd": "seek", "t": T}.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from gcs_swarm.mission import Mission
from gcs_swarm.mission.model import Zone

DECIMALS = 3  # positions to the millimetre, angles to the milliradian: what the page can show


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
