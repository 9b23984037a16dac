"""What each vehicle can fly, measured from its own telemetry during the flight [add] (docs/iaapf-smc-spec.md
section 6b): its horizontal drag, and from it the fastest it can fly at a share of its tilt limit, so that the
leader never cruises faster than its slowest follower can follow (`leader_cap`).

A formation is as fast as its slowest member. The mission cannot know each airframe's drag (real PX4 SIH tops
out at 6.9 m/s at the 35 deg tilt limit, under the leader's 10 m/s cap; sitl-sim's airframe at 24.7 m/s), but
the telemetry tells it. In level flight the thrust's horizontal part and the drag make the acceleration:

    a_xy = U_xy - c (v_xy - w),    U_xy = (a_z + g) axis_xy / axis_z,    axis = R(roll, pitch, yaw) e3

(inversion.thrust_vector's axis; c 1/s the linear drag per unit mass, w m/s the wind, taken as steady over the
estimate's memory). The residual r = a_xy - U_xy = -c v_xy + c w is linear in theta = (c, c w_x, c w_y): each
vehicle's theta is the least-squares fit over samples every `sample_s` (a from the change of velocity over the
sample, U and v the means of both ends), older samples forgotten with time constant `memory_s`. The fit is
trusted once the velocities it saw spread by `min_spread_m_s` (the determinant of the normal equations is the
weight cubed times that spread squared, so c is then well defined) and c > 0.

At a share f (`tilt_share`) of the tilt limit theta_max the drag across the heading u is balanced first, the
rest drives along it:

    v_cap(u) = w.u + sqrt((f g tan theta_max)^2 - (c w_perp)^2) / c

and the leader's cap is the smallest v_cap of the followers the estimate trusts, along the leader's heading.
The remaining (1 - f) of the tilt is what a follower has to catch up and correct.

The same v_cap at the share `own_tilt_share`, along each vehicle's own heading (`top_speeds` with one heading
per vehicle), caps that vehicle's own reference (fleet_controller), so that no reference asks for a speed its
vehicle cannot fly with thrust to spare for steering.

Until a follower's drag has been `measured` (`ever_measured`), the leader flies no faster than lets that
follower's slot run ahead of it by more than `start_lead_m_s` along psi_L, never under a floor that lets
psi_L turn (`start_cap`): a leader that knows nothing yet of its followers would otherwise cruise away at its
own top speed from a follower still hovering. (The fleet controller does not apply it to a formation that
starts in flight.)

The leader's acceleration is bounded the same way (`AccelBudget`, `within_budget`): a follower keeping its
slot must make the leader's horizontal acceleration a at the leader's velocity v, which takes the thrust
U_xy = a + c (v - w); the leader's reference acceleration is held inside the disc

    |a + c (v - w)| <= f_a g tan(theta_max)

of its slowest follower (the one whose v_cap sets the speed cap), f_a = `accel_tilt_share` (1 by default:
the tilt limit itself; at f_a = f the leader could neither speed up nor turn at v_cap, measured worse on a
slow airframe, docs/metrics.md). Braking gets the drag besides.
Shapes: N vehicles; ENU.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from gcs_swarm.guidance.inversion import thrust_vector
from gcs_swarm.guidance.params import CapabilityParams
from swarm_common.jit import kernel


class AccelBudget(NamedTuple):
    """One vehicle's horizontal acceleration budget (module docstring): |a + drag v - drag_wind| <= budget."""

    drag: float  # 1/s, c
    drag_wind_x: float  # m/s^2, c w_x (ENU)
    drag_wind_y: float  # m/s^2, c w_y
    budget: float  # m/s^2, f_a g tan(theta_max); inf: no budget


NO_BUDGET = AccelBudget(0.0, 0.0, 0.0, math.inf)


@kernel
def within_budget(
    a_x: float, a_y: float, v_x: float, v_y: float, drag: float, drag_wind_x: float, drag_wind_y: float,
    budget: float,
) -> tuple[float, float]:  # fmt: skip
    """The horizontal acceleration (a_x, a_y) m/s^2 of a reference moving at (v_x, v_y) m/s, brought into
    the disc |a + drag v - drag_wind| <= budget (`AccelBudget`; spec 6b): shortened along its own direction
    to the disc's edge, so the reference is not pushed sideways; when even a = 0 lies outside (the reference
    faster than the follower can fly), moved straight toward the disc's centre drag_wind - drag v, which
    brakes it. Unchanged inside the disc or when budget is inf."""
    if not budget < math.inf:
        return a_x, a_y
    centre_x, centre_y = drag_wind_x - drag * v_x, drag_wind_y - drag * v_y
    off_x, off_y = a_x - centre_x, a_y - centre_y
    size = np.hypot(off_x, off_y)
    if size <= budget:
        return a_x, a_y
    centre_sq = centre_x * centre_x + centre_y * centre_y
    if centre_sq <= budget * budget:  # k a on the edge: k^2 |a|^2 - 2 k a.C + |C|^2 - budget^2 = 0
        along = a_x * centre_x + a_y * centre_y
        a_sq = a_x * a_x + a_y * a_y
        k = (along + math.sqrt(along * along - a_sq * (centre_sq - budget * budget))) / a_sq
        return k * a_x, k * a_y
    scale = budget / size
    return centre_x + off_x * scale, centre_y + off_y * scale


