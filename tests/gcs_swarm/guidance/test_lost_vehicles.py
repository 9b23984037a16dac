"""Prediction of a lost vehicle's path: coast on its last velocity until its GCS failsafe, then RTL straight
home at WPNAV_SPEED (or stay, for LAND)."""

from __future__ import annotations

import numpy as np
import pytest

from gcs_swarm.guidance.lost_vehicles import LostTrack, predicted_position


def track(action: str = "rtl") -> LostTrack:
    return LostTrack(
        t_last=10.0,
        pos=np.array([100.0, 0.0, 50.0]),
        vel=np.array([0.0, 10.0, 0.0]),
        home=np.array([0.0, 0.0, 0.0]),
        action=action,
        failsafe_s=5.0,
        speed=10.0,
        rtl_alt=15.0,
    )


def test_it_coasts_on_its_last_velocity_until_the_failsafe() -> None:
    np.testing.assert_allclose(predicted_position(track(), 10.0), [100, 0, 50])
    np.testing.assert_allclose(predicted_position(track(), 13.0), [100, 30, 50])
    np.testing.assert_allclose(predicted_position(track(), 15.0), [100, 50, 50])


def test_rtl_flies_straight_home_at_its_speed_and_stops_there() -> None:
    start, home = np.array([100.0, 50.0]), np.zeros(2)
    direction = (home - start) / np.linalg.norm(home - start)
    np.testing.assert_allclose(predicted_position(track(), 17.0)[:2], start + 20.0 * direction)
    assert predicted_position(track(), 17.0)[2] == 50.0  # above RTL_ALT: keeps its altitude
    np.testing.assert_allclose(predicted_position(track(), 1000.0), [0, 0, 50])


def test_land_and_off_do_not_go_home() -> None:
    np.testing.assert_allclose(predicted_position(track("land"), 100.0), [100, 50, 50])
    np.testing.assert_allclose(predicted_position(track("off"), 20.0), [100, 100, 50])


def test_bad_tracks_are_refused() -> None:
    with pytest.raises(ValueError):
        LostTrack(0.0, np.zeros(3), np.zeros(3), np.zeros(3), "smart_rtl", 5.0, 10.0, 15.0)
    with pytest.raises(ValueError):
        LostTrack(0.0, np.zeros(3), np.zeros(3), np.zeros(3), "rtl", 5.0, 0.0, 15.0)
