"""SYS_STATUS sensor bits and EKF_STATUS_REPORT flags as ArduCopter sets them."""

from __future__ import annotations

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

# sensor bits as ArduCopter sets them (MAVSDK: GPS present+healthy -> position ok,
# PREARM_CHECK healthy -> armable).
SENSORS_ALWAYS = (
    mavlink2.MAV_SYS_STATUS_SENSOR_3D_GYRO
    | mavlink2.MAV_SYS_STATUS_SENSOR_3D_ACCEL
    | mavlink2.MAV_SYS_STATUS_SENSOR_3D_MAG
    | mavlink2.MAV_SYS_STATUS_SENSOR_ABSOLUTE_PRESSURE
    | mavlink2.MAV_SYS_STATUS_SENSOR_ANGULAR_RATE_CONTROL
    | mavlink2.MAV_SYS_STATUS_SENSOR_ATTITUDE_STABILIZATION
    | mavlink2.MAV_SYS_STATUS_SENSOR_YAW_POSITION
    | mavlink2.MAV_SYS_STATUS_SENSOR_BATTERY
)
SENSOR_XY = mavlink2.MAV_SYS_STATUS_SENSOR_XY_POSITION_CONTROL
SENSOR_Z = mavlink2.MAV_SYS_STATUS_SENSOR_Z_ALTITUDE_CONTROL
SENSORS_PRESENT = (
    SENSORS_ALWAYS
    | mavlink2.MAV_SYS_STATUS_SENSOR_GPS
    | SENSOR_XY
    | SENSOR_Z
    | mavlink2.MAV_SYS_STATUS_SENSOR_MOTOR_OUTPUTS
    | mavlink2.MAV_SYS_STATUS_AHRS
    | mavlink2.MAV_SYS_STATUS_PREARM_CHECK
)
EKF_BOOTING = mavlink2.EKF_UNINITIALIZED
EKF_NO_GPS = (
    mavlink2.EKF_ATTITUDE
    | mavlink2.EKF_VELOCITY_VERT
    | mavlink2.EKF_POS_VERT_ABS
    | mavlink2.EKF_CONST_POS_MODE
)
EKF_GOOD = (
    mavlink2.EKF_ATTITUDE
    | mavlink2.EKF_VELOCITY_HORIZ
    | mavlink2.EKF_VELOCITY_VERT
    | mavlink2.EKF_POS_HORIZ_REL
    | mavlink2.EKF_POS_HORIZ_ABS
    | mavlink2.EKF_POS_VERT_ABS
    | mavlink2.EKF_PRED_POS_HORIZ_REL
    | mavlink2.EKF_PRED_POS_HORIZ_ABS
)
