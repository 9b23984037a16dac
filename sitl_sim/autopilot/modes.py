"""ArduCopter's flight modes as the simulated autopilot knows them (custom_mode numbers), their names, the
groups ArduCopter treats alike, and the magic numbers of the commands that change them."""

from __future__ import annotations

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

STABILIZE, ALT_HOLD, GUIDED, LOITER, RTL, LAND, BRAKE, GUIDED_NOGPS = 0, 2, 4, 5, 6, 9, 17, 20
MODE_NAMES = {  # the simulated modes' names, as pymavlink's COPTER_MODE enum spells them
    mode: mavlink2.enums["COPTER_MODE"][mode].name.removeprefix("COPTER_MODE_")
    for mode in (STABILIZE, ALT_HOLD, GUIDED, LOITER, RTL, LAND, BRAKE, GUIDED_NOGPS)
}
# ArduCopter requires_GPS(): refused when armed without a position estimate
POSITION_MODES = (GUIDED, LOITER, RTL, BRAKE)
NOT_ARMABLE = (RTL, LAND, BRAKE)
GUIDED_ENABLED_MODES = (GUIDED, LOITER, RTL, BRAKE)  # ArduCopter base_mode() GUIDED_ENABLED list
FORCE_ARM = 2989  # MAV_CMD_COMPONENT_ARM_DISARM param2 that skips the arming checks
FORCE_DISARM = 21196  # ... and the one that disarms in flight
GUID_OPTION_THRUST = 8  # GUID_OPTIONS bit 3: SET_ATTITUDE_TARGET thrust is collective thrust

# FS_GCS_ENABLE -> action (ArduCopter 4.6 enumeration; SmartRTL and DO_LAND_START fall back to RTL/LAND).
GCS_FAILSAFE_ACTIONS = {1: RTL, 2: RTL, 3: RTL, 4: LAND, 5: LAND, 6: RTL, 7: BRAKE}
