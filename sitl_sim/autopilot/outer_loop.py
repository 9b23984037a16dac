"""The autopilot's outer loop over all vehicles, compiled (swarm_common.jit): guided timeouts, navigation
targets (takeoff, RTL stages, the landing descent, BRAKE), land detector, the position or angle control
law, and the disarm / GCS-failsafe events the personas then handle (sitl_sim.autopilot.copter.Autopilot
.update).

World ENU, body FLU, SI units; the shared parameter columns in ArduCopter's units (cm, cdeg) as the parameter
table holds them. Its inputs and outputs are grouped in named records of arrays (Vehicles, Modes, Navigation,
AngleTargets, Descent, Outputs; N vehicles). What differs per persona is data in these records: the landing
descent profile and its parameters (Descent), an upward velocity limit (Navigation.climb_cap).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from sitl_sim.autopilot.modes import ALT_HOLD, BRAKE, GUIDED, GUIDED_NOGPS, LAND, RTL, STABILIZE
from sitl_sim.vehicle_model.position_control import (
    I_MAX_XY,
    I_MAX_Z,
    MIN_UP_ACCEL,
    attitude_from_accel,
    brake_shaping_step,
    velocity_demand,
    velocity_pi,
)
from swarm_common.jit import kernel
from swarm_common.shaping import sqrt_controller

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
# Jerk-limited vertical trajectories (jerk_limited_step): the acceleration aimed at is
# sqrt_controller(velocity error, SMOOTH_P, jerk), i.e. the time-optimal sqrt(2 jerk |error|) (brought to 0
# at the jerk limit as the error closes, as a jerk-limited velocity smoother plans) except within
# jerk / SMOOTH_P^2 (0.04 m/s at 4 m/s^3), where it is linear: it lags a moving target by ~ rate^2 / (2 jerk)
SMOOTH_P = 10.0

EVENT_DISARM, EVENT_GCS_FAILSAFE = 1, 2
NO_VELOCITY = np.zeros(3)  # the feed-forward velocity of a target without one
LOOP_PARAMS = (
    "MOT_THST_HOVER", "ANGLE_MAX", "GUID_TIMEOUT", "PSC_POSXY_P", "PSC_POSZ_P", "PSC_VELXY_P", "PSC_VELXY_I",
    "PSC_VELZ_P", "PSC_VELZ_I", "WPNAV_SPEED", "WPNAV_SPEED_UP", "WPNAV_SPEED_DN", "WPNAV_ACCEL",
    "LAND_SPEED", "DISARM_DELAY", "FS_GCS_ENABLE", "FS_GCS_TIMEOUT", "ATC_ANGLE_BOOST", "PSC_JERK_XY",
    "LOIT_BRK_ACCEL", "LOIT_BRK_JERK",
)  # fmt: skip
(
    P_HOVER, P_ANGLE_MAX, P_GUID_TIMEOUT, P_POSXY_P, P_POSZ_P, P_VELXY_P, P_VELXY_I, P_VELZ_P, P_VELZ_I,
    P_SPEED, P_SPEED_UP, P_SPEED_DN, P_ACCEL, P_LAND_SPEED, P_DISARM_DELAY, P_FS_ENABLE, P_FS_TIMEOUT,
    P_ANGLE_BOOST, P_JERK_XY, P_LOIT_BRK_ACCEL, P_LOIT_BRK_JERK,
) = range(len(LOOP_PARAMS))  # fmt: skip
# Landing descent profiles (Descent.profile): ArduCopter's two speeds (LAND_SPEED below LAND_ALT_LOW,
# WPNAV_SPEED_DN above, as the target velocity at once), or a speed interpolated between two heights with a
# crawl near the ground, capped, and reached through the jerk-limited trajectory (interpolated_land_speed)
DESCENT_TWO_SPEED, DESCENT_INTERPOLATED = 0, 1
# Descent.columns: the parameter columns DESCENT_INTERPOLATED reads, in this order (all in m, m/s, m/s^3)
D_ALT_FAST, D_ALT_SLOW, D_ALT_CRAWL, D_CRAWL_SPEED, D_SLOW_SPEED, D_FAST_SPEED, D_SPEED_CAP, D_JERK = range(8)


class Vehicles(NamedTuple):
    """The physics' state the loop reads: pos, vel (N,3) ENU m, m/s; quat (N,4) body FLU -> world ENU; landed,
    crashed (N,) bool; home (N,3) ENU m; rtl_dest (N,3) ENU m, where RTL returns and lands (home or a rally
    point, chosen by the persona as RTL starts)."""

    pos: np.ndarray
    vel: np.ndarray
    quat: np.ndarray
    landed: np.ndarray
    crashed: np.ndarray
    home: np.ndarray
    rtl_dest: np.ndarray


class Modes(NamedTuple):
    """Mode state (N,): mode (internal, ArduCopter-numbered), armed, control (CTRL_*), rtl_stage (RTL_*),
    takeoff_active, land_complete, land_timer and disarm_timer (s), target_time (s of the last guided target),
    last_gcs_heartbeat (s), failsafe_gcs."""

    mode: np.ndarray
    armed: np.ndarray
    control: np.ndarray
    rtl_stage: np.ndarray
    takeoff_active: np.ndarray
    land_complete: np.ndarray
    land_timer: np.ndarray
    disarm_timer: np.ndarray
    target_time: np.ndarray
    last_gcs_heartbeat: np.ndarray
    failsafe_gcs: np.ndarray


class Navigation(NamedTuple):
    """Position-control targets: kind (N,) KIND_*; pos, vel, acc (N,3) ENU m, m/s, m/s^2 (NaN pos: that axis
    free); yaw, yaw_rate (N,) rad, rad/s ENU; climb_cap (N,) m/s, an upward velocity limit a persona puts on
    position control (+inf: none); integrator (N,3) velocity PI memory, m/s^2."""

    kind: np.ndarray
    pos: np.ndarray
    vel: np.ndarray
    acc: np.ndarray
    yaw: np.ndarray
    yaw_rate: np.ndarray
    climb_cap: np.ndarray
    integrator: np.ndarray


class AngleTargets(NamedTuple):
    """Angle-control targets: quat (N,4); rates (N,3) body FLU rad/s; rate_ff, rates_only (N,) bool;
    climb_rate (N,) m/s; collective (N,) fraction of full thrust, used when use_thrust; timed_out (N,)
    bool."""

    quat: np.ndarray
    rates: np.ndarray
    rate_ff: np.ndarray
    rates_only: np.ndarray
    climb_rate: np.ndarray
    collective: np.ndarray
    use_thrust: np.ndarray
    timed_out: np.ndarray


class Descent(NamedTuple):
    """Each vehicle's landing descent, from its persona: profile (N,) DESCENT_*; for DESCENT_INTERPOLATED
    columns (N,8) the parameter columns read (D_*), accel_down (N,) m/s^2 the trajectory's descent
    acceleration, range_max (N,) m the height up to which the crawl applies (a range finder's)."""

    profile: np.ndarray
    columns: np.ndarray
    accel_down: np.ndarray
    range_max: np.ndarray


class Outputs(NamedTuple):
    """What the loop hands on: quat_sp (N,4), rate_ff (N,3) rad/s, thrust_demand (N,) fraction of full thrust
    (also read back: the land detector's last demand), motors_on (N,), tilt_max (N,) rad, rate_mask (N,) bool
    (rate-only control), events (N,) EVENT_* for the personas."""

    quat_sp: np.ndarray
    rate_ff: np.ndarray
    thrust_demand: np.ndarray
    motors_on: np.ndarray
    tilt_max: np.ndarray
    rate_mask: np.ndarray
    events: np.ndarray


@kernel
def _set_level(quats: np.ndarray, i: int, yaw: float) -> None:
    """Row i of (N,4) quaternions := level attitude at heading yaw (rad)."""
    quats[i, 0], quats[i, 1], quats[i, 2], quats[i, 3] = math.cos(0.5 * yaw), 0.0, 0.0, math.sin(0.5 * yaw)


@kernel
def interpolated_land_speed(
    height: float,
    alt1: float,
    alt2: float,
    alt3: float,
    land_speed: float,
    crawl_speed: float,
    max_down: float,
    auto_down: float,
    range_max: float,
) -> float:
    """DESCENT_INTERPOLATED's descent speed (m/s, > 0) at `height` m above the ground (the
    AUTO.LAND of sitl_sim.autopilot's second persona, whose module cites its source and parameters).

    land_speed at and below alt2, max_down above alt1, linear between (alt1 is kept >= alt2); crawl_speed at
    and below alt3 while the height is within range_max (a range finder measures it); the result capped at
    auto_down.
    """
    alt1 = max(alt1, alt2)
    if height <= alt2:
        speed = land_speed
    elif height > alt1:
        speed = max_down
    else:  # lib/mathlib math::interpolate
        slope = (max_down - land_speed) / (alt1 - alt2)
        speed = slope * height + (land_speed - slope * alt2)
    if height <= min(alt3, range_max):
        speed = crawl_speed
    return min(speed, auto_down)


@kernel
def jerk_limited_step(
    vel: float, acc: float, target: float, accel_max: float, jerk_max: float, dt: float
) -> tuple[float, float]:
    """(velocity, acceleration) one step dt towards the velocity `target` (m/s, m/s^2): acceleration at most
    accel_max, changing by at most jerk_max per s, never overshooting (SMOOTH_P): the DESCENT_INTERPOLATED
    descents and the climbs a persona limits (Navigation.climb_cap)."""
    want = min(max(sqrt_controller(target - vel, SMOOTH_P, jerk_max, 0.0), -accel_max), accel_max)
    acc += min(max(want - acc, -jerk_max * dt), jerk_max * dt)
    new_vel = vel + acc * dt
    if (new_vel - target) * (vel - target) <= 0.0:
        return target, 0.0
    return new_vel, acc


@kernel
def outer_loop(
    t: float,
    dt: float,
    g: float,
    params: np.ndarray,
    columns: np.ndarray,
    vehicles: Vehicles,
    modes: Modes,
    navigation: Navigation,
    angle: AngleTargets,
    descent: Descent,
    out: Outputs,
) -> None:
    """One tick at simulated time t (s) covering dt (s), per vehicle: guided timeouts, navigation targets,
    land detector, control law, disarm/failsafe events. params (N, P) the parameter table's values, columns
    (len LOOP_PARAMS,) the column of each LOOP_PARAMS entry; g m/s^2. Updates the records in place and writes
    `out`.
    """
    pos, vel, quat, landed, crashed, home, rtl_dest = vehicles
    (
        mode, armed, control, rtl_stage, takeoff_active, land_complete,
        land_timer, disarm_timer, target_time, last_gcs_heartbeat, failsafe_gcs,
    ) = modes  # fmt: skip
    nav_kind, nav_pos, nav_vel, nav_acc, nav_yaw, nav_yaw_rate, climb_cap, integrator = navigation
    angle_quat, angle_rates, angle_rate_ff, rates_only, climb_rate, collective, use_thrust, timed_out = angle
    quat_sp, rate_ff, thrust_demand, motors_on, tilt_max, rate_mask, events = out
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
        # A pos-vel-accel target moves on between two setpoints as ArduCopter's does: AC_PosControl::
        # input_pos_vel_accel_xy / _z project the guided position and velocity forward with the target's
        # acceleration every loop (update_pos_vel_accel); after GUID_TIMEOUT (above) it stops where it got to
        if guided and control[i] == CTRL_POS and nav_kind[i] == KIND_POSVEL:
            for k in range(3):
                nav_pos[i, k] += (nav_vel[i, k] + 0.5 * nav_acc[i, k] * dt) * dt
                nav_vel[i, k] += nav_acc[i, k] * dt
        if angle_guided and stale and not timed_out[i]:
            _set_level(angle_quat, i, yaw_now)
            angle_rates[i] = 0.0
            angle_rate_ff[i] = False
            rates_only[i] = False
            climb_rate[i] = 0.0
            use_thrust[i] = False
            timed_out[i] = True

        # Navigation: takeoff completion, RTL stages, LAND descent speed, BRAKE hold, guided yaw rate.
        if takeoff_active[i] and pos[i, 2] >= nav_pos[i, 2] - TAKEOFF_REACHED_M:
            takeoff_active[i] = False
        if m == RTL and armed[i]:
            if rtl_stage[i] == RTL_CLIMB and pos[i, 2] >= nav_pos[i, 2] - 0.5:
                nav_pos[i, 0], nav_pos[i, 1] = rtl_dest[i, 0], rtl_dest[i, 1]
                rtl_stage[i] = RTL_RETURN
            elif (
                rtl_stage[i] == RTL_RETURN
                and math.hypot(pos[i, 0] - rtl_dest[i, 0], pos[i, 1] - rtl_dest[i, 1]) < RTL_REACHED_M
            ):
                nav_pos[i, 2] = math.nan
                rtl_stage[i] = RTL_DESCEND
        landing = m == LAND or (m == RTL and rtl_stage[i] == RTL_DESCEND)
        if landing and descent.profile[i] == DESCENT_INTERPOLATED:  # through the jerk-limited trajectory
            c = descent.columns[i]
            speed = interpolated_land_speed(
                pos[i, 2] - home[i, 2], p[c[D_ALT_FAST]], p[c[D_ALT_SLOW]], p[c[D_ALT_CRAWL]],
                p[c[D_SLOW_SPEED]], p[c[D_CRAWL_SPEED]], p[c[D_FAST_SPEED]], p[c[D_SPEED_CAP]],
                descent.range_max[i],
            )  # fmt: skip
            nav_vel[i, 2], nav_acc[i, 2] = jerk_limited_step(
                nav_vel[i, 2], nav_acc[i, 2], -speed, descent.accel_down[i], p[c[D_JERK]], dt
            )
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
        angle_law = angle_guided or m == STABILIZE or m == ALT_HOLD
        direct = angle_law and use_thrust[i]
        flying = armed[i] and not land_complete[i]
        speed_dn = p[columns[P_SPEED_DN]] / 100.0
        speed_up = p[columns[P_SPEED_UP]] / 100.0
        # a pos-vel-accel target's speed limits bound the position correction only, its velocity is added
        # after (AC_PosControl::input_pos_vel_accel_xy with limit_output false, as ModeGuided calls it)
        trajectory = guided and control[i] == CTRL_POS and nav_kind[i] == KIND_POSVEL
        vx, vy, vz = velocity_demand(
            pos[i], nav_pos[i], NO_VELOCITY if trajectory else nav_vel[i], p[columns[P_POSXY_P]],
            p[columns[P_POSZ_P]], p[columns[P_ACCEL]] / 100.0, p[columns[P_SPEED]] / 100.0, speed_up,
            speed_dn,
        )  # fmt: skip
        if trajectory:
            vx, vy, vz = vx + nav_vel[i, 0], vy + nav_vel[i, 1], vz + nav_vel[i, 2]
        if climb_cap[i] < vz:  # a persona's upward limit (+inf: none)
            vz = climb_cap[i]
        ax = ay = az = 0.0
        if angle_law:
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
            az += 0.0 if angle_law else nav_acc[i, 2]
        if angle_law or not flying:
            integrator[i, 0] = integrator[i, 1] = 0.0
        if not flying or direct:
            integrator[i, 2] = 0.0
        if angle_law:
            for k in range(4):  # element by element: an array copy would compile numba's shape-error text
                quat_sp[i, k] = angle_quat[i, k]
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