class SpeedEnvelope:
    """Per-vehicle drag fits from telemetry (module docstring) and the leader cap they give."""

    def __init__(self, n: int, params: CapabilityParams, tilt_max: float, g: float) -> None:
        """`n` vehicles, `tilt_max` rad the tilt limit, g m/s^2."""
        self.params = params
        self.g = g
        self.tilt_max = tilt_max
        self.thrust_xy = params.tilt_share * g * math.tan(tilt_max)  # m/s^2, f g tan(theta_max)
        self.accel_xy = params.accel_tilt_share * g * math.tan(tilt_max)  # m/s^2, f_a g tan(theta_max)
        self.normal = np.zeros((n, 3, 3))  # forgotten sums of the normal equations (A^T A)
        self.moment = np.zeros((n, 3))  # ... and A^T r
        self.weight = np.zeros(n)  # forgotten sample count
        self.v_sum = np.zeros((n, 2))  # forgotten sums of v_xy and |v_xy|^2, for the spread
        self.v2_sum = np.zeros(n)
        self.last_t = math.nan
        self.last_vel = np.full((n, 3), np.nan)
        self.last_axis = np.full((n, 3), np.nan)
        self.theta = np.full((n, 3), np.nan)  # (c 1/s, c w_x, c w_y m/s^2); NaN until trusted
        # (N,) bool: the fit has been `measured` at some time (it may fall back under min_spread_m_s in a long
        # steady cruise, when the samples that spread it are forgotten)
        self.ever_measured = np.zeros(n, dtype=bool)

    def update(self, t: float, vel: np.ndarray, att: np.ndarray, active: np.ndarray) -> bool:
        """Take a sample at t s from measured vel (N, 3) m/s and att (N, 3) roll, pitch, yaw rad of the
        (N,) bool `active` vehicles if `sample_s` has passed since the last; True when the fits changed."""
        if t - self.last_t < self.params.sample_s:
            return False
        axis = thrust_vector(att[:, 0], att[:, 1], att[:, 2], np.ones(len(att)))
        dt = t - self.last_t
        fresh = active & np.isfinite(self.last_vel).all(axis=1) & np.isfinite(vel).all(axis=1)
        fresh &= np.isfinite(axis).all(axis=1) & np.isfinite(self.last_axis).all(axis=1)
        changed = False
        if fresh.any() and dt > 0.0:
            accel = (vel[fresh] - self.last_vel[fresh]) / dt
            mean_axis = 0.5 * (axis[fresh] + self.last_axis[fresh])
            v = 0.5 * (vel[fresh, :2] + self.last_vel[fresh, :2])
            thrust_xy = (accel[:, 2:3] + self.g) * mean_axis[:, :2] / mean_axis[:, 2:3]
            r = accel[:, :2] - thrust_xy
            keep = math.exp(-dt / self.params.memory_s)
            self.normal *= keep
            self.moment *= keep
            self.weight *= keep
            self.v_sum *= keep
            self.v2_sum *= keep
            rows = np.zeros((len(v), 2, 3))  # the sample's two rows of A: (-v_x, 1, 0) and (-v_y, 0, 1)
            rows[:, :, 0] = -v
            rows[:, 0, 1] = rows[:, 1, 2] = 1.0
            self.normal[fresh] += np.einsum("kai,kaj->kij", rows, rows)
            self.moment[fresh] += np.einsum("kai,ka->ki", rows, r)
            self.weight[fresh] += 1.0
            self.v_sum[fresh] += v
            self.v2_sum[fresh] += np.einsum("ka,ka->k", v, v)
            changed = self._solve()
        self.last_t = t
        self.last_vel = np.where(active[:, None], vel, np.nan)
        self.last_axis = np.where(active[:, None], axis, np.nan)
        return changed

    def spread(self) -> np.ndarray:
        """(N,) m/s: the RMS spread of the horizontal velocities in each fit (0 before any sample)."""
        w = np.maximum(self.weight, 1e-12)
        mean = self.v_sum / w[:, None]
        return np.sqrt(np.maximum(self.v2_sum / w - np.einsum("ka,ka->k", mean, mean), 0.0))

    @property
    def measured(self) -> np.ndarray:
        """(N,) bool: the fit has min_samples and velocities spread by min_spread_m_s (whether or not it
        found a drag)."""
        return (self.weight >= self.params.min_samples) & (self.spread() >= self.params.min_spread_m_s)

    def _solve(self) -> bool:
        ready = self.measured
        self.ever_measured |= ready
        theta = np.full_like(self.theta, np.nan)
        if ready.any():
            theta[ready] = np.linalg.solve(self.normal[ready], self.moment[ready][..., None])[..., 0]
        theta[~(theta[:, 0] > 0.0)] = np.nan  # no drag measured: no cap from this vehicle
        changed = not np.array_equal(theta, self.theta, equal_nan=True)
        self.theta = theta
        return changed

    @property
    def drag(self) -> np.ndarray:
        """(N,) 1/s: the fitted linear drag per unit mass c (NaN where not trusted)."""
        return self.theta[:, 0]

    def top_speeds(self, heading: float | np.ndarray, tilt_share: float | None = None) -> np.ndarray:
        """(N,) m/s: v_cap along the unit heading (rad, ENU; one for all, or (N,) one per vehicle) at
        `tilt_share` of the tilt limit (None: params.tilt_share; module docstring); NaN where the fit is not
        trusted, 0 where the wind across takes the whole share."""
        c, cw = self.theta[:, 0], self.theta[:, 1:]
        thrust = self.thrust_xy if tilt_share is None else tilt_share * self.g * math.tan(self.tilt_max)
        u_x, u_y = np.cos(heading), np.sin(heading)
        along = cw[:, 0] * u_x + cw[:, 1] * u_y  # c (w . u)
        across = cw[:, 1] * u_x - cw[:, 0] * u_y  # c (w . u_perp), u_perp = (-u_y, u_x)
        drive = np.sqrt(np.maximum(thrust**2 - across**2, 0.0))
        return (along + drive) / c

    def slowest(self, heading: float, followers: np.ndarray) -> int | None:
        """The index of the (N,) bool `followers` with the smallest top speed along `heading` rad among those
        whose fit is trusted; None when none is."""
        speeds = np.where(followers, self.top_speeds(heading), np.nan)
        return None if np.isnan(speeds).all() else int(np.nanargmin(speeds))

    def accel_budget(self, heading: float, followers: np.ndarray) -> AccelBudget:
        """The leader's acceleration budget (module docstring): the disc of the slowest of the (N,) bool
        `followers` along `heading` rad (`slowest`); NO_BUDGET when no fit is trusted or accel_tilt_share is
        0."""
        row = self.slowest(heading, followers)
        if row is None or self.params.accel_tilt_share == 0:
            return NO_BUDGET
        c, cw_x, cw_y = (float(x) for x in self.theta[row])
        return AccelBudget(c, cw_x, cw_y, float(self.accel_xy))

    def start_cap(
        self, vel: np.ndarray, heading: float, slot_rate: np.ndarray, followers: np.ndarray, floor: float
    ) -> float:
        """m/s: the leader's cap until the drag of each of the (N,) bool `followers` has been `measured`
        (`ever_measured`), so that no such follower's slot runs ahead of it along `heading` rad by more than
        params.start_lead_m_s: its speed along the heading (vel (N, 3) m/s ENU) less its slot's own rate along
        it (`slot_rate` (N,) m/s, the slot's motion in the leader's frame, forward positive), plus
        start_lead_m_s, the smallest over those followers, at least `floor`; inf when every follower has been
        measured or the cap is off."""
        rows = followers & ~self.ever_measured & np.isfinite(vel[:, :2]).all(axis=1)
        if self.params.start_lead_m_s == 0 or not rows.any():
            return math.inf
        along = vel[rows, 0] * math.cos(heading) + vel[rows, 1] * math.sin(heading) - slot_rate[rows]
        return max(floor, float(along.min()) + self.params.start_lead_m_s)

    def leader_cap(self, heading: float, followers: np.ndarray) -> float:
        """m/s: the smallest top speed along `heading` rad of the (N,) bool `followers` whose fit is trusted;
        inf when none is."""
        speeds = self.top_speeds(heading)[followers]
        speeds = speeds[np.isfinite(speeds)]
        return float(max(speeds.min(), 0.0)) if len(speeds) else math.inf
