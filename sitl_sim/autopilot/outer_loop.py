"""The autopilot's fused outer loop over all vehicles (compiled by numba when available): guided timeouts,
navigation targets (takeoff, RTL stages, LAND descent, BRAKE), land detector, the position or angle control
law, and the disarm / GCS-failsafe events Python then handles (sitl_sim.autopilot.copter.Autopilot.update).

World ENU, body FLU, SI units; parameters in ArduCopter's units (cm, cdeg) as the parameter table holds them,
the PX4 persona's own (MPC_*, read for PX4 vehicles only) in PX4's (m, m/s).
"""

from __future__ import annotations

import math

import numpy as np

from sitl_sim.autopilot.modes import ALT_HOLD, BRAKE, GUIDED, GUIDED_NOGPS, LAND, RTL, STABILIZE
from swarm_common.jit import kernel
from swarm_common.shaping import sqrt_controller
from sitl_sim.vehicle_model.position_control import (
    I_MAX_XY,
    I_MAX_Z,
    MIN_UP_ACCEL,
    attitude_from_accel,
    brake_shaping_step,
    velocity_demand,
    velocity_pi,
)

CTRL_POS, CTRL_ANGLE = 0, 1
KIND_POS, KIND_VEL, KIND_POSVEL, KIND_ACCEL = 0, 1, 2, 3  # guided position-target kinds
KIND_BRAKE = 4  # BRAKE's shaped stop (position_control.brake_shaping_step)
BRAKE_DECEL = 7.5  # m/s^2, ArduCopter config.h BRAKE_MODE_DECEL_RATE (750 cm/s^2)
RTL_CLIMB, RTL_RETURN, RTL_DESCEND = 0, 1, 2

LAND_DETECT_S = 1.0  # ArduCopter LAND_DETECTOR_TRIGGER_SEC
LAND_ALT_LOW = 10.0  # m, LAND descends at WPNAV_SPEED_DN above, LAND_SPEED below (LAND_ALT_LOW 1000 cm)
SPIN_ARMED = 0.05  # fraction of full thrust while armed on the ground (MOT_SPIN_ARM-like)
RTL_REACHED_M = 1.0  # m, horizontal distance at which RTL starts its descent
TAKEOFF_REACHED_M = 0.1  # m below the takeoff altitude at which the takeoff is complete
# PX4 persona (sitl_sim.autopilot.px4): MPC_ACC_DOWN_MAX default (mc_pos_control
# multicopter_position_control_limits_params: 3 m/s^2), the descent acceleration of FlightTaskAuto's
# PositionSmoothing (FlightTaskAuto::_updateTrajConstraints, "down"); not a parameter of the persona
PX4_ACC_DOWN_MAX = 3.0
# SIH's downward distance sensor (simulator_sih sih.cpp send_dist_snsr, published while |SIH_DISTSNSR_OVR| <
# 10000, default -1): valid up to SIH_DISTSNSR_MAX (default 100 m), so PX4's FlightTask has _dist_to_bottom
PX4_RANGE_MAX_M = 100.0
# PX4's jerk-limited vertical trajectories (_smooth_vertical, px4.jerk_limited_step): the acceleration aimed
# at is sqrt_controller(velocity error, SMOOTH_P, jerk), i.e. the time-optimal sqrt(2 jerk |error|) (brought
# to 0 at the jerk limit as the error closes, as VelocitySmoothing plans) except within jerk / SMOOTH_P^2
# (0.04 m/s at 4 m/s^3), where it is linear: it lags a moving target by ~ rate^2 / (2 jerk), as PX4 does
SMOOTH_P = 10.0

