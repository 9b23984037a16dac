"""The MAVLink mission protocol of one simulated vehicle, for geofence items (mission_type FENCE) and rally
points (mission_type RALLY), as ArduPilot answers it (libraries/GCS_MAVLink/MissionItemProtocol.cpp,
MissionItemProtocol_Fence.cpp, GCS_Common.cpp):

- upload: MISSION_COUNT(count, FENCE) -> the vehicle asks MISSION_REQUEST(seq, FENCE) for seq 0.. (ArduPilot
  asks with MISSION_REQUEST, id 40, not MISSION_REQUEST_INT: MissionItemProtocol::queued_request_send),
  re-asking after 1 s without the item and giving up 8 s after the last item it received ("Fence upload
  timeout", MISSION_ACK OPERATION_CANCELLED); each MISSION_ITEM_INT (or the deprecated MISSION_ITEM) with
  the requested seq is stored, any other seq is answered MISSION_ACK INVALID_SEQUENCE and the upload goes
  on; after the last item the whole fence is validated and stored: MISSION_ACK ACCEPTED, or ERROR with a
  STATUSTEXT saying why (AC_PolyFence_loader::validate_fence). A new MISSION_COUNT from the uploader starts
  over; from anyone else it is DENIED while an upload runs. An item that is not a fence command is
  UNSUPPORTED, an unsupported frame UNSUPPORTED_FRAME, a vertex count over 255 INVALID_PARAM1: all end the
  upload. More than MAX_ITEMS items: NO_SPACE ("Only 70 items are supported").
- MISSION_WRITE_PARTIAL_LIST(start, end, FENCE): the same for items start..end of the stored fence.
- download: MISSION_REQUEST_LIST(FENCE) -> MISSION_COUNT; MISSION_REQUEST_INT(seq, FENCE) -> MISSION_ITEM_INT
  (frame GLOBAL, x/y lat/lon degE7, param1 radius or vertex count), a seq out of range -> MISSION_COUNT and
  MISSION_ACK INVALID_SEQUENCE; the deprecated MISSION_REQUEST -> MISSION_ITEM (once "got MISSION_REQUEST;
  use MISSION_REQUEST_INT!"). While an upload runs both are DENIED.
- MISSION_CLEAR_ALL(FENCE): cancels an own upload, stores an empty fence, MISSION_ACK ACCEPTED.
- a PX4 vehicle (persona mission_protocol "px4", src/modules/mavlink/mavlink_mission.cpp) differs in two
  ways: it asks with MISSION_REQUEST_INT once the peer has used MISSION_REQUEST_INT or MISSION_ITEM_INT
  (_int_mode; the float forms switch it back), and it ignores an item of the wrong seq without an answer
  (handle_mission_item_both). Its fence and rally points are validated as ArduPilot's (PX4 refuses a polygon
  of fewer than 3 vertices with ERROR as well, but also takes rally points in frame GLOBAL; its dataman limits
  are not simulated).
- rally points (mission_type RALLY, MissionItemProtocol_Rally.cpp): the same transfers with
  MAV_CMD_NAV_RALLY_POINT items (another command: UNSUPPORTED) in frame GLOBAL_RELATIVE_ALT(_INT) (another:
  UNSUPPORTED_FRAME), z metres above home stored as a whole number (RallyLocation.alt, an int16; outside it
  INVALID_PARAM7); downloaded in frame GLOBAL_RELATIVE_ALT. Stored on completion (AP_Rally, RALLY_TOTAL) and
  used by RTL (sitl_sim.autopilot.rally). One transfer runs at a time, whatever its type (as PX4's single
  MavlinkMissionManager; ArduPilot runs one per type). "Rally upload timeout" after 8 s.
- other mission types: this simulator keeps no mission (AUTO), so MISSION_COUNT,
  MISSION_REQUEST_LIST, MISSION_CLEAR_ALL, MISSION_WRITE_PARTIAL_LIST and items of those types are answered
  MISSION_ACK UNSUPPORTED (what ArduPilot answers for a type it has no protocol for, MAV_MISSION_TYPE_ALL
  too); MISSION_REQUEST(_INT) of them get no answer (GCS_MAVLINK::handle_mission_request_int, no protocol).
  Over MAVLink 1 the mission_type extension is absent, so fence transfers need MAVLink 2.

Errors are counted in the endpoint's `refused` (well-formed, refused as ArduCopter would) or `invalid`
(NaN/absurd numbers); nothing here raises on input. Time is simulated time.
"""

