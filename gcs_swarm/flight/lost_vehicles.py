"""Vehicles lost in formation flight: where each has probably flown on its GCS failsafe since its last report
(gcs_swarm.guidance.lost_vehicles), as moving spheres the others avoid."""

from __future__ import annotations

import numpy as np

from gcs_swarm.guidance.fleet_controller import FleetController
from gcs_swarm.guidance.lost_vehicles import LostTrack, avoidance_radius, predicted_position
from gcs_swarm.guidance.params import TelemetryParams
from gcs_swarm.link.fleet import Fleet


class LostVehicleTracks:
    """One LostTrack per lost vehicle (by row), from its last report until it is heard again."""

    def __init__(self) -> None:
        self.tracks: dict[int, LostTrack] = {}

    def start(self, fleet: Fleet, i: int, home: np.ndarray, failsafe: np.ndarray, action: str) -> None:
        """Start predicting lost vehicle i from its last report; `home` (3,) ENU m where it took off (NaN:
        unknown, its last position stands in), `failsafe` (3,) its failsafe timeout s, Return speed m/s and
        Return altitude m (VehicleSetup.failsafe_params), `action` the mission's safety.gcs_failsafe."""
        st = fleet.state
        pos, vel = fleet.pos[i], fleet.vel[i]
        if st.position_ms[i] < 0 or not (np.isfinite(pos).all() and np.isfinite(vel).all()):
            return  # never reported a position: nothing to predict from
        timeout_s, speed, rtl_alt = failsafe
        self.tracks[i] = LostTrack(
            t_last=float(st.position_ms[i]) / 1000.0,
            pos=pos,
            vel=vel,
            home=home if np.isfinite(home).all() else pos,
            action=action,
            failsafe_s=float(timeout_s),
            speed=max(float(speed), 0.1),
            rtl_alt=max(float(rtl_alt), 0.0),
        )

    def place(
        self, t: float, alive: np.ndarray, controller: FleetController, params: TelemetryParams
    ) -> tuple[np.ndarray, np.ndarray]:
        """Where lost vehicles have probably flown at vehicle time t (s): (K, 3) ENU m and (K,) m, spheres the
        others avoid as moving obstacles (each also repels them from its centre, told to `controller`). A
        vehicle heard again ((N,) `alive`) is flown from its measured state and its track dropped."""
        for i in [i for i in self.tracks if alive[i]]:
            del self.tracks[i]
        centres, radii = np.zeros((0, 3)), np.zeros(0)
        for i, track in self.tracks.items():
            here = predicted_position(track, t)
            moving = (here - predicted_position(track, t - 0.1)) / 0.1
            controller.place_uncommanded(i, here, moving)
            radius = avoidance_radius(
                track, t, params.lost_radius, params.lost_radius_growth, params.lost_radius_max
            )
            centres, radii = np.vstack([centres, here]), np.append(radii, radius)
        return centres, radii