EVENT_DISARM, EVENT_GCS_FAILSAFE = 1, 2
LOOP_PARAMS = (
    "MOT_THST_HOVER", "ANGLE_MAX", "GUID_TIMEOUT", "PSC_POSXY_P", "PSC_POSZ_P", "PSC_VELXY_P", "PSC_VELXY_I",
    "PSC_VELZ_P", "PSC_VELZ_I", "WPNAV_SPEED", "WPNAV_SPEED_UP", "WPNAV_SPEED_DN", "WPNAV_ACCEL",
    "LAND_SPEED", "DISARM_DELAY", "FS_GCS_ENABLE", "FS_GCS_TIMEOUT", "ATC_ANGLE_BOOST", "PSC_JERK_XY",
    "LOIT_BRK_ACCEL", "LOIT_BRK_JERK",
    "MPC_LAND_ALT1", "MPC_LAND_ALT2", "MPC_LAND_ALT3", "MPC_LAND_CRWL", "MPC_LAND_SPEED", "MPC_Z_VEL_MAX_DN",
    "MPC_Z_V_AUTO_DN", "MPC_JERK_AUTO",
)  # fmt: skip
(
    P_HOVER, P_ANGLE_MAX, P_GUID_TIMEOUT, P_POSXY_P, P_POSZ_P, P_VELXY_P, P_VELXY_I, P_VELZ_P, P_VELZ_I,
    P_SPEED, P_SPEED_UP, P_SPEED_DN, P_ACCEL, P_LAND_SPEED, P_DISARM_DELAY, P_FS_ENABLE, P_FS_TIMEOUT,
    P_ANGLE_BOOST, P_JERK_XY, P_LOIT_BRK_ACCEL, P_LOIT_BRK_JERK,
    P_PX4_LAND_ALT1, P_PX4_LAND_ALT2, P_PX4_LAND_ALT3, P_PX4_LAND_CRWL, P_PX4_LAND_SPEED, P_PX4_Z_VEL_MAX_DN,
    P_PX4_Z_V_AUTO_DN, P_PX4_JERK_AUTO,
) = range(len(LOOP_PARAMS))  # fmt: skip


@kernel
def _set_level(quats: np.ndarray, i: int, yaw: float) -> None:
    """Row i of (N,4) quaternions := level attitude at heading yaw (rad)."""
    quats[i, 0], quats[i, 1], quats[i, 2], quats[i, 3] = math.cos(0.5 * yaw), 0.0, 0.0, math.sin(0.5 * yaw)


@kernel
def px4_land_speed(
    height: float,
    alt1: float,
    alt2: float,
    alt3: float,
    land_speed: float,
    crawl_speed: float,
    max_down: float,
    auto_down: float,
) -> float:
    """PX4's AUTO.LAND descent speed (m/s, > 0) at `height` m above the ground, all in PX4's units.

    FlightTaskAuto::_prepareLandSetpoints: math::interpolate(_dist_to_ground, MPC_LAND_ALT2, MPC_LAND_ALT1,
    MPC_LAND_SPEED, MPC_Z_VEL_MAX_DN) (MPC_LAND_SPEED at and below ALT2, MPC_Z_VEL_MAX_DN above ALT1, linear
    between; FlightTaskAuto::updateParams keeps ALT1 >= ALT2), MPC_LAND_CRWL at and below MPC_LAND_ALT3 when a
    distance sensor measures the height (_dist_to_bottom finite: SIH's downward one, up to PX4_RANGE_MAX_M);
    the PositionSmoothing then caps the descent at MPC_Z_V_AUTO_DN (_updateTrajConstraints, "down").
    """
    alt1 = max(alt1, alt2)
    if height <= alt2:
        speed = land_speed
    elif height > alt1:
        speed = max_down
    else:  # lib/mathlib math::interpolate
        slope = (max_down - land_speed) / (alt1 - alt2)
        speed = slope * height + (land_speed - slope * alt2)
    if height <= min(alt3, PX4_RANGE_MAX_M):
        speed = crawl_speed
    return min(speed, auto_down)


@kernel
def jerk_limited_step(
    vel: float, acc: float, target: float, accel_max: float, jerk_max: float, dt: float
) -> tuple[float, float]:
    """(velocity, acceleration) one step dt towards the velocity `target` (m/s, m/s^2): acceleration at most
    accel_max, changing by at most jerk_max per s, never overshooting: the stand-in for PX4's jerk-limited
    PositionSmoothing (SMOOTH_P) in the PX4 persona's descents (_smooth_vertical) and climbs (px4.py)."""
    want = min(max(sqrt_controller(target - vel, SMOOTH_P, jerk_max, 0.0), -accel_max), accel_max)
    acc += min(max(want - acc, -jerk_max * dt), jerk_max * dt)
    new_vel = vel + acc * dt
    if (new_vel - target) * (vel - target) <= 0.0:
        return target, 0.0
    return new_vel, acc


