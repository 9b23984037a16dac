"""FleetController.tick's steps 1-7 with the per-vehicle work compiled (field_kernels, tick_kernels): a
handful of kernel calls and the tick's transcendental functions in numpy, instead of about 900 small numpy
calls. The same bits as the numpy steps in fleet_controller.py (tests/gcs_swarm/guidance/test_tick_replay.py
flies both through whole recorded flights and compares every output and every internal state byte for byte).

Every numpy function here (cos, sin, arctan2, arcsin, the powers) is called on the
very array the numpy steps call it on, same values and same memory layout, so its SIMD results are the same.
A position controller other than the SMC (the PID, or any PositionController) is called as it is.

Importing this module requires numba (extra "fast"); fleet_controller falls back to the numpy steps without
it.
`warm_up` compiles or loads every kernel once (numba's cache), so no tick waits for the JIT.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from gcs_swarm.guidance import field_kernels as fk
from gcs_swarm.guidance import tick_kernels as tk
from gcs_swarm.guidance.attitude_slew import TiltSlew
from gcs_swarm.guidance.controller import PositionController
from gcs_swarm.guidance.degradation_kernels import stale_verdict
from gcs_swarm.guidance.failsafe_speed import _brake_table
from gcs_swarm.guidance.params import (
    DeadGcsParams,
    FieldParams,
    Limits,
    ReferenceParams,
    SeparationParams,
    SMCParams,
)
from gcs_swarm.guidance.reference import ReferenceGenerator, paper_literal_reference
from gcs_swarm.guidance.separation import CLOSING_MARGIN_M, CLOSING_RANGE_MAX_M
from gcs_swarm.guidance.smc import SMCController, _per_axis


class FleetState(Protocol):
    """What the compiled steps read and update of their FleetController (fleet_controller.py documents each;
    arrays have one row per vehicle). A Protocol, so that this module need not import fleet_controller,
    which imports it."""

    n: int
    leader: int
    is_leader: np.ndarray
    offsets: np.ndarray
    follower_targets: np.ndarray | None
    field: FieldParams
    separation: SeparationParams
    reference: ReferenceParams
    limits: Limits
    dead_gcs: DeadGcsParams | None
    generator: ReferenceGenerator
    position_controller: PositionController
    slew: TiltSlew
    thrust_mode: str
    g: float
    d_g: float
    d_max: float
    closing_accel: float
    v_xy_cap: np.ndarray
    speed_scale: float
    spacing_scale: float
    last_pos: np.ndarray
    last_vel: np.ndarray

    def speed_caps(self) -> np.ndarray: ...


class WarmUpController(Protocol):
    """The two calls warm_up makes on a controller (FleetController.reset and .tick)."""

    def reset(self, pos: np.ndarray, vel: np.ndarray, yaw: np.ndarray) -> None: ...

    def tick(
        self,
        t: float,
        pos: np.ndarray,
        vel: np.ndarray,
        att: np.ndarray,
        obstacles_c: np.ndarray,
        obstacles_r: np.ndarray,
        active: np.ndarray,
    ) -> object: ...


NO_ROWS = np.zeros((0, 3))
NO_VALUES = np.zeros(0)


@dataclass(frozen=True)
class TickOutputs:
    """What one compiled tick computed: the fields of fleet_controller.Command but the leader's and those
    Command works out itself (clearance, collision)."""

    roll_d: np.ndarray
    pitch_d: np.ndarray
    yaw_d: np.ndarray
    thrust_acc: np.ndarray
    ref_pos: np.ndarray
    ref_vel: np.ndarray
    ref_acc: np.ndarray
    field_force: np.ndarray
    slots: np.ndarray
    u: np.ndarray
    emergency: np.ndarray


def _reference_config(gen: ReferenceGenerator) -> np.ndarray:
    """tick_kernels.reference_step's `config` from the generator's parameters."""
    p: ReferenceParams = gen.params
    lim: Limits = gen.limits
    return np.array(
        [
            gen.gain, lim.v_z, p.stop_accel, p.k_v, p.jerk_max, float(gen.z_min is not None),
            0.0 if gen.z_min is None else gen.z_min, p.jerk_max_z, lim.a_z, p.tau_v, gen.a_xy_max,
            gen.a_xy_evasive, float(max(p.evasive_jerk_max, p.jerk_max)),
            float(max(p.evasive_jerk_max, p.jerk_max_z)),
        ],
        dtype=float,
    )  # fmt: skip


def _smc_config(pc: SMCController) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """tick_kernels.smc_output's `gains` (5, 3) and `config`, and the exponents xi1, xi2 (3,) per axis."""
    params: SMCParams = pc.params
    gains = np.array([_per_axis(params, name) for name in ("c1", "k1", "k2", "k3")] + [pc.k_d])
    lim = pc.limits
    config = np.array(
        [
            params.boundary_layer, pc.g, params.drag_adaptation, params.drag_max, float(lim is not None),
            float(np.tan(lim.tilt_max)) if lim else 0.0, lim.uz_min_g * pc.g if lim else 0.0,
            lim.thrust_max_g * pc.g if lim else 0.0, params.xy.disturbance_max, params.z.disturbance_max,
            float(pc.k_d.any()),
        ],
        dtype=float,
    )  # fmt: skip
    return gains, config, _per_axis(params, "xi1"), _per_axis(params, "xi2")


