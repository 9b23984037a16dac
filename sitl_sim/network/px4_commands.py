"""The MAVLink surface of a PX4 vehicle: the command, mode, parameter and setpoint handlers that answer as
PX4's mavlink module and commander do, over the ArduCopter ones they extend (sitl_sim.network.commands,
.setpoints). The rules themselves live in sitl_sim.autopilot.px4; sources are cited beside each answer.
"""

from __future__ import annotations

import math

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from sitl_sim.autopilot.params import INT_TYPES, float_as_int32
from sitl_sim.autopilot.px4 import MODE_LAND, MODE_RTL, Px4
from sitl_sim.network.commands import CommandHandlers
from sitl_sim.network.message_fields import finite, param_name
from sitl_sim.network.services import SimulatorServices
from sitl_sim.network.setpoints import BODY_FRAMES, SetpointHandlers

M = mavlink2
PX4_VERSION = (1 << 24) | (16 << 16) | (0 << 8) | M.FIRMWARE_VERSION_TYPE_DEV  # reported as 1.16.0-dev
PX4_CAPABILITIES = (
    M.MAV_PROTOCOL_CAPABILITY_MAVLINK2
    | M.MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_BYTEWISE
    | M.MAV_PROTOCOL_CAPABILITY_COMMAND_INT
    | M.MAV_PROTOCOL_CAPABILITY_SET_ATTITUDE_TARGET
    | M.MAV_PROTOCOL_CAPABILITY_SET_POSITION_TARGET_LOCAL_NED
    | M.MAV_PROTOCOL_CAPABILITY_SET_POSITION_TARGET_GLOBAL_INT
)
# mavlink_receiver.cpp handle_message_set_position_target_local_ned: LOCAL_NED and BODY_NED only
PX4_LOCAL_FRAMES = (M.MAV_FRAME_LOCAL_NED, M.MAV_FRAME_BODY_NED)
ROLL_PITCH_RATES = (
    M.ATTITUDE_TARGET_TYPEMASK_BODY_ROLL_RATE_IGNORE | M.ATTITUDE_TARGET_TYPEMASK_BODY_PITCH_RATE_IGNORE
)


def px4_rules(sim: SimulatorServices, i: int) -> Px4:
    """Vehicle i's PX4 persona (the rules these handlers answer by)."""
    persona = sim.autopilot.persona(i)
    assert isinstance(persona, Px4), f"vehicle {i} is not a PX4 vehicle"
    return persona


class Px4CommandHandlers(CommandHandlers):
    """Commands, modes, parameters and stream requests of a PX4 vehicle."""

    capabilities = PX4_CAPABILITIES
    flight_sw_version = PX4_VERSION
    unavailable_result = M.MAV_RESULT_DENIED  # handle_request_message_command: a stream PX4 lacks -> DENIED

    def _on_heartbeat(self, msg: mavlink2.MAVLink_heartbeat_message, addr: tuple[str, int]) -> None:
        px4_rules(self.sim, self.index).gcs_heartbeat(self.index, msg.type)

    def _on_set_mode(self, msg: mavlink2.MAVLink_set_mode_message, addr: tuple[str, int]) -> None:
        """mavlink_receiver handle_message_set_mode: turned into VEHICLE_CMD_DO_SET_MODE (main and sub mode
        from the custom_mode union); commander answers that command (COMMAND_ACK command 176)."""
        main, sub = (msg.custom_mode >> 16) & 0xFF, (msg.custom_mode >> 24) & 0xFF
        px4 = px4_rules(self.sim, self.index)
        result = px4.set_mode(self.index, msg.base_mode, main, sub, msg.get_srcComponent())
        self.outbox.ack(M.MAV_CMD_DO_SET_MODE, self._refused_if_not_accepted(result), msg)

    def _command(self, command: int, p: tuple[float, ...], frame: int | None, source: int) -> int:
        """Commander::handle_command and mavlink_receiver's own commands (`source`: the sender's component,
        for commander's printRejectMode rule); others as the shared handler."""
        i, px4 = self.index, px4_rules(self.sim, self.index)
        if command == M.MAV_CMD_COMPONENT_ARM_DISARM:
            return self._refused_if_not_accepted(px4.arm(i, p[0], p[1]))
        if command == M.MAV_CMD_DO_SET_MODE:
            if not finite(p[0], p[1], p[2]):
                return self._invalid(M.MAV_RESULT_DENIED)
            modes = (int(p[0]) & 0xFF, int(p[1]) & 0xFF, int(p[2]) & 0xFF)
            return self._refused_if_not_accepted(px4.set_mode(i, *modes, source))
        if command == M.MAV_CMD_NAV_TAKEOFF:  # param7 AMSL (navigator takeoff); NaN: MIS_TAKEOFF_ALT
            home_amsl = self.sim.geodesy.alt0 + float(self.sim.autopilot.home[i, 2])
            altitude = p[6] if math.isfinite(p[6]) else math.nan
            return self._refused_if_not_accepted(px4.takeoff(i, altitude, home_amsl))
        if command in (M.MAV_CMD_NAV_LAND, M.MAV_CMD_NAV_RETURN_TO_LAUNCH):
            land = command == M.MAV_CMD_NAV_LAND
            result = px4.change_mode(i, MODE_LAND if land else MODE_RTL, source)
            if result == M.MAV_RESULT_ACCEPTED:
                text = "Landing at current position" if land else "Returning to launch"
                self.sim.autopilot.say(i, M.MAV_SEVERITY_INFO, text)
            return self._refused_if_not_accepted(result)
        if command == M.MAV_CMD_SET_MESSAGE_INTERVAL:
            # mavlink_receiver set_message_interval: HEARTBEAT or an unknown stream -> FAILED
            if not finite(p[0], p[1]) or int(p[0] + 0.5) == M.MAVLINK_MSG_ID_HEARTBEAT:
                return self._refused_if_not_accepted(M.MAV_RESULT_FAILED)
            interval = -1.0 if p[1] < -1e-5 else (0.0 if p[1] <= 1e-5 else p[1])
            if not self.sim.streams.set_interval(i, int(p[0] + 0.5), interval, self.sim.time_us):
                return self._refused_if_not_accepted(M.MAV_RESULT_FAILED)
            return M.MAV_RESULT_ACCEPTED
        if command == M.MAV_CMD_DO_FENCE_ENABLE:
            return M.MAV_RESULT_UNSUPPORTED  # geofences are not simulated for the PX4 persona
        return super()._command(command, p, frame, source)

    def _on_request_data_stream(
        self, msg: mavlink2.MAVLink_request_data_stream_message, addr: tuple[str, int]
    ) -> None:
        """PX4's mavlink_receiver has no REQUEST_DATA_STREAM handler: ignored (counted as refused)."""
        self.counters.refused += 1

    def _on_param_set(self, msg: mavlink2.MAVLink_param_set_message, addr: tuple[str, int]) -> None:
        """mavlink_parameters.cpp PARAM_SET: unknown name -> STATUSTEXT, no PARAM_VALUE; INT32 values are
        read bytewise from the float; another type than the parameter's is refused, its value echoed."""
        name = param_name(msg.param_id)
        params = self.sim.params
        j = params.lookup(self.index, name)
        if j is None:
            self.counters.refused += 1
            self.sim.autopilot.say(self.index, M.MAV_SEVERITY_ERROR, f"[pm] unknown param: {name}"[:50])
            return
        spec = params.specs[j]
        is_int = spec.type in INT_TYPES
        if msg.param_type != spec.type:
            self.counters.refused += 1
            text = f"[pm] param types mismatch: {name}"[:50]
            self.sim.autopilot.say(self.index, M.MAV_SEVERITY_ERROR, text)
            self._send_param(j)
            return
        value = float(float_as_int32(msg.param_value)) if is_int else float(msg.param_value)
        problem = params.check(name, value)
        if problem is not None:  # out of a range this simulator can fly: refused, the value echoed
            self.counters.refused += 1
            self.sim.autopilot.say(self.index, M.MAV_SEVERITY_WARNING, f"Param denied: {problem}"[:50])
            self._send_param(j)
            return
        self.sim.set_param(self.index, name, value)