@kernel
def _smooth_vertical(
    nav_vel: np.ndarray,
    nav_acc: np.ndarray,
    i: int,
    target: float,
    accel_max: float,
    jerk_max: float,
    dt: float,
) -> None:
    """One step of vehicle i's vertical velocity target (nav_vel[i, 2], its acceleration nav_acc[i, 2], ENU)
    towards `target` m/s (jerk_limited_step)."""
    nav_vel[i, 2], nav_acc[i, 2] = jerk_limited_step(
        nav_vel[i, 2], nav_acc[i, 2], target, accel_max, jerk_max, dt
    )


@kernel
def outer_loop(
    t, dt, g, params, columns,
    pos, vel, quat, landed, crashed, home,
    mode, armed, control, nav_kind, nav_pos, nav_vel, nav_acc, nav_yaw, nav_yaw_rate, target_time, rtl_stage,
    takeoff_active, land_complete, land_timer, disarm_timer, thrust_demand,
    angle_quat, angle_rates, angle_rate_ff, rates_only, climb_rate, collective, use_thrust, angle_timed_out,
    integrator, last_gcs_heartbeat, failsafe_gcs, climb_cap, px4,
    quat_sp, rate_ff, motors_on, tilt_max, rate_mask, events,
):  # fmt: skip  # noqa: ANN001, ANN202 - numba kernel over the Autopilot's arrays (see Autopilot.update)
    """Per vehicle: guided timeouts, navigation targets, land detector, control law, disarm/failsafe events.

    Writes quat_sp (N,4), rate_ff (N,3), thrust_demand (fraction of full thrust), motors_on, tilt_max (rad),
    rate_mask (rate-only control) and events (0, EVENT_DISARM, EVENT_GCS_FAILSAFE) for Python to act on.
    climb_cap (N,) m/s caps the upward velocity demand of position control (+inf: none); px4 (N,) bool: the
    vehicles whose landing descent is PX4's (px4_land_speed); both are the PX4 persona's only.
    """
    for i in range(len(mode)):
        p = params[i]
        hover = p[columns[P_HOVER]]
        tilt = math.radians(p[columns[P_ANGLE_MAX]] / 100.0)
        w, x, y, z = quat[i, 0], quat[i, 1], quat[i, 2], quat[i, 3]
        yaw_now = math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
        m = mode[i]
        guided = m == GUIDED
        angle_guided = (guided or m == GUIDED_NOGPS) and control[i] == CTRL_ANGLE
        stale = t - target_time[i] > p[columns[P_GUID_TIMEOUT]]

        # GUID_TIMEOUT: velocity/acceleration targets stop; attitude targets level and hold altitude.
        if guided and control[i] == CTRL_POS and stale and nav_kind[i] != KIND_POS:
            nav_vel[i] = 0.0
            nav_acc[i] = 0.0
        if angle_guided and stale and not angle_timed_out[i]:
            _set_level(angle_quat, i, yaw_now)
            angle_rates[i] = 0.0
            angle_rate_ff[i] = False
            rates_only[i] = False
            climb_rate[i] = 0.0
            use_thrust[i] = False
            angle_timed_out[i] = True

        # Navigation: takeoff completion, RTL stages, LAND descent speed, BRAKE hold, guided yaw rate.
        if takeoff_active[i] and pos[i, 2] >= nav_pos[i, 2] - TAKEOFF_REACHED_M:
            takeoff_active[i] = False
        if m == RTL and armed[i]:
            if rtl_stage[i] == RTL_CLIMB and pos[i, 2] >= nav_pos[i, 2] - 0.5:
                nav_pos[i, 0], nav_pos[i, 1] = home[i, 0], home[i, 1]
                rtl_stage[i] = RTL_RETURN
            elif (
                rtl_stage[i] == RTL_RETURN
                and math.hypot(pos[i, 0] - home[i, 0], pos[i, 1] - home[i, 1]) < RTL_REACHED_M
            ):
                nav_pos[i, 2] = math.nan
                rtl_stage[i] = RTL_DESCEND
        landing = m == LAND or (m == RTL and rtl_stage[i] == RTL_DESCEND)
        if landing and px4[i]:  # PX4's descent profile, through its jerk-limited trajectory
            speed = px4_land_speed(
                pos[i, 2] - home[i, 2], p[columns[P_PX4_LAND_ALT1]], p[columns[P_PX4_LAND_ALT2]],
                p[columns[P_PX4_LAND_ALT3]], p[columns[P_PX4_LAND_SPEED]], p[columns[P_PX4_LAND_CRWL]],
                p[columns[P_PX4_Z_VEL_MAX_DN]], p[columns[P_PX4_Z_V_AUTO_DN]],
            )  # fmt: skip
            _smooth_vertical(nav_vel, nav_acc, i, -speed, PX4_ACC_DOWN_MAX, p[columns[P_PX4_JERK_AUTO]], dt)
        elif landing:
            low = pos[i, 2] - home[i, 2] <= LAND_ALT_LOW
            nav_vel[i, 2] = -(p[columns[P_LAND_SPEED]] if low else p[columns[P_SPEED_DN]]) / 100.0
        if m == BRAKE and nav_kind[i] == KIND_BRAKE:
            brake_shaping_step(nav_pos[i], nav_vel[i], nav_acc[i], BRAKE_DECEL, p[columns[P_JERK_XY]], dt)
        elif m == LAND and nav_kind[i] == KIND_BRAKE:  # AC_Loiter's braking: LOIT_BRK_ACCEL, LOIT_BRK_JERK
            brake_shaping_step(
                nav_pos[i], nav_vel[i], nav_acc[i], p[columns[P_LOIT_BRK_ACCEL]] / 100.0,
                p[columns[P_LOIT_BRK_JERK]] / 100.0, dt,
            )  # fmt: skip
        if guided and control[i] == CTRL_POS:
            nav_yaw[i] += nav_yaw_rate[i] * dt

        # Land detector: on the ground LAND_DETECT_S without a climb demand (at once when disarmed).
        quiet = landed[i] and not takeoff_active[i] and (not armed[i] or thrust_demand[i] < hover)
        land_timer[i] = land_timer[i] + dt if quiet else 0.0
        land_complete[i] = (land_complete[i] and landed[i]) or (
            quiet and (not armed[i] or land_timer[i] >= LAND_DETECT_S)
        )
        # A positive climb/thrust demand in guided angle control takes off (ArduCopter angle_control_run).
        if angle_guided and (
            (use_thrust[i] and collective[i] > 0.0) or (not use_thrust[i] and climb_rate[i] > 0.0)
        ):
            land_complete[i] = False
            land_timer[i] = 0.0

        # Control law.
        if m == STABILIZE:
            collective[i] = hover  # no RC: the throttle stick rests at mid (hover)
        angle = angle_guided or m == STABILIZE or m == ALT_HOLD
        direct = angle and use_thrust[i]
        flying = armed[i] and not land_complete[i]
        speed_dn = p[columns[P_SPEED_DN]] / 100.0
        speed_up = p[columns[P_SPEED_UP]] / 100.0
        vx, vy, vz = velocity_demand(
            pos[i], nav_pos[i], nav_vel[i], p[columns[P_POSXY_P]], p[columns[P_POSZ_P]],
            p[columns[P_ACCEL]] / 100.0, p[columns[P_SPEED]] / 100.0, speed_up, speed_dn,
        )  # fmt: skip
        if climb_cap[i] < vz:  # the PX4 persona's takeoff limit (never set for ArduCopter: +inf)
            vz = climb_cap[i]
        ax = ay = az = 0.0
        if angle:
            vz = min(max(climb_rate[i], -speed_dn), speed_up)
        elif flying:
            kp, ki = p[columns[P_VELXY_P]], p[columns[P_VELXY_I]]
            ax, integrator[i, 0] = velocity_pi(vx - vel[i, 0], integrator[i, 0], kp, ki, I_MAX_XY, dt)
            ay, integrator[i, 1] = velocity_pi(vy - vel[i, 1], integrator[i, 1], kp, ki, I_MAX_XY, dt)
            ax += nav_acc[i, 0]
            ay += nav_acc[i, 1]
        if flying and not direct:
            kp, ki = p[columns[P_VELZ_P]], p[columns[P_VELZ_I]]
            az, integrator[i, 2] = velocity_pi(vz - vel[i, 2], integrator[i, 2], kp, ki, I_MAX_Z, dt)
            az += 0.0 if angle else nav_acc[i, 2]
        if angle or not flying:
            integrator[i, 0] = integrator[i, 1] = 0.0
        if not flying or direct:
            integrator[i, 2] = 0.0
        if angle:
            quat_sp[i] = angle_quat[i]
            up = max(1.0 - 2.0 * (x * x + y * y), math.cos(tilt))  # cos(tilt) of the actual attitude
            if direct:
                # guided thrust goes through set_throttle_out(thrust, apply_angle_boost=true)
                # (mode_guided.cpp angle_control_run); AC_AttitudeControl_Multi::get_throttle_boosted: with
                # ATC_ANGLE_BOOST, x inverted_factor / clamp(cos(current lean), 0.1, 1)
                fraction = collective[i]
                if p[columns[P_ANGLE_BOOST]] != 0.0:
                    cos_lean = 1.0 - 2.0 * (x * x + y * y)
                    inverted = min(max(10.0 * cos_lean, 0.0), 1.0)
                    fraction = fraction * inverted / min(max(cos_lean, 0.1), 1.0)
            else:
                fraction = hover * max(g + az, MIN_UP_ACCEL * g) / g / up
        else:
            qw, qx, qy, qz, thrust_g = attitude_from_accel(ax, ay, az, nav_yaw[i], tilt, g)
            quat_sp[i, 0], quat_sp[i, 1], quat_sp[i, 2], quat_sp[i, 3] = qw, qx, qy, qz
            fraction = hover * thrust_g
        if armed[i] and land_complete[i]:  # armed on the ground: level, motors spinning slowly
            _set_level(quat_sp, i, yaw_now)
            fraction = SPIN_ARMED
        motors_on[i] = armed[i] and not crashed[i]
        thrust_demand[i] = min(max(fraction, 0.0), 1.0) if motors_on[i] else 0.0
        # ANGLE_MAX limits the lean the autopilot's own controllers ask for; a guided attitude target is flown
        # as given (AC_AttitudeControl::input_quaternion has no lean limit)
        tilt_max[i] = math.pi if angle_guided and not (armed[i] and land_complete[i]) else tilt
        use_ff = angle_guided and angle_rate_ff[i] and not rates_only[i]
        for k in range(3):
            rate_ff[i, k] = angle_rates[i, k] if use_ff else 0.0
        rate_mask[i] = angle_guided and rates_only[i] and not (armed[i] and land_complete[i])

        # Events for Python: disarm on touchdown in LAND/RTL or after DISARM_DELAY landed; GCS failsafe.
        events[i] = 0
        delay = p[columns[P_DISARM_DELAY]]
        waiting = armed[i] and land_complete[i] and delay > 0.0
        disarm_timer[i] = disarm_timer[i] + dt if waiting else 0.0
        if armed[i] and land_complete[i] and (landing or (waiting and disarm_timer[i] >= delay)):
            events[i] = EVENT_DISARM
        silent = t - last_gcs_heartbeat[i] > p[columns[P_FS_TIMEOUT]]
        if p[columns[P_FS_ENABLE]] > 0 and armed[i] and math.isfinite(last_gcs_heartbeat[i]) and silent:
            if not failsafe_gcs[i] and events[i] == 0:
                events[i] = EVENT_GCS_FAILSAFE
