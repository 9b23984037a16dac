"""RTL with rally points in the simulator (sitl_sim.autopilot.rally, issue 37 item 5): ArduCopter returns to
the nearest rally point unless it lies beyond RALLY_LIMIT_KM or home is nearer with RALLY_INCL_HOME
(AP_Rally::calc_best_rally_or_home_location); PX4 takes the closest of home and the safe points more than 10 m
from home, 2 m nearer than the best so far, home last with RTL_TYPE 1 (rtl.cpp findRtlDestination). Worked by
hand on a plan: home (0, 0), rally A (80, 30), B (-50, 0), C (5, 0); a full RTL lands at the chosen point."""

from __future__ import annotations

import numpy as np
import pytest

from sitl_sim.autopilot import modes
from sitl_sim.autopilot import px4 as px4_persona
from sitl_sim.autopilot.rally import RallyItem, RallyPoints
from sitl_sim.simulator import Simulator
from tests.sitl_sim.sim_process import in_process_config

HOME = np.array([0.0, 0.0, 0.0])
A, B, C = (80.0, 30.0), (-50.0, 0.0), (5.0, 0.0)


def _points(*xy: tuple[float, float]) -> RallyPoints:
    rally = RallyPoints(1)
    rally.store(0, [RallyItem(0, 0, 0.0) for _ in xy], np.array([[x, y, 0.0] for x, y in xy]))
    return rally


@pytest.mark.parametrize(
    ("at", "limit_km", "include_home", "expected"),
    [
        # from (60, 0): A is sqrt(20^2 + 30^2) = 36.1 m away, B 110 m, home 60 m
        ((60.0, 0.0), 0.3, True, A),
        ((60.0, 0.0), 0.0, True, A),  # RALLY_LIMIT_KM 0: no limit
        ((60.0, 0.0), 0.03, True, (0.0, 0.0)),  # the nearest (36.1 m) lies beyond 30 m: home
        # from (10, 0): home 10 m, B 60 m, A 76.2 m: home when it counts, else B
        ((10.0, 0.0), 0.3, True, (0.0, 0.0)),
        ((10.0, 0.0), 0.3, False, B),
    ],
)
def test_arducopter_returns_to_the_nearest_rally_point(at, limit_km, include_home, expected) -> None:
    rally = _points(A, B)
    pos = np.array([at[0], at[1], 10.0])
    got = rally.arducopter_destination(0, pos, HOME, limit_km, include_home)
    assert got[:2] == pytest.approx(expected)


@pytest.mark.parametrize(
    ("at", "rtl_type", "expected"),
    [
        ((60.0, 0.0), 0, A),  # A (36.1 m) + 2 < home (60 m)
        # home (10 m) nearest; C (5 m from here) is within 10 m of home: not a destination
        ((10.0, 0.0), 0, (0.0, 0.0)),
        ((10.0, 0.0), 1, B),  # RTL_TYPE 1: home last; B 60 m < A 76.2 m; C ignored
        ((4.0, 0.0), 1, B),
    ],
)
def test_px4_returns_to_the_closest_safe_point(at, rtl_type, expected) -> None:
    rally = _points(A, B, C)
    got = rally.px4_destination(0, np.array([at[0], at[1], 10.0]), HOME, rtl_type)
    assert got[:2] == pytest.approx(expected)


def test_no_rally_points_is_home() -> None:
    rally = RallyPoints(1)
    at = np.array([60.0, 0.0, 10.0])
    assert rally.arducopter_destination(0, at, HOME, 0.3, False)[:2] == pytest.approx((0.0, 0.0))
    assert rally.px4_destination(0, at, HOME, 1)[:2] == pytest.approx((0.0, 0.0))


def _land_in_rtl(autopilot: str) -> tuple[Simulator, np.ndarray]:
    """A vehicle of `autopilot` airborne 10 m over its home (an airborne start's home is below it) with rally
    points A and B about home, set to prefer them (RALLY_INCL_HOME 0, RTL_TYPE 1, as the ground station sets
    them), sent to RTL and flown until it has landed and disarmed (at most 120 simulated s); the simulator
    and where it stopped, ENU m about home."""
    sim = Simulator(in_process_config([[0.0, 0.0, 10.0]], autopilots=(autopilot,)))
    home = sim.autopilot.home[0]
    xy = np.array([A, B]) + home[:2]
    sim.autopilot.store_rally(0, [RallyItem(0, 0, 0.0), RallyItem(0, 0, 0.0)], xy)
    sim.params.set(0, "RTL_TYPE" if autopilot == "px4" else "RALLY_INCL_HOME", 1 if autopilot == "px4" else 0)
    if autopilot == "px4":
        persona = sim.autopilot.persona(0)
        assert isinstance(persona, px4_persona.Px4)
        assert persona.change_mode(0, px4_persona.MODE_RTL) == 0
    else:
        assert sim.autopilot.set_mode(0, modes.RTL) == 0
    for _ in range(round(120.0 / sim.timing.tick_s)):
        sim._tick()
        if not sim.autopilot.armed[0]:
            break
    return sim, sim.dyn.state.pos[0] - home


@pytest.mark.parametrize("autopilot", ["ardupilot", "px4"])
def test_rtl_lands_at_the_rally_point(autopilot: str) -> None:
    # over home, B (50 m) is nearer than A (85.4 m): both fly there; the RTL descends once within 1 m of it
    sim, stop = _land_in_rtl(autopilot)
    try:
        assert not sim.autopilot.armed[0]
        assert np.hypot(stop[0] - B[0], stop[1] - B[1]) < 1.5
        assert stop[2] < 0.5
    finally:
        sim.close()
