"""What a mission run did, from the ground station's point of view (`FlightResult`, written to flight.json by
gcs_swarm.flight.fly; the metrics come from the evaluation)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from gcs_swarm.flight.phase import Phase


@dataclass
class FlightResult:
    """What the run did, from the ground station's point of view (metrics come from report.py)."""

    phase_reached: Phase = Phase.CONNECT
    command_mode: dict[str, object] | None = None  # the command mode chosen before take-off (CommandPlan)
    # each step down of the command mode in flight (link.command_mode.change_row), oldest first
    command_mode_changes: list[dict[str, object]] = field(default_factory=list)
    arrived: bool = False
    t_formation_start: float | None = None
    t_arrival: float | None = None
    t_formation_end: float | None = None
    lost: list[str] = field(default_factory=list)
    lost_at: dict[str, float] = field(default_factory=dict)  # vehicle time s at which each was declared lost
    events: list[str] = field(default_factory=list)
    # the formation's changes of shape (guidance.reshape.ShapeChange.as_json: t_s, change, shape, scale)
    reshapes: list[dict[str, float | str]] = field(default_factory=list)
    # each leg of the route as the leader started it (runner._start_leg: index, name, t_s, shape, spacing_m,
    # speed_m_s, first_waypoint)
    legs: list[dict[str, float | int | str]] = field(default_factory=list)
    # legs the leader flew round a gap (guidance.route_plan.Detour.as_json: t_s, waypoint, via)
    detours: list[dict[str, object]] = field(default_factory=list)
    ticks: int = 0
    final_targets: np.ndarray | None = None  # (N, 3) where each vehicle should end, from the last tick
    leader: int | None = None  # the leading vehicle at the end (the lead passes on when a leader is lost)
    offsets: np.ndarray | None = None  # (N, 3) slot offsets in force at the end
    degraded_s: float = 0.0  # vehicle s flown in degraded mode (stale telemetry: slower, wider)
    holds: int = 0  # times a vehicle was held for stale telemetry
    max_telemetry_age_s: float = 0.0  # oldest position telemetry of a live vehicle at any formation tick
    params_changed: list[dict[str, object]] = field(default_factory=list)  # flight_params.ParamChange rows
    # (vehicle time s, leader, (N, 3) slot offsets flown, NaN rows for lost vehicles, whether the column's
    # slots follow the leader's path, guidance.column_path) at each change
    formation_timeline: list[tuple[float, int, np.ndarray, bool]] = field(default_factory=list)
    # vehicles found flying at the start (`--airborne`): None (none were), "finish" or "land"; and for
    # "land", whether every vehicle was disarmed on the ground at the end
    reattached: str | None = None
    landed_all: bool = False
    # operator takeover (gcs_swarm.flight.takeover): each vehicle that left the mode we commanded
    # (Takeover.as_json: t_s, vehicle, mode, by), and those still taken over, left to their operator
    taken_over: list[dict[str, object]] = field(default_factory=list)
    left_to_operator: list[str] = field(default_factory=list)
    # vehicle name -> the autopilot the ground station speaks to ("ArduCopter", "PX4"), bound at connect
    autopilots: dict[str, str] = field(default_factory=dict)