from __future__ import annotations

import math

import numpy as np
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from sitl_sim.autopilot.fence import (
    FENCE_COMMANDS,
    MAX_ITEMS,
    POLYGON_EXCLUSION,
    POLYGON_INCLUSION,
    FenceItem,
    validate,
)
from sitl_sim.autopilot.rally import RallyItem
from sitl_sim.network.counters import LinkCounters
from sitl_sim.network.outbox import Outbox
from sitl_sim.network.services import SimulatorServices

FENCE = mavlink2.MAV_MISSION_TYPE_FENCE
RALLY = mavlink2.MAV_MISSION_TYPE_RALLY
SERVED = (FENCE, RALLY)
# MissionItemProtocol_Fence::timeout, MissionItemProtocol_Rally::timeout
TIMEOUT_TEXT = {FENCE: "Fence upload timeout", RALLY: "Rally upload timeout"}
RALLY_POINT = mavlink2.MAV_CMD_NAV_RALLY_POINT
RALLY_FRAMES = (mavlink2.MAV_FRAME_GLOBAL_RELATIVE_ALT, mavlink2.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT)
INT16 = (-32768, 32767)  # RallyLocation.alt m
UPLOAD_TIMEOUT_S = 8.0  # MissionItemProtocol upload_timeout_ms
REQUEST_RESEND_S = 1.0  # MissionItemProtocol::update wp_recv_timeout_ms (1000 + stream slowdown)
ITEM_FRAMES = (
    mavlink2.MAV_FRAME_GLOBAL,
    mavlink2.MAV_FRAME_GLOBAL_INT,
    mavlink2.MAV_FRAME_GLOBAL_RELATIVE_ALT,
    mavlink2.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
    mavlink2.MAV_FRAME_GLOBAL_TERRAIN_ALT,
    mavlink2.MAV_FRAME_GLOBAL_TERRAIN_ALT_INT,
)  # MissionItemProtocol_Fence::convert_MISSION_ITEM_INT_to_AC_PolyFenceItem