class CompiledTick:
    """The compiled steps for one FleetController; constants derived from its parameters are rebuilt when a
    parameter object is replaced (they are frozen dataclasses)."""

    def __init__(self) -> None:
        self._key: tuple[object, ...] = ()
        self._reference = NO_VALUES
        self._smc: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None = None
        self._failsafe: tuple[np.ndarray, np.ndarray] | None = None
        self._trig = (0.0, 0.0)

    def _constants(self, ctl: FleetState) -> None:
        pc = ctl.position_controller
        key = (
            ctl.generator.params,
            ctl.generator.limits,
            ctl.limits,
            pc,
            getattr(pc, "params", None),
            ctl.dead_gcs,
        )
        if len(key) == len(self._key) and all(a is b for a, b in zip(key, self._key, strict=True)):
            return
        self._key = key
        self._reference = _reference_config(ctl.generator)
        self._smc = _smc_config(pc) if type(pc) is SMCController else None
        fs = ctl.dead_gcs
        if fs is not None and fs.speed_scheduling:
            speeds, distances = _brake_table(float(fs.brake_accel or 0.0), float(fs.brake_jerk or 0.0))
            self._failsafe = (speeds * float(fs.failsafe_timeout_s or 0.0) + distances, speeds)
        else:
            self._failsafe = None
        self._trig = (float(np.tan(ctl.limits.tilt_max)), float(np.cos(ctl.limits.tilt_max)))

    def __call__(
        self,
        ctl: FleetState,
        heard: np.ndarray,
        goal: np.ndarray,
        dt: float,
        pos: np.ndarray,
        vel: np.ndarray,
        att: np.ndarray,
        obs_c: np.ndarray,
        obs_r: np.ndarray,
        active: np.ndarray,
    ) -> TickOutputs:
        """Steps 1-7 (FleetController.tick after the leader's goal and heading) from the leader state each
        vehicle heard (N, 11) and the tick's checked inputs; updates the controller's state as the numpy steps
        do."""
        self._constants(ctl)
        n = ctl.n
        fp, ref, gen = ctl.field, ctl.reference, ctl.generator
        pos_c, vel_c = np.ascontiguousarray(pos), np.ascontiguousarray(vel)
        centres, radii = np.ascontiguousarray(obs_c), np.ascontiguousarray(obs_r)
        psi_l = heard[:, 6]
        follower = NO_ROWS if ctl.follower_targets is None else ctl.follower_targets
        targets, v_ff, a_ff, dest = tk.formation_targets(
            heard, np.cos(psi_l), np.sin(psi_l), np.ascontiguousarray(ctl.offsets), float(ctl.spacing_scale),
            centres, radii, float(ref.slot_margin), int(ctl.leader), np.ascontiguousarray(goal),
            np.ascontiguousarray(follower),
        )  # fmt: skip
        literal = ref.paper_literal & ~ctl.is_leader
        if ref.paper_literal:
            gen.reset_rows(literal & active, pos, vel)

        # Step 6 (leash) then step 2: the field at the reference points
        rows = np.ascontiguousarray(active)
        ahead = tk.leash_and_lookahead(gen.p, gen.v, pos_c, rows, float(ref.leash), float(ref.brake_accel))
        p_r = gen.p
        known = np.asarray(np.isfinite(ctl.last_pos).all(axis=1))
        iaapf = fp.method == "iaapf"
        vehicle, l_obs, n_o, n_g, rho = fk.obstacle_pairs(
            p_r, ahead, dest, centres, radii, float(fp.l0), float(fp.l_min)
        )
        rho_n = rho**fp.n if iaapf else rho  # iaapf.adaptive_repulsion_scales
        f_obs = fk.obstacle_forces(
            n, vehicle, l_obs, n_o, n_g, rho, rho_n, iaapf, float(fp.k_rep), float(fp.l0), float(fp.n),
            float(fp.rho_eps), float(fp.circulation), float(fp.obstacle_vertical),
        )  # fmt: skip
        wide = ctl.spacing_scale
        sep = ctl.separation
        d_emg, s_s = (sep.d_emg, sep.s_s) if wide == 1.0 else (sep.d_emg * wide, sep.s_s * wide)
        d_max = ctl.d_max * wide
        pairs, e_ji, l_uav = fk.uav_pairs(
            p_r,
            ctl.last_pos,
            ctl.last_vel,
            gen.v,
            known,
            float(d_max),
            float(fp.l_min),
            float(ref.brake_accel),
        )
        l_pow = l_uav ** (fp.n_uav - 2.0)  # separation.pair_force_scale
        f_uav, emergency = fk.uav_forces(
            n, pairs, e_ji, l_uav, l_pow, ctl.last_vel, float(fp.k_uav), float(fp.n_uav), float(d_max),
            sep.mode == "formula", float(min(d_emg, d_max)), float(sep.a_e), float(s_s),
        )  # fmt: skip
        f_att = fk.attraction(p_r, targets, float(fp.k_att), float(ctl.d_g), iaapf)
        force = f_att + f_obs + f_uav

        # Steps 3-5
        speed_cap = ctl.speed_caps()
        if ctl.closing_accel > 0.0:
            accel = ctl.closing_accel
            gap = d_emg if sep.mode == "constant" else s_s
            reach = gap + CLOSING_MARGIN_M + (2.0 * float(np.max(ctl.v_xy_cap))) ** 2 / (2.0 * accel)
            caps = fk.closing_speed_caps(
                ctl.last_pos,
                ctl.last_vel,
                known,
                float(gap),
                float(accel),
                float(min(reach, CLOSING_RANGE_MAX_M)),
            )
            speed_cap = np.minimum(speed_cap, caps)
        if self._failsafe is not None:
            assert ctl.dead_gcs is not None
            total, speeds = self._failsafe
            caps = fk.failsafe_speed_caps(
                pos_c, vel_c, centres, radii, float(ctl.dead_gcs.clearance), total, speeds
            )
            speed_cap = np.minimum(speed_cap, caps)
        x_d, xd_dot = gen.p, gen.v
        xd_ddot, gen.p, gen.v = tk.reference_step(
            x_d,
            xd_dot,
            gen.a,
            force,
            v_ff,
            a_ff,
            targets,
            speed_cap,
            rows,
            emergency,
            float(dt),
            self._reference,
        )
        gen.a = xd_ddot
        if ref.paper_literal:
            lit = paper_literal_reference(targets, v_ff, f_obs + f_uav, fp.k_att, fp.l0)
            for arr, lit_arr in zip((x_d, xd_dot, xd_ddot), lit, strict=True):
                arr[literal] = lit_arr[literal]

        # Step 7: position control, inversion, tilt slew
        u = self._smc_step(ctl, x_d, xd_dot, xd_ddot, pos_c, vel_c, dt)
        if u is None:
            u = ctl.position_controller(x_d, xd_dot, xd_ddot, pos, vel, dt)
        lim, g = ctl.limits, ctl.g
        tan_tilt, cos_tilt = self._trig
        ul, norm, pitch_num, roll_arg = tk.inversion_terms(
            np.ascontiguousarray(u), np.cos(att[:, 2]), np.sin(att[:, 2]), float(lim.uz_min_g * g), tan_tilt
        )
        pitch = np.arctan2(pitch_num, ul[:, 2])
        roll = np.arcsin(roll_arg)
        tilt_cos = np.cos(att[:, 0]) * np.cos(att[:, 1]) if ctl.thrust_mode == "measured" else NO_VALUES
        slew = ctl.slew
        roll_cmd, pitch_cmd, thrust, u_out, slew.roll, slew.pitch = tk.commands(
            ul, norm, roll, pitch, tilt_cos, cos_tilt, float(lim.thrust_max_g * g), slew.roll, slew.pitch,
            float(slew.rate_max), float(dt), rows,
        )  # fmt: skip
        off = ~active
        yaw = np.array(psi_l, dtype=float)
        yaw[off] = np.nan
        return TickOutputs(
            roll_d=roll_cmd, pitch_d=pitch_cmd, yaw_d=yaw, thrust_acc=thrust, ref_pos=x_d, ref_vel=xd_dot,
            ref_acc=xd_ddot, field_force=force, slots=targets, u=u_out, emergency=emergency & active,
        )  # fmt: skip

    def _smc_step(
        self,
        ctl: FleetState,
        x_d: np.ndarray,
        xd_dot: np.ndarray,
        xd_ddot: np.ndarray,
        pos: np.ndarray,
        vel: np.ndarray,
        dt: float,
    ) -> np.ndarray | None:
        """SMCController.__call__ compiled (its s, c_hat, d_hat updated); None for another controller."""
        if self._smc is None:
            return None
        pc = ctl.position_controller
        assert isinstance(pc, SMCController)
        gains, config, xi1, xi2 = self._smc
        n = len(pos)
        if pc.params.drag_adaptation > 0.0 and pc.c_hat.shape != (n,):
            pc.c_hat = np.zeros(n)
        if pc.k_d.any() and pc.d_hat.shape != (n, 3):
            if len(pc.d_hat):
                raise ValueError(f"SMCController was reset for {len(pc.d_hat)} vehicles, got {n}")
            pc.d_hat = np.zeros((n, 3))
        e1, pc.s, abs_s = tk.smc_sliding(x_d, xd_dot, pos, vel, gains[0])
        c_hat = pc.c_hat if pc.c_hat.shape == (n,) else np.zeros(n)
        d_hat = pc.d_hat if pc.d_hat.shape == (n, 3) else np.zeros((n, 3))
        u, c_next, d_next = tk.smc_output(
            e1, pc.s, abs_s**xi1, abs_s**xi2, xd_ddot, vel, gains, c_hat, d_hat, float(dt), config
        )
        if pc.params.drag_adaptation > 0.0:
            pc.c_hat = c_next
        if pc.k_d.any():
            pc.d_hat = d_next
        return u


