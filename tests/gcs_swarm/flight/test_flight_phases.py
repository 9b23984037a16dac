"""Pieces of the mission run that need no link: the airborne choice (gcs_swarm.flight.reattach), the
operator's position hold (gcs_swarm.flight.landing) and the formation error
(gcs_swarm.flight.formation_tick)."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from gcs_swarm.flight.formation_tick import formation_rms
from gcs_swarm.flight.landing import HOLD_LATCH_SPEED, PositionHold
from gcs_swarm.flight.preflight import PreflightError
from gcs_swarm.flight.reattach import check_airborne_choice

NAMES = ["uav1", "uav2", "uav3"]


def test_airborne_choice() -> None:
    fleet = SimpleNamespace(names=NAMES)
    every, some = np.ones(3, dtype=bool), np.array([True, False, True])
    check_airborne_choice(fleet, every, "finish", "found")  # type: ignore[arg-type]
    check_airborne_choice(fleet, some, "land", "found")  # type: ignore[arg-type]  # landing: any subset
    with pytest.raises(PreflightError, match=r"some are on the ground \(uav2\)"):
        check_airborne_choice(fleet, some, "finish", "found")  # type: ignore[arg-type]
    with pytest.raises(PreflightError, match="vehicles already flying: found. Say --airborne finish"):
        check_airborne_choice(fleet, every, None, "found")  # type: ignore[arg-type]


class SentTargets:
    """Stands in for a vehicle's setpoints: keeps the position targets sent to it."""

    def __init__(self) -> None:
        self.sent: list[tuple[np.ndarray, float | None]] = []

    def send_position_target(self, pos: np.ndarray, yaw: float | None = None) -> None:
        self.sent.append((np.array(pos), yaw))


def test_hold_brakes_on_the_spot_then_holds_the_point_where_it_slowed() -> None:
    """A vehicle faster than HOLD_LATCH_SPEED is sent where it is each tick; once slower, that point is
    latched and sent from then on, wherever the vehicle drifts; a lost vehicle gets nothing."""
    targets = [SentTargets() for _ in NAMES]
    fleet = SimpleNamespace(
        pos=np.array([[0.0, 0.0, 10.0], [5.0, 0.0, 10.0], [9.0, 0.0, 10.0]]),
        vel=np.array([[2.0, 0.0, 0.0], [0.1, 0.0, 0.0], [0.0, 0.0, 0.0]]),
        att=np.array([[0.0, 0.0, 0.5], [0.0, 0.0, np.nan], [0.0, 0.0, 0.0]]),
        alive=np.array([True, True, False]),
        vehicle=lambda i: SimpleNamespace(setpoints=targets[i]),
    )
    assert np.linalg.norm(fleet.vel[1]) < HOLD_LATCH_SPEED < np.linalg.norm(fleet.vel[0])
    hold = PositionHold(3)
    hold.tick(fleet, fleet.alive)  # type: ignore[arg-type]
    fleet.pos = fleet.pos + [1.0, 0.0, 0.0]  # both move on by 1 m; vehicle 0 still fast
    hold.tick(fleet, fleet.alive)  # type: ignore[arg-type]
    np.testing.assert_array_equal([p for p, _ in targets[0].sent], [[0.0, 0.0, 10.0], [1.0, 0.0, 10.0]])
    assert [yaw for _, yaw in targets[0].sent] == [0.5, 0.5]
    np.testing.assert_array_equal([p for p, _ in targets[1].sent], [[5.0, 0.0, 10.0], [5.0, 0.0, 10.0]])
    assert [yaw for _, yaw in targets[1].sent] == [None, None]  # no finite yaw: the autopilot keeps its own
    assert targets[2].sent == []
    hold.clear()
    assert np.isnan(hold.points).all()


def test_formation_rms_is_over_active_followers_only() -> None:
    """Errors 9 (leader), 3 and 4 (followers), 100 (inactive): sqrt((9 + 16) / 2)."""
    errors = np.array([9.0, 3.0, 4.0, 100.0])
    active = np.array([True, True, True, False])
    assert formation_rms(errors, active, leader=0) == pytest.approx(math.sqrt(12.5))
    assert formation_rms(errors, np.array([True, False, False, False]), leader=0) == 0.0