class FenceProtocol:
    """Mission-protocol state of vehicle `index` (fence and rally uploads, downloads and clears), served by
    `sim`; replies go to `outbox`, refusals to `counters`."""

    def __init__(self, index: int, counters: LinkCounters, outbox: Outbox, sim: SimulatorServices) -> None:
        self.index = index
        self.counters = counters
        self.outbox = outbox
        self.sim = sim
        self.receiving = False
        self.mission_type = FENCE  # of the upload running (or the last one)
        self.dest = (0, 0)  # (sysid, compid) of the uploader
        self.request_i = 0
        self.request_last = -1
        self.new_items: list[FenceItem | RallyItem | None] = []
        self.last_receive = 0.0
        self.last_request = 0.0
        self.int_mode = False  # the peer last used MISSION_REQUEST_INT / MISSION_ITEM_INT (PX4's _int_mode)
        self._item_warned = False
        self._request_warned = False
        self.handlers = {
            mavlink2.MAVLINK_MSG_ID_MISSION_COUNT: self._on_count,
            mavlink2.MAVLINK_MSG_ID_MISSION_WRITE_PARTIAL_LIST: self._on_write_partial_list,
            mavlink2.MAVLINK_MSG_ID_MISSION_ITEM_INT: self._on_item,
            mavlink2.MAVLINK_MSG_ID_MISSION_ITEM: self._on_item,
            mavlink2.MAVLINK_MSG_ID_MISSION_REQUEST_LIST: self._on_request_list,
            mavlink2.MAVLINK_MSG_ID_MISSION_REQUEST_INT: self._on_request,
            mavlink2.MAVLINK_MSG_ID_MISSION_REQUEST: self._on_request,
            mavlink2.MAVLINK_MSG_ID_MISSION_CLEAR_ALL: self._on_clear_all,
            mavlink2.MAVLINK_MSG_ID_MISSION_ACK: lambda msg: None,  # not used (GCS_Common.cpp)
        }

    # --- replies --------------------------------------------------------------------------------------------

    def _ack(self, msg: mavlink2.MAVLink_message, result: int, mission_type: int | None = None) -> None:
        """MISSION_ACK `result` to msg's sender, of `mission_type` (None: msg's own)."""
        if mission_type is None:
            mission_type = int(getattr(msg, "mission_type", FENCE))
        if result != mavlink2.MAV_MISSION_ACCEPTED:
            self.counters.refused += 1
        self.outbox.send(
            self.outbox.tx.mission_ack_encode(
                msg.get_srcSystem(), msg.get_srcComponent(), result, mission_type
            )
        )

    def _say(self, severity: int, text: str) -> None:
        self.sim.autopilot.say(self.index, severity, text)

    def _px4(self) -> bool:
        """Whether this vehicle answers as PX4's MavlinkMissionManager where it differs from ArduPilot."""
        return bool(self.sim.autopilot.persona(self.index).mission_protocol == "px4")

    def _send_request(self) -> None:
        """Ask the uploader for item request_i: MISSION_REQUEST, as ArduPilot; a PX4 vehicle asks with
        MISSION_REQUEST_INT once the peer spoke the _INT messages (mavlink_mission.cpp send_mission_request:
        _int_mode, set by MISSION_REQUEST_INT / MISSION_ITEM_INT, cleared by their float forms)."""
        if self.int_mode and self._px4():
            request = self.outbox.tx.mission_request_int_encode(*self.dest, self.request_i, self.mission_type)
        else:
            request = self.outbox.tx.mission_request_encode(*self.dest, self.request_i, self.mission_type)
        self.outbox.send(request)
        self.last_request = self.sim.t

    # --- handlers -------------------------------------------------------------------------------------------

    def _stored(self, mission_type: int) -> tuple[FenceItem, ...] | tuple[RallyItem, ...]:
        """The vehicle's stored items of `mission_type` (FENCE or RALLY)."""
        autopilot, i = self.sim.autopilot, self.index
        return autopilot.fence.items[i] if mission_type == FENCE else autopilot.rally.items[i]

    def _store(self, mission_type: int, items: list) -> None:  # type: ignore[type-arg]
        """Keep `items` as the vehicle's whole fence or rally list (rally points placed in the ENU frame)."""
        if mission_type == FENCE:
            self.sim.store_fence(self.index, items)
            return
        xy = np.zeros((len(items), 2))
        geodesy = self.sim.geodesy
        for k, item in enumerate(items):
            xy[k] = geodesy.to_enu(item.lat_e7 * 1e-7, item.lon_e7 * 1e-7, geodesy.alt0)[:2]
        self.sim.autopilot.store_rally(self.index, items, xy)

    def _fence(self, msg: mavlink2.MAVLink_message) -> bool:
        """Whether msg is about a served mission type (FENCE, RALLY); others are answered UNSUPPORTED."""
        mission_type = int(getattr(msg, "mission_type", 0))
        if mission_type in SERVED:
            return True
        if msg.get_msgId() not in (
            mavlink2.MAVLINK_MSG_ID_MISSION_REQUEST_INT,
            mavlink2.MAVLINK_MSG_ID_MISSION_REQUEST,
        ):
            self._ack(msg, mavlink2.MAV_MISSION_UNSUPPORTED, mission_type)
        else:
            self.counters.refused += 1
        return False

    def _cancel_upload(self, msg: mavlink2.MAVLink_message) -> bool:
        """MissionItemProtocol::cancel_upload: True if no upload runs or it was the sender's own."""
        if not self.receiving:
            return True
        if (msg.get_srcSystem(), msg.get_srcComponent()) != self.dest:
            self._ack(msg, mavlink2.MAV_MISSION_DENIED)
            return False
        self.receiving = False
        return True

    def _on_count(self, msg: mavlink2.MAVLink_mission_count_message) -> None:
        if not self._fence(msg) or not self._cancel_upload(msg):
            return
        if msg.mission_type == FENCE and msg.count > MAX_ITEMS:
            self._ack(msg, mavlink2.MAV_MISSION_NO_SPACE)
            self._say(mavlink2.MAV_SEVERITY_WARNING, f"Only {MAX_ITEMS} items are supported")
            return
        self.new_items = [None] * msg.count
        self.mission_type = int(msg.mission_type)
        if msg.count == 0:
            self._complete(msg)
            return
        self._start(msg, 0, msg.count - 1)

    def _on_write_partial_list(self, msg: mavlink2.MAVLink_mission_write_partial_list_message) -> None:
        if not self._fence(msg):
            return
        if self.receiving:
            self._ack(msg, mavlink2.MAV_MISSION_DENIED)
            return
        stored = self._stored(int(msg.mission_type))
        start, end = msg.start_index, msg.end_index
        if start > len(stored) or end > len(stored) or end < start or start < 0:
            self._say(mavlink2.MAV_SEVERITY_WARNING, "Flight plan update rejected")
            self._ack(msg, mavlink2.MAV_MISSION_ERROR)
            return
        self.new_items = list(stored)
        self.mission_type = int(msg.mission_type)
        self._start(msg, start, end)

    def _start(self, msg: mavlink2.MAVLink_message, first: int, last: int) -> None:
        """MissionItemProtocol::init_send_requests: ask for items first..last from the sender."""
        self.receiving = True
        self.dest = (msg.get_srcSystem(), msg.get_srcComponent())
        self.request_i, self.request_last = first, last
        self.last_receive = self.sim.t
        self._send_request()

    def _on_item(self, msg: mavlink2.MAVLink_message) -> None:
        if not self._fence(msg):
            return
        deprecated = msg.get_msgId() == mavlink2.MAVLINK_MSG_ID_MISSION_ITEM
        self.int_mode = not deprecated
        if deprecated:
            # GCS_MAVLINK::handle_mission_item converts it first (AP_Mission::
            # convert_MISSION_ITEM_to_MISSION_ITEM_INT: fence commands carry lat/lon in degrees)
            if not (math.isfinite(msg.x) and abs(msg.x) <= 90.0):
                self._ack(msg, mavlink2.MAV_MISSION_INVALID_PARAM5_X)
                return
            if not (math.isfinite(msg.y) and abs(msg.y) <= 180.0):
                self._ack(msg, mavlink2.MAV_MISSION_INVALID_PARAM6_Y)
                return
            if not self._item_warned:
                self._item_warned = True
                self._say(mavlink2.MAV_SEVERITY_WARNING, "got MISSION_ITEM; GCS should send MISSION_ITEM_INT")
        if not self.receiving or msg.mission_type != self.mission_type:
            self._ack(msg, mavlink2.MAV_MISSION_ERROR, int(msg.mission_type))
            return
        if msg.seq != self.request_i:
            if not self._px4():  # PX4 ignores it silently (handle_mission_item_both); both go on
                self._ack(msg, mavlink2.MAV_MISSION_INVALID_SEQUENCE)
            return
        if (msg.get_srcSystem(), msg.get_srcComponent()) != self.dest:
            self._ack(msg, mavlink2.MAV_MISSION_DENIED)
            return
        if msg.seq >= len(self.new_items):
            result = mavlink2.MAV_MISSION_INVALID_SEQUENCE
            item = None
        else:
            item, result = self._convert(msg, deprecated)
        if item is None:
            self._ack(msg, result, self.mission_type)
            self.receiving = False
            return
        self.new_items[msg.seq] = item
        self.last_receive = self.sim.t
        self.request_i += 1
        if self.request_i > self.request_last:
            self._complete(msg)
            return
        self._send_request()

    def _convert(
        self, msg: mavlink2.MAVLink_message, deprecated: bool
    ) -> tuple[FenceItem | RallyItem | None, int]:
        """MISSION_ITEM(_INT) -> FenceItem or RallyItem, or (None, the MAV_MISSION_RESULT refusing it)
        (MissionItemProtocol_Fence::convert_MISSION_ITEM_INT_to_AC_PolyFenceItem). What the conversion lets
        through (a NaN or negative radius, a vertex count of 0) is refused when the fence is validated."""
        scale = 1e7 if deprecated else 1.0  # AP_Mission::convert_MISSION_ITEM_to_MISSION_ITEM_INT
        if self.mission_type == RALLY:
            return self._convert_rally(msg, scale)
        if msg.frame not in ITEM_FRAMES:
            return None, mavlink2.MAV_MISSION_UNSUPPORTED_FRAME
        if msg.command not in FENCE_COMMANDS:
            return None, mavlink2.MAV_MISSION_UNSUPPORTED
        param1 = float(msg.param1)
        if not math.isfinite(param1):
            self.counters.invalid += 1
        if msg.command in (POLYGON_INCLUSION, POLYGON_EXCLUSION):
            if param1 > 255:
                return None, mavlink2.MAV_MISSION_INVALID_PARAM1
            param1 = float(int(param1)) if math.isfinite(param1) and param1 >= 0 else 0.0  # a uint8 count
        else:
            param1 = float(np.float32(param1))  # the radius is stored as a float
        lat, lon = round(float(msg.x) * scale), round(float(msg.y) * scale)
        return FenceItem(int(msg.command), lat, lon, param1), mavlink2.MAV_MISSION_ACCEPTED

    def _convert_rally(self, msg: mavlink2.MAVLink_message, scale: float) -> tuple[RallyItem | None, int]:
        """MissionItemProtocol_Rally::convert_MISSION_ITEM_INT_to_RallyLocation: the command, the frame, the
        position, z as an int16 of metres (a C conversion: truncated)."""
        if msg.command != RALLY_POINT:
            return None, mavlink2.MAV_MISSION_UNSUPPORTED
        if msg.frame not in RALLY_FRAMES:
            return None, mavlink2.MAV_MISSION_UNSUPPORTED_FRAME
        lat, lon = round(float(msg.x) * scale), round(float(msg.y) * scale)
        if abs(lat) > 900_000_000:  # check_lat
            return None, mavlink2.MAV_MISSION_INVALID_PARAM5_X
        if abs(lon) > 1_800_000_000:  # check_lng
            return None, mavlink2.MAV_MISSION_INVALID_PARAM6_Y
        z = float(msg.z)
        if not (math.isfinite(z) and INT16[0] <= z <= INT16[1]):
            self.counters.invalid += 0 if math.isfinite(z) else 1
            return None, mavlink2.MAV_MISSION_INVALID_PARAM7
        return RallyItem(lat, lon, float(math.trunc(z))), mavlink2.MAV_MISSION_ACCEPTED

    def _complete(self, msg: mavlink2.MAVLink_message) -> None:
        """MissionItemProtocol::transfer_is_complete: validate and store, then ACK."""
        self.receiving = False
        items = [item for item in self.new_items if item is not None]
        kind = self.mission_type
        if len(items) != len(self.new_items):
            self._say(mavlink2.MAV_SEVERITY_INFO, "Error replacing item")
            self._ack(msg, mavlink2.MAV_MISSION_ERROR, kind)
            return
        if kind == RALLY:
            self._store(RALLY, items)
            self._ack(msg, mavlink2.MAV_MISSION_ACCEPTED, RALLY)
            return
        problem = validate([item for item in items if isinstance(item, FenceItem)])
        if problem is not None:
            self._say(mavlink2.MAV_SEVERITY_WARNING, problem)
            self._say(mavlink2.MAV_SEVERITY_WARNING, "Fence validation failed")
            self._ack(msg, mavlink2.MAV_MISSION_ERROR)
            return
        self._store(FENCE, items)
        self._ack(msg, mavlink2.MAV_MISSION_ACCEPTED)

    def _on_request_list(self, msg: mavlink2.MAVLink_mission_request_list_message) -> None:
        if not self._fence(msg):
            return
        mission_type = int(msg.mission_type)
        if self.receiving:
            self._ack(msg, mavlink2.MAV_MISSION_DENIED, mission_type)
            return
        count = len(self._stored(mission_type))
        sysid, compid = msg.get_srcSystem(), msg.get_srcComponent()
        self.outbox.send(self.outbox.tx.mission_count_encode(sysid, compid, count, mission_type))

    def _on_request(self, msg: mavlink2.MAVLink_message) -> None:
        if not self._fence(msg):
            return
        deprecated = msg.get_msgId() == mavlink2.MAVLINK_MSG_ID_MISSION_REQUEST
        self.int_mode = not deprecated
        if self.receiving and not deprecated:
            self._ack(msg, mavlink2.MAV_MISSION_DENIED)
            return
        mission_type = int(msg.mission_type)
        stored = self._stored(mission_type)
        sysid, compid = msg.get_srcSystem(), msg.get_srcComponent()
        if not 0 <= msg.seq < len(stored):
            if not deprecated:
                count = self.outbox.tx.mission_count_encode(sysid, compid, len(stored), mission_type)
                self.outbox.send(count)
            self._ack(msg, mavlink2.MAV_MISSION_INVALID_SEQUENCE)
            return
        item = stored[msg.seq]
        if isinstance(item, RallyItem):  # MissionItemProtocol_Rally::get_item: above home
            frame, command, param1, z = mavlink2.MAV_FRAME_GLOBAL_RELATIVE_ALT, RALLY_POINT, 0.0, item.alt_m
        else:
            frame, command, param1, z = mavlink2.MAV_FRAME_GLOBAL, item.command, item.param1, 0.0
        if deprecated:
            if not self._request_warned:
                self._request_warned = True
                self._say(mavlink2.MAV_SEVERITY_WARNING, "got MISSION_REQUEST; use MISSION_REQUEST_INT!")
            self.outbox.send(self.outbox.tx.mission_item_encode(
                sysid, compid, msg.seq, frame, command, 0, 0, param1, 0.0, 0.0, 0.0, item.lat_e7 * 1e-7,
                item.lon_e7 * 1e-7, z, mission_type,
            ))  # fmt: skip
            return
        self.outbox.send(self.outbox.tx.mission_item_int_encode(
            sysid, compid, msg.seq, frame, command, 0, 0, param1, 0.0, 0.0, 0.0, item.lat_e7, item.lon_e7, z,
            mission_type,
        ))  # fmt: skip

    def _on_clear_all(self, msg: mavlink2.MAVLink_mission_clear_all_message) -> None:
        if not self._fence(msg) or not self._cancel_upload(msg):
            return
        self._store(int(msg.mission_type), [])
        self._ack(msg, mavlink2.MAV_MISSION_ACCEPTED)

    # --- time -----------------------------------------------------------------------------------------------

    def update(self) -> None:
        """MissionItemProtocol::update, every autopilot tick: give up an upload 8 s after its last item,
        re-ask for the awaited item after 1 s."""
        if not self.receiving:
            return
        now = self.sim.t
        if now - self.last_receive > UPLOAD_TIMEOUT_S:
            self.receiving = False
            self._say(mavlink2.MAV_SEVERITY_WARNING, TIMEOUT_TEXT[self.mission_type])
            self.counters.refused += 1
            cancelled = mavlink2.MAV_MISSION_OPERATION_CANCELLED
            self.outbox.send(self.outbox.tx.mission_ack_encode(*self.dest, cancelled, self.mission_type))
            return
        if now - self.last_request > REQUEST_RESEND_S:
            self._send_request()