def warm_up(make_controller: Callable[..., WarmUpController]) -> None:
    """Call every kernel once on a small fleet (compiles them, or loads them from numba's cache: about 0.1 s),
    so that no tick of a flight waits for the JIT. make_controller: FleetController's constructor."""
    offsets = np.array([[0.0, 0.0, 0.0], [-5.0, 2.0, 0.0], [-5.0, -2.0, 0.0]])
    pos = offsets + np.array([0.0, 0.0, 10.0])
    for mode in ("constant", "formula"):
        ctl = make_controller(
            3, 0, offsets, np.array([[100.0, 0.0, 10.0]]), separation=SeparationParams(mode=mode), z_min=1.0
        )
        ctl.reset(pos, np.zeros((3, 3)), np.zeros(3))
        ctl.tick(
            0.0, pos, np.ones((3, 3)), np.zeros((3, 3)), pos[:1] + 3.0, np.ones(1), np.ones(3, dtype=bool)
        )
    table = np.array(
        [0.0, 1.0]
    )  # the failsafe speed scheduling's kernel (its real table takes 0.3 s to build, 1.1 s without numba)
    fk.failsafe_speed_caps(pos, np.ones((3, 3)), pos[:1] + 3.0, np.ones(1), 1.0, table, table)
    fk.neighbour_pairs(np.zeros((fk.DENSE_PAIRS_MAX, 3)), np.zeros((2, 3)), 1.0, True)  # the hash grid's path
    alive = np.ones(3, dtype=bool)  # the stale-telemetry rule (degradation.StaleTelemetryMonitor.assess)
    stale_verdict(np.zeros(3), alive, ~alive, pos, np.ones((3, 3)), 0, 1.0, 0.3)
