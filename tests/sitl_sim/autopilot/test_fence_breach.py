"""Geofences of the simulator (sitl_sim.autopilot.fence, the autopilot's fence check): geometry with
hand-worked answers, AC_Fence::check's bookkeeping, what Copter does on a breach (BRAKE, the STATUSTEXTs,
FENCE_STATUS, the manual recovery window), the pre-arm refusals, and one breach over MAVLink against a running
sitl-sim."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sitl_sim.autopilot import fence as f
from sitl_sim.autopilot import modes
from sitl_sim.autopilot.fence import FenceItem, Fences
from sitl_sim.simulator import Simulator
from tests.sitl_sim.sim_process import M, Pilot, in_process_config

CIRCLE_EXCL, CIRCLE_INCL = f.CIRCLE_EXCLUSION, f.CIRCLE_INCLUSION
POLY_EXCL = f.POLYGON_EXCLUSION


# --- geometry ----------------------------------------------------------------------------------------------


def test_fence_names_read_as_arducopter_prints_them():
    assert f.fence_names(f.POLYGON) == "Polygon fence"
    assert f.fence_names(f.ALT_MAX | f.POLYGON) == "Max Alt and Polygon fences"
    assert f.fence_names(f.ALT_MAX | f.CIRCLE | f.POLYGON) == "Max Alt, Circle and Polygon fences"
    assert f.fence_names(0) == ""


def test_point_in_polygon_and_edge_distance_of_a_square():
    square = np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0]])
    points = np.array([[5.0, 5.0], [15.0, 5.0], [-1.0, 5.0], [13.0, 14.0]])
    assert f.point_in_polygon(points, square).tolist() == [True, False, False, False]
    # centre: 5 m from every edge; (15, 5): 5 m east of the east edge; (13, 14): 3-4-5 from corner (10, 10)
    assert f.distance_to_polygon(points, square) == pytest.approx([5.0, 5.0, 1.0, 5.0])


def _fences(n: int, zones: dict[int, list[tuple[FenceItem, tuple[float, float]]]]) -> Fences:
    fences = Fences(n)
    for i, entries in zones.items():
        fences.store(i, [item for item, _ in entries], np.array([xy for _, xy in entries]))
    return fences


def test_exclusion_circle_is_breached_strictly_inside_with_its_depth():
    fences = _fences(4, {i: [(FenceItem(CIRCLE_EXCL, 0, 0, 10.0), (0.0, 0.0))] for i in range(4)})
    xy = np.array([[6.0, 8.0], [6.0, 7.9], [3.0, 4.0], [0.0, 20.0]])
    breached, depth = fences.zones_breached(xy)
    # (6, 8) is exactly on the circle (10 m): not inside; (3, 4) is 5 m from the centre: 5 m deep
    assert breached.tolist() == [False, True, True, False]
    assert depth[1] == pytest.approx(10.0 - math.hypot(6.0, 7.9))
    assert depth[2] == pytest.approx(5.0)
    assert depth[3] == pytest.approx(-10.0)  # 10 m outside the only circle


def test_each_vehicle_only_meets_its_own_zones():
    fences = _fences(2, {0: [(FenceItem(CIRCLE_EXCL, 0, 0, 10.0), (0.0, 0.0))]})
    breached, _ = fences.zones_breached(np.zeros((2, 2)))
    assert breached.tolist() == [True, False]


def test_overlapping_circles_report_the_first_one_stored():
    a = (FenceItem(CIRCLE_EXCL, 0, 0, 10.0), (0.0, 0.0))
    b = (FenceItem(CIRCLE_EXCL, 1, 1, 10.0), (5.0, 0.0))
    fences = _fences(1, {0: [a, b]})
    breached, depth = fences.zones_breached(np.array([[1.0, 0.0]]))
    assert breached[0] and depth[0] == pytest.approx(9.0)  # 9 m inside the first, 6 m inside the second


def test_inclusion_circle_breached_outside_and_exclusion_polygon_inside():
    square = [(0.0, 0.0), (10.0, 0.0), (10.0, 10.0), (0.0, 10.0)]
    poly = [(FenceItem(POLY_EXCL, k, k, 4.0), xy) for k, xy in enumerate(square)]
    fences = _fences(
        3,
        {
            0: [(FenceItem(CIRCLE_INCL, 0, 0, 10.0), (0.0, 0.0))],
            1: [(FenceItem(CIRCLE_INCL, 0, 0, 10.0), (0.0, 0.0))],
            2: poly,
        },
    )
    breached, distance = fences.zones_breached(np.array([[20.0, 0.0], [0.0, 0.0], [4.0, 5.0]]))
    assert breached.tolist() == [True, False, True]
    assert distance[0] == pytest.approx(10.0)  # 10 m outside the inclusion circle
    assert distance[2] == pytest.approx(4.0)  # 4 m inside the square (nearest edge x = 0)


def test_validation_gives_arducopters_reasons():
    circle = FenceItem(CIRCLE_EXCL, 0, 0, 5.0)
    assert f.validate([circle]) is None
    assert f.validate([FenceItem(CIRCLE_EXCL, 0, 0, 0.0)]) == "Non-positive circle radius"
    assert f.validate([FenceItem(POLY_EXCL, 0, 0, 2.0)] * 2) == "Invalid vertex count (2)"
    assert f.validate([FenceItem(POLY_EXCL, 0, 0, 3.0)] * 2) == "Incorrect item count"
    assert f.validate([FenceItem(POLY_EXCL, 0, 0, 3.0), circle]).startswith("Received incorrect type")
    assert f.validate([FenceItem(CIRCLE_EXCL, 910_000_000, 0, 5.0)]) == "Bad lat or lon"
    # storage: 4-byte header + 13 per circle + end marker <= 560 bytes: 42 circles fit, 43 do not
    assert f.validate([circle] * 42) is None
    assert f.validate([circle] * 43) == "Fence exceeds storage size"


def test_check_records_new_breaches_backup_fences_and_the_recovery_window():
    fences = Fences(1)
    home = np.zeros((1, 3))
    one = np.ones(1)
    fences.update_enable(one, np.array([f.ALT_MAX]))

    def check(t: float, z: float) -> int:
        pos = np.array([[0.0, 0.0, z]])
        return int(fences.check(t, pos, home, one > 0, one, np.array([100.0]), np.array([300.0]))[0])

    assert check(0.0, 50.0) == 0
    assert check(0.04, 101.0) == f.ALT_MAX  # over FENCE_ALT_MAX: new; a backup fence 20 m above
    assert check(0.08, 110.0) == 0  # still breached: not new
    assert check(0.12, 121.5) == f.ALT_MAX  # past the backup (101 + 20 m): new again
    assert fences.breach_count[0] == 2
    assert fences.manual_recovery_start(0, 0.12)
    assert check(0.16, 142.0) == 0  # past the next backup, but inside the 10 s recovery window
    assert check(10.2, 142.0) == 0  # the window is over; 142 m was already the backup's breach
    assert check(10.24, 50.0) == 0 and fences.breaches[0] == 0


# --- the autopilot ---------------------------------------------------------------------------------------


def _sim_with_circle(start: list[float], centre_xy: tuple[float, float], radius: float, action: int = 4):
    sim = Simulator(in_process_config([start]))
    lat, lon, _ = sim.geodesy.to_geodetic(np.array([[centre_xy[0], centre_xy[1], 0.0]]))[0]
    sim.store_fence(0, [FenceItem(CIRCLE_EXCL, round(lat * 1e7), round(lon * 1e7), radius)])
    for name, value in (("FENCE_TYPE", 4), ("FENCE_ACTION", action), ("FENCE_ENABLE", 1)):
        sim.params.set(0, name, value)
    texts: list[str] = []
    endpoint = sim.endpoints[0]

    def capture(wall_now: float, clock_ms: int | None = None) -> None:  # keep what the vehicle says
        texts.extend(text for _, text in sim.autopilot.texts[0])
        sim.autopilot.texts[0].clear()
        endpoint.outbox.packets.clear()

    endpoint.flush = capture  # type: ignore[method-assign]
    return sim, texts


def _fly_east(sim: Simulator, speed: float, seconds: float) -> None:
    for _ in range(round(seconds / sim.timing.tick_s)):
        if sim.autopilot.mode[0] == modes.GUIDED:
            sim.autopilot.set_position_target(0, None, np.array([speed, 0.0, 0.0]), None, None, None)
        sim._tick()


def test_a_vehicle_flying_into_an_exclusion_circle_brakes_and_says_so():
    sim, texts = _sim_with_circle([0.0, 0.0, 10.0], (40.0, 0.0), 10.0)
    try:
        _fly_east(sim, 4.0, 16.0)
        a = sim.autopilot
        assert a.mode[0] == modes.BRAKE
        assert texts.index("Polygon fence breached") < texts.index("Manual recovery started")
        x = sim.dyn.state.pos[0, 0]
        assert 30.0 < x < 39.0  # entered at 30 m at 4 m/s, stopped short of the centre (40 m)
        assert np.hypot(*sim.dyn.state.vel[0, :2]) < 0.3
        assert a.fence.breaches[0] == f.POLYGON and a.fence.breach_count[0] == 1
        assert a.fence.mavlink_breach_type(0) == M.FENCE_BREACH_BOUNDARY
        present, enabled, health = a.sensor_bits(0)
        assert present & enabled & M.MAV_SYS_STATUS_GEOFENCE and not health & M.MAV_SYS_STATUS_GEOFENCE
        # a mode change back to GUIDED while breached is a manual recovery: the fence leaves it alone for 10 s
        assert a.set_mode(0, modes.GUIDED) == M.MAV_RESULT_ACCEPTED
        _fly_east(sim, 0.0, 2.0)
        assert a.mode[0] == modes.GUIDED and texts.count("Manual recovery started") == 2
    finally:
        sim.close()


def test_report_only_says_breached_and_flies_on():
    sim, texts = _sim_with_circle([0.0, 0.0, 10.0], (30.0, 0.0), 5.0, action=0)
    try:
        _fly_east(sim, 8.0, 8.0)
        assert sim.autopilot.mode[0] == modes.GUIDED and sim.dyn.state.pos[0, 0] > 35.0
        assert "Polygon fence breached" in texts and "Fence breach cleared" in texts
        assert "Manual recovery started" not in texts
    finally:
        sim.close()


def test_guided_destination_inside_the_fence_is_refused():
    sim, _ = _sim_with_circle([0.0, 0.0, 10.0], (40.0, 0.0), 10.0)
    try:
        _fly_east(sim, 0.0, 0.1)  # one fence check: FENCE_ENABLE takes effect
        a = sim.autopilot
        assert not a.set_position_target(0, np.array([40.0, 0.0, 10.0]), None, None, None, None)
        assert a.set_position_target(0, np.array([0.0, 20.0, 10.0]), None, None, None, None)
    finally:
        sim.close()


def test_pre_arm_refuses_a_vehicle_inside_an_exclusion_zone():
    sim, texts = _sim_with_circle([0.0, 0.0, 0.0], (3.0, 0.0), 5.0)
    try:
        _fly_east(sim, 0.0, 0.1)
        a = sim.autopilot
        assert a.arm(0, force=False) == M.MAV_RESULT_FAILED
        assert not a.persona(0).prearm_ok(0)
        _fly_east(sim, 0.0, 0.01)
        assert "PreArm: Vehicle breaching Polygon fence" in texts
        assert a.arm(0, force=True) == M.MAV_RESULT_ACCEPTED  # the force-arm magic skips the checks
    finally:
        sim.close()


def test_pre_arm_wants_a_position_and_a_fence_to_enforce():
    sim = Simulator(in_process_config([[0.0, 0.0, 0.0]], ready_delay=30.0))
    try:
        a = sim.autopilot
        sim.params.set(0, "FENCE_ENABLE", 1)  # FENCE_TYPE 7 by default: max alt and home circle need position
        for _ in range(5):
            sim._tick()
        assert a.arm(0, force=False) == M.MAV_RESULT_FAILED
        said = [text for _, text in a.texts[0]]
        assert (
            "PreArm: Need Position Estimate" in said
            and "PreArm: Fence enabled, need position estimate" in said
        )
        assert a.fence_prearm(0) == "Fence requires position"
        sim.params.set(0, "FENCE_TYPE", 4)  # polygons only, and none uploaded
        assert a.fence_prearm(0) == "Fences enabled, but none selected"
    finally:
        sim.close()


# --- over MAVLink ------------------------------------------------------------------------------------------


def _upload_circle(pilot: Pilot, lat_e7: int, lon_e7: int, radius: float) -> int:
    """MISSION_COUNT / MISSION_REQUEST / MISSION_ITEM_INT / MISSION_ACK with a scripted ground station."""
    v = pilot[0]
    for kind in ("MISSION_REQUEST", "MISSION_ACK"):
        v.latest.pop(kind, None)
    v.mav.mission_count_send(v.sysid, 1, 1, M.MAV_MISSION_TYPE_FENCE)

    def answered() -> bool:
        request = v.latest.pop("MISSION_REQUEST", None)
        if request is not None and request.mission_type == M.MAV_MISSION_TYPE_FENCE:
            v.mav.mission_item_int_send(
                v.sysid, 1, request.seq, M.MAV_FRAME_GLOBAL, CIRCLE_EXCL, 0, 0, radius, 0, 0, 0, lat_e7,
                lon_e7, 0, M.MAV_MISSION_TYPE_FENCE,
            )  # fmt: skip
        return "MISSION_ACK" in v.latest

    pilot.spin(answered, 5.0)
    return int(v.latest["MISSION_ACK"].type)


def test_breach_over_mavlink_brakes_with_statustext_and_fence_status(sitl, pilot_for):
    sim = sitl("--lockstep", "--ready-delay", "2", "--home=-35.0,149.0,500")
    pilot = pilot_for(sim)
    v = pilot[0]
    pilot.take_off(0, 10.0)
    # a circle of 8 m whose centre lies 25 m north of home
    lat_e7, lon_e7 = round((-35.0 + 25.0 / 111_000.0) * 1e7), 1_490_000_000
    assert _upload_circle(pilot, lat_e7, lon_e7, 8.0) == M.MAV_MISSION_ACCEPTED
    for name, value in (("FENCE_TYPE", 4), ("FENCE_ACTION", 4), ("FENCE_ENABLE", 1)):
        assert pilot.set_param(0, name, value) == value
    v.command(M.MAV_CMD_SET_MESSAGE_INTERVAL, M.MAVLINK_MSG_ID_FENCE_STATUS, 200_000)

    def north(vehicle):  # 3 m/s north (SET_POSITION_TARGET_LOCAL_NED velocity)
        vehicle.mav.set_position_target_local_ned_send(
            vehicle.time_boot_ms, vehicle.sysid, 1, M.MAV_FRAME_LOCAL_NED, 0b110111000111, 0, 0, 0, 3.0, 0, 0,
            0, 0, 0, 0, 0,
        )  # fmt: skip

    pilot.spin(lambda: v.mode == modes.BRAKE, 15.0, each_frame=north)
    pilot.spin(lambda: "FENCE_STATUS" in v.latest and v.latest["FENCE_STATUS"].breach_status == 1, 2.0)
    assert "Polygon fence breached" in v.texts
    status = v.latest["FENCE_STATUS"]
    assert status.breach_count == 1 and status.breach_type == M.FENCE_BREACH_BOUNDARY
    pilot.spin(
        lambda: math.hypot(v.latest["LOCAL_POSITION_NED"].vx, v.latest["LOCAL_POSITION_NED"].vy) < 0.2, 10.0
    )
    assert 17.0 < v.latest["LOCAL_POSITION_NED"].x < 25.0  # stopped inside the rim, short of the centre