class Px4SetpointHandlers(SetpointHandlers):
    """Offboard setpoints of a PX4 vehicle: every valid one is proof of life (offboard_control_mode), flown
    only in OFFBOARD (mavlink_receiver.cpp: "only publish setpoint once in OFFBOARD")."""

    def _on_position_target_local(
        self, msg: mavlink2.MAVLink_set_position_target_local_ned_message, addr: tuple[str, int]
    ) -> None:
        if msg.coordinate_frame not in PX4_LOCAL_FRAMES:
            self.counters.invalid += 1
            self.sim.autopilot.say(
                self.index,
                M.MAV_SEVERITY_CRITICAL,
                f"SET_POSITION_TARGET_LOCAL_NED coordinate frame {msg.coordinate_frame} unsupported",
            )
            return
        if msg.coordinate_frame in BODY_FRAMES:  # BODY_NED: position ignored (set to NaN) by PX4
            msg.type_mask |= 0b111
        super()._on_position_target_local(msg, addr)

    def _apply_position_target(self, msg, mask: int, pos, vel, acc, yaw_offset: float) -> None:  # noqa: ANN001
        if pos is None and vel is None and acc is None:
            self.counters.invalid += 1
            self.sim.autopilot.say(self.index, M.MAV_SEVERITY_CRITICAL, f"{msg.get_type()} invalid")
            return
        if not self._accepts(True):
            self.counters.refused += 1
            return
        super()._apply_position_target(msg, mask, pos, vel, acc, yaw_offset)

    def _accepts(self, mask_has_target: bool) -> bool:
        """A setpoint naming something to fly renews the proof of life; True when it is flown (OFFBOARD)."""
        if not mask_has_target:
            return False
        return px4_rules(self.sim, self.index).setpoint(self.index)

    def _on_attitude_target(
        self, msg: mavlink2.MAVLink_set_attitude_target_message, addr: tuple[str, int]
    ) -> None:
        """handle_message_set_attitude_target: attitude or body rates (roll and pitch) count; thrust is the
        normalised collective (fill_thrust: thrust_body[2] = -thrust for a quadrotor), 0 when ignored."""
        mask = msg.type_mask
        values = [*msg.q, msg.body_roll_rate, msg.body_pitch_rate, msg.body_yaw_rate, msg.thrust]
        if not finite(*values) or max(map(abs, values[4:7])) > 50.0:
            self.counters.invalid += 1
            return
        attitude = not mask & M.ATTITUDE_TARGET_TYPEMASK_ATTITUDE_IGNORE
        rates = not mask & ROLL_PITCH_RATES
        if not self._accepts(attitude or rates):
            self.counters.refused += 1
            return
        if mask & M.ATTITUDE_TARGET_TYPEMASK_THROTTLE_IGNORE:
            msg.thrust = 0.0
            msg.type_mask &= ~M.ATTITUDE_TARGET_TYPEMASK_THROTTLE_IGNORE
        super()._on_attitude_target(msg, addr)
