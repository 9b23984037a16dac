"""BRAKE stops as ArduCopter's does: a shaped, jerk-limited stop (sitl_sim.vehicle_model.position_control
.brake_shaping_step), not a hard stop. Reference: a real ArduCopter V4.7.0-dev SITL quad flown in GUIDED at
10.14 m/s and switched to BRAKE stopped 20.4 m further on, speed 7.93 m/s after 1.0 s, 4.27 m/s after 2.0 s,
2.05 m/s after 3.0 s (docs/reliability.md, "How a vehicle stops"). The earlier model of this simulator
stopped from 10 m/s in about 5 m: four times kinder than the real vehicle."""

from __future__ import annotations

import numpy as np
import pytest

from sitl_sim.autopilot import modes
from sitl_sim.simulator import Simulator
from tests.sitl_sim.sim_process import M, in_process_config

REAL_STOP_M = 20.4  # m, real ArduCopter SITL from 10.14 m/s
REAL_SPEED_AFTER = {1.0: 7.93, 2.0: 4.27, 3.0: 2.05}  # s after BRAKE -> m/s, the same flight


def _cruise_then_brake(speed: float, mode: int = modes.BRAKE) -> tuple[float, dict[float, float], float]:
    """Fly east at `speed` in GUIDED, then switch to `mode` (BRAKE or LAND): (speed at the switch, speed after
    1/2/3 s, horizontal distance to the stop) from the simulator's state."""
    sim = Simulator(in_process_config([[0.0, 0.0, 20.0]]))
    a, state = sim.autopilot, sim.dyn.state
    tick = sim.timing.tick_s
    for _ in range(round(10.0 / tick)):
        a.set_position_target(0, None, np.array([speed, 0.0, 0.0]), None, None, None)
        sim._tick()
    start_speed, start_x = float(state.vel[0, 0]), float(state.pos[0, 0])
    assert a.set_mode(0, mode) == M.MAV_RESULT_ACCEPTED
    after: dict[float, float] = {}
    for k in range(1, round(12.0 / tick) + 1):
        sim._tick()
        if round(k * tick, 6) in REAL_SPEED_AFTER:
            after[round(k * tick, 6)] = float(np.hypot(*state.vel[0, :2]))
    assert a.mode[0] == mode and float(np.hypot(*state.vel[0, :2])) < 0.05
    return start_speed, after, float(state.pos[0, 0]) - start_x


def test_brake_from_cruise_stops_like_a_real_arducopter() -> None:
    start, after, distance = _cruise_then_brake(10.14)
    assert start == pytest.approx(10.14, abs=0.6)
    # per m/s of start speed, within 10 % of the real vehicle (and far from the ~5 m of a hard stop)
    assert distance / start == pytest.approx(REAL_STOP_M / 10.14, rel=0.10)
    for t, real in REAL_SPEED_AFTER.items():
        assert after[t] / start == pytest.approx(real / 10.14, abs=0.06), (t, after[t])


def test_brake_holds_where_it_stopped() -> None:
    sim = Simulator(in_process_config([[0.0, 0.0, 20.0]]))
    a, state = sim.autopilot, sim.dyn.state
    for _ in range(round(6.0 / sim.timing.tick_s)):
        a.set_position_target(0, None, np.array([0.0, 5.0, 0.0]), None, None, None)
        sim._tick()
    a.set_mode(0, modes.BRAKE)
    for _ in range(round(10.0 / sim.timing.tick_s)):
        sim._tick()
    stopped = state.pos[0].copy()
    for _ in range(round(5.0 / sim.timing.tick_s)):
        sim._tick()
    assert np.linalg.norm(state.pos[0] - stopped) < 0.1
    assert abs(state.pos[0, 2] - 20.0) < 0.5  # altitude held


def test_land_from_cruise_stops_like_a_real_arducopter() -> None:
    """LAND brakes with AC_Loiter's gentler limits (LOIT_BRK_ACCEL 2.5 m/s^2, LOIT_BRK_JERK 5 m/s^3) while it
    descends: the real ArduCopter SITL quad, GUIDED at 10.14 m/s then LAND, came to rest 23.7 m further on
    (8.34 m/s after 1 s, 6.07 after 2 s, 3.41 after 3 s)."""
    start, after, distance = _cruise_then_brake(10.14, modes.LAND)
    assert distance / start == pytest.approx(23.7 / 10.14, rel=0.10)
    for t, real in {1.0: 8.34, 2.0: 6.07, 3.0: 3.41}.items():
        assert after[t] / start == pytest.approx(real / 10.14, abs=0.08), (t, after[t])
