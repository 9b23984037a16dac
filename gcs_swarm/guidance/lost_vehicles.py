"""Where a lost vehicle probably is: the ground station keeps avoiding it after its link died [add]
(docs/reliability.md).

A vehicle that stops hearing its ground station flies on its last target until its GCS failsafe fires
FS_GCS_TIMEOUT seconds later; then ArduCopter's RTL climbs to RTL_ALT above home (if lower) and flies straight
home at WPNAV_SPEED, LAND descends where it is and BRAKE stops and holds (its few metres of braking are
inside the avoidance radius). The prediction: constant velocity from the last report
until the failsafe, then that manoeuvre. The others avoid the predicted point as a moving spherical obstacle
whose radius grows with the time since the last report (TelemetryParams.lost_radius*: the prediction's error
grows), so a lost vehicle returning home through the formation is avoided rather than met.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

FAILSAFE_ACTIONS = ("brake", "land", "rtl", "off")


@dataclass(frozen=True)
class LostTrack:
    """The last report of a lost vehicle and what it will do (ENU m, m/s, s of vehicle time).

    pos, vel (3,) at t_last; home (3,) where it took off; action: the mission's safety.gcs_failsafe;
    failsafe_s: FS_GCS_TIMEOUT; speed: WPNAV_SPEED in m/s; rtl_alt: RTL_ALT in m above home."""

    t_last: float
    pos: np.ndarray
    vel: np.ndarray
    home: np.ndarray
    action: str
    failsafe_s: float
    speed: float
    rtl_alt: float

    def __post_init__(self) -> None:
        if self.action not in FAILSAFE_ACTIONS:
            raise ValueError(f"failsafe action must be one of {FAILSAFE_ACTIONS}, not {self.action!r}")
        if not (self.failsafe_s >= 0 and self.speed > 0 and self.rtl_alt >= 0):
            raise ValueError("need failsafe_s >= 0, speed > 0 and rtl_alt >= 0")


def predicted_position(track: LostTrack, t: float) -> np.ndarray:
    """(3,) ENU m: where the lost vehicle probably is at vehicle time t (s). The RTL climb is taken as
    immediate (formations fly above RTL_ALT; below it the point is at most the climb height off)."""
    elapsed = max(0.0, t - track.t_last)
    coast = elapsed if track.action == "off" else min(elapsed, track.failsafe_s)
    start = np.asarray(track.pos, dtype=float) + np.asarray(track.vel, dtype=float) * coast
    returning = elapsed - track.failsafe_s
    if track.action != "rtl" or returning <= 0:
        return start  # LAND descends below where it stopped, BRAKE holds there: that point stays repelled
    home = np.asarray(track.home, dtype=float)
    flat = home[:2] - start[:2]
    dist = float(np.hypot(*flat))
    step = flat * min(1.0, returning * track.speed / dist) if dist > 0 else np.zeros(2)
    return np.array([start[0] + step[0], start[1] + step[1], max(start[2], home[2] + track.rtl_alt)])


def avoidance_radius(track: LostTrack, t: float, radius: float, growth: float, radius_max: float) -> float:
    """m: radius of the sphere avoided around the predicted position at vehicle time t (s)."""
    return min(radius_max, radius + growth * max(0.0, t - track.t_last))
