"""The PX4 persona's geofence (issue 37 item 5): a PX4 vehicle flying OFFBOARD into an uploaded exclusion zone
says "Geofence violation" (navigator geofence_breach_check) and acts as GF_ACTION says (failsafe.cpp
fromGfActParam): Hold at once, Return after COM_FAIL_ACT_T in Hold, nothing but the message for Warning; its
fence is not erased by ArduPilot's FENCE_TOTAL rule, and its OFFBOARD setpoints are not refused inside the
fence as ArduCopter's GUIDED destinations are."""

from __future__ import annotations

import numpy as np

from sitl_sim.autopilot import px4
from sitl_sim.autopilot.fence import CIRCLE_EXCLUSION, FenceItem
from sitl_sim.simulator import Simulator
from tests.sitl_sim.sim_process import in_process_config


def _px4_with_circle(centre_xy: tuple[float, float], radius: float, gf_action: int):
    """An in-process sitl-sim of one PX4 vehicle flying OFFBOARD at 10 m over (0, 0), an exclusion circle of
    `radius` m at `centre_xy` (ENU m) stored through the simulator as an upload stores it, GF_ACTION set; the
    texts it says are collected."""
    sim = Simulator(in_process_config([[0.0, 0.0, 10.0]], autopilots=("px4",)))
    lat, lon, _ = sim.geodesy.to_geodetic(np.array([[centre_xy[0], centre_xy[1], 0.0]]))[0]
    sim.store_fence(0, [FenceItem(CIRCLE_EXCLUSION, round(lat * 1e7), round(lon * 1e7), radius)])
    sim.params.set(0, "GF_ACTION", gf_action)
    texts: list[str] = []
    endpoint = sim.endpoints[0]

    def capture(wall_now: float, clock_ms: int | None = None) -> None:  # keep what the vehicle says
        texts.extend(text for _, text in sim.autopilot.texts[0])
        sim.autopilot.texts[0].clear()
        endpoint.outbox.packets.clear()

    endpoint.flush = capture  # type: ignore[method-assign]
    return sim, texts


def _fly_east(sim: Simulator, speed: float, seconds: float) -> None:
    """OFFBOARD velocity setpoints east at `speed` m/s every tick while the vehicle is in OFFBOARD (as the
    ground station streams them), for `seconds` simulated s."""
    persona = sim.autopilot.persona(0)
    assert isinstance(persona, px4.Px4)
    for _ in range(round(seconds / sim.timing.tick_s)):
        if persona.nav[0] == px4.MODE_OFFBOARD:
            persona.last_setpoint[0] = sim.autopilot.t
            sim.autopilot.set_position_target(0, None, np.array([speed, 0.0, 0.0]), None, None, None)
        sim._tick()


def test_hold_stops_the_vehicle_at_once_inside_the_zone() -> None:
    sim, texts = _px4_with_circle((40.0, 0.0), 10.0, gf_action=2)  # PX4's default: Hold mode
    try:
        _fly_east(sim, 4.0, 16.0)
        persona = sim.autopilot.persona(0)
        assert isinstance(persona, px4.Px4)
        assert persona.nav[0] == px4.MODE_LOITER and persona.failsafe[0]
        assert texts.count("Geofence violation") == 1 and "Failsafe activated" in texts
        # at 4 m/s the vehicle reaches the circle's edge (x = 30 m) 7.5 s in; AUTO.LOITER stops it within
        # about v^2 / (2 a) = 16 / 6 = 2.7 m (MPC_ACC_HOR 3 m/s^2) plus the braking's jerk ramp: short of
        # the centre (40 m)
        x = float(sim.dyn.state.pos[0, 0])
        assert 30.0 < x < 38.0
        assert np.hypot(*sim.dyn.state.vel[0, :2]) < 0.3
    finally:
        sim.close()


def test_return_waits_com_fail_act_t_in_hold_then_returns() -> None:
    sim, texts = _px4_with_circle((40.0, 0.0), 10.0, gf_action=3)
    try:
        _fly_east(sim, 4.0, 9.0)  # the edge is crossed at 7.5 s: in the 5 s Hold (COM_FAIL_ACT_T default)
        persona = sim.autopilot.persona(0)
        assert isinstance(persona, px4.Px4)
        assert persona.nav[0] == px4.MODE_LOITER
        assert "Failsafe activated: entering Hold for 5 seconds" in texts
        _fly_east(sim, 4.0, 5.0)
        assert persona.nav[0] == px4.MODE_RTL
    finally:
        sim.close()


def test_warning_only_says_so_and_flies_on() -> None:
    sim, texts = _px4_with_circle((30.0, 0.0), 5.0, gf_action=1)
    try:
        _fly_east(sim, 4.0, 10.0)
        persona = sim.autopilot.persona(0)
        assert isinstance(persona, px4.Px4)
        assert persona.nav[0] == px4.MODE_OFFBOARD and not persona.failsafe[0]
        assert texts.count("Geofence violation") == 1
        assert float(sim.dyn.state.pos[0, 0]) > 33.0  # through the circle (25..35 m) and beyond its centre
    finally:
        sim.close()


def test_no_fence_total_erase_and_setpoints_inside_the_fence_are_flown() -> None:
    sim, _ = _px4_with_circle((40.0, 0.0), 10.0, gf_action=0)
    try:
        sim.params.set(0, "FENCE_TOTAL", 0)  # the hidden ArduPilot column dropping to 0: no erase on PX4
        sim._tick()
        sim._tick()
        assert len(sim.autopilot.fence.items[0]) == 1
        # a position setpoint in the circle is taken (ArduCopter's GUIDED would refuse it)
        assert sim.autopilot.set_position_target(0, np.array([40.0, 0.0, 10.0]), None, None, None, None)
    finally:
        sim.close()
