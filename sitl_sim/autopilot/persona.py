"""Which autopilot each simulated vehicle impersonates: the persona base class and the registry of personas.

The physics, the attitude controller and the shared outer loop (sitl_sim.autopilot.copter.Autopilot,
sitl_sim.autopilot.outer_loop) are the same for every vehicle. Whatever differs per autopilot is asked of the
vehicle's persona: its default ready delay and telemetry rates, its parameter table (names, encoding, the
mirrors of its parameters into the shared loop's columns), its HEARTBEAT, its pre-arm verdict, its rules
around each tick of the shared loop (failsafes, auto-disarm, takeoff limits), and its landing descent profile.
One module per persona: ArduCopter's in sitl_sim.autopilot.arducopter, PX4's in sitl_sim.autopilot.px4 (and
their MAVLink surfaces in sitl_sim.network.commands / .px4_commands, chosen by sitl_sim.network.surfaces).

A persona class answers the fleet-wide questions asked before the autopilot exists (class attributes and
class methods); an instance holds the persona's own state for its vehicles of one Autopilot (`rows`) and
plays its rules. The registry (sitl_sim.autopilot.registry) knows every persona by its `--autopilot` name and
refuses any other name: there is no silent default persona.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from sitl_sim.autopilot.outer_loop import DESCENT_TWO_SPEED
from sitl_sim.autopilot.params import ParamSpec, ParamTable


class Persona:
    """An autopilot's behaviour over the shared autopilot `ap`, for its vehicles `rows` (N,) bool.

    Subclasses set the class attributes and override the methods whose behaviour differs; the defaults here
    are "no rules of its own" (nothing before or after the shared loop, no parameters of its own).
    """

    name: ClassVar[str] = ""  # the `--autopilot` name
    ready_delay_s: ClassVar[float] = 0.0  # default simulated s from boot to the position estimate
    default_rates_hz: ClassVar[Mapping[int, float]] = {}  # MAVLink message id -> Hz on a new link (0: off)
    bytewise_params: ClassVar[bool] = False  # PARAM_VALUE integers bytewise (else as float values)
    shows_shared_params: ClassVar[bool] = True  # the shared (ArduCopter-named) table is its parameter surface
    reports_ekf_status: ClassVar[bool] = False  # sends ardupilotmega's EKF_STATUS_REPORT
    # the shared loop's landing descent (outer_loop.DESCENT_*) and, for DESCENT_INTERPOLATED, the parameters
    # it reads (outer_loop.Descent documents the order) and its two constants
    descent_profile: ClassVar[int] = DESCENT_TWO_SPEED
    descent_params: ClassVar[tuple[str, ...]] = ()
    descent_accel_down: ClassVar[float] = 0.0  # m/s^2
    descent_range_max: ClassVar[float] = 0.0  # m, the height a range finder measures up to
    # own parameter -> (the shared loop's column it drives, scale); shared columns hidden and held fixed
    # FENCE_TOTAL going to 0 erases the stored fence (ArduPilot SITL's old fence-point protocol, fence.Fences.
    # legacy_clears)
    legacy_fence_total: ClassVar[bool] = False
    # a guided position target outside an enabled fence is refused (ArduCopter ModeGuided::set_destination)
    guided_fence_check: ClassVar[bool] = False
    # whose mission protocol it speaks where they differ (sitl_sim.network.mission_protocol): "ardupilot" or
    # "px4"
    mission_protocol: ClassVar[str] = "ardupilot"
    mirrors: ClassVar[Mapping[str, tuple[str, float]]] = {}
    hidden_fixed: ClassVar[Mapping[str, float]] = {}

    def __init__(self, ap: Any, rows: np.ndarray) -> None:  # ap: the shared copter.Autopilot
        self.ap = ap
        self.rows = np.asarray(rows, dtype=bool)

    # --- before the fleet exists ----------------------------------------------------------------------------

    @classmethod
    def param_specs(cls, hover_fraction: float) -> tuple[ParamSpec, ...]:
        """The parameters of its own, beyond the shared table (hover_fraction: MOT_THST_HOVER's default)."""
        return ()

    @classmethod
    def shows(cls, spec: ParamSpec, own: tuple[ParamSpec, ...], shared: bool) -> bool:
        """Whether its vehicles list `spec` (one of its `own` parameters, or of the shared table when
        `shared`): its own parameters, the simulator's SIM_*, and the shared table when that is its
        surface."""
        return spec in own or spec.name.startswith("SIM_") or (shared and cls.shows_shared_params)

    @classmethod
    def configure(cls, table: ParamTable, rows: np.ndarray) -> None:
        """Its vehicles' hidden shared columns, from its own parameters (mirrors) or fixed (hidden_fixed)."""
        for name, (column, scale) in cls.mirrors.items():
            own = table.values[rows, table.column_index(name)]
            table.values[rows, table.column_index(column)] = own * scale
        for name, value in cls.hidden_fixed.items():
            table.values[rows, table.column_index(name)] = value

    @classmethod
    def parameter_set(cls, table: ParamTable, i: int, name: str) -> None:
        """Vehicle i's parameter `name` was set: a mirrored one drives its shared column at once."""
        if name in cls.mirrors:
            column, scale = cls.mirrors[name]
            table.values[i, table.column_index(column)] = table.value(i, name) * scale

    # --- over the fleet -------------------------------------------------------------------------------------

    def heartbeat(self, i: int) -> tuple[int, int, int, int]:
        """(autopilot, base_mode, custom_mode, system_status) of vehicle i's HEARTBEAT."""
        raise NotImplementedError

    def system_status(self, i: int, failsafe: bool) -> int:
        """Vehicle i's HEARTBEAT system_status, the same rule for both autopilots: EMERGENCY crashed, CRITICAL
        in a `failsafe`, BOOT while booting, then ACTIVE armed or STANDBY."""
        ap = self.ap
        if ap.state.crashed[i]:
            return int(mavlink2.MAV_STATE_EMERGENCY)
        if failsafe:
            return int(mavlink2.MAV_STATE_CRITICAL)
        if ap.t < ap.boot_end[i]:
            return int(mavlink2.MAV_STATE_BOOT)
        return int(mavlink2.MAV_STATE_ACTIVE if ap.armed[i] else mavlink2.MAV_STATE_STANDBY)

    def prearm_ok(self, i: int) -> bool:
        """SYS_STATUS's pre-arm check bit: vehicle i would arm now."""
        raise NotImplementedError

    def before_loop(self, t: float, dt: float) -> None:
        """Its rules before the shared loop's tick at simulated time t (s) covering dt (s)."""

    def after_loop(self, t: float, events: np.ndarray) -> None:
        """Its rules after the shared loop's tick; events (N,): the loop's outer_loop.EVENT_* per vehicle."""

    def rtl_destination(self, i: int) -> np.ndarray:
        """Where vehicle i's RTL, starting now, returns and lands (3,) ENU m: its home (no rally points)."""
        return np.asarray(self.ap.home[i].copy())

    def fence_breached(self, i: int, new: int, t: float) -> None:
        """Armed vehicle i newly breached its fences `new` (sitl_sim.autopilot.fence bits) at simulated
        time t: its autopilot's answer."""

    def fence_cleared(self, i: int) -> None:
        """Flying vehicle i is back inside every fence it breached."""
