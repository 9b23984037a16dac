"""The position-controller interface of the fleet controller (spec 7, step 7 of spec 8) and the factory that
builds the one a mission names (`control.controller`).

A position controller turns the reference the guidance computed and the measured state into the thrust
acceleration each vehicle should produce; `gcs_swarm.guidance.inversion` turns that into attitude and thrust.
To add a control law, implement `PositionController` (no subclassing needed: the match is structural), add its
name to `CONTROLLERS` and one branch to `make_position_controller`.
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np

from gcs_swarm.guidance.params import G, Limits, PIDParams, SMCParams
from gcs_swarm.guidance.pid import PIDController
from gcs_swarm.guidance.smc import SMCController

CONTROLLERS = ("smc", "pid")  # the names a mission's control.controller may take


@runtime_checkable
class PositionController(Protocol):
    """Position control of N vehicles at once, one row per vehicle, called once per control tick.

    Frames and units: every (N, 3) array is in the local ENU world frame (x east, y north, z up), positions in
    m, velocities in m/s, accelerations in m/s^2; `dt` in s.

    Call `controller(x_d, xd_dot, xd_ddot, x, v, dt) -> U`:
      x_d, xd_dot, xd_ddot  (N, 3) reference position, velocity and acceleration (the guidance's output);
      x, v                  (N, 3) measured position and velocity;
      dt                    s since the previous call (the nominal control period on the first call), for
                            controllers with internal state (integrators, estimates);
      U                     (N, 3) commanded thrust acceleration U/m in m/s^2, gravity included: a vehicle
                            hovering at its reference (x = x_d, v = xd_dot = 0, xd_ddot = 0) gets
                            U = (0, 0, g). Not yet limited: the spec 5 tilt and thrust limits are applied by
                            the inversion.
    Rows of vehicles without a finite state may come out non-finite; the caller does not send them.

    `reset(n)` forgets the internal state of all n vehicles (start of formation flight, resume);
    `reset_rows(rows)` that of the vehicles selected by the (N,) bool mask (a vehicle commanded again after
    a gap).
    """

    def reset(self, n: int) -> None: ...

    def reset_rows(self, rows: np.ndarray) -> None: ...

    def __call__(
        self,
        x_d: np.ndarray,
        xd_dot: np.ndarray,
        xd_ddot: np.ndarray,
        x: np.ndarray,
        v: np.ndarray,
        dt: float,
    ) -> np.ndarray: ...


def make_position_controller(
    name: str,
    smc: SMCParams | None = None,
    pid: PIDParams | None = None,
    limits: Limits | None = None,
    g: float = G,
) -> PositionController:
    """The controller called `name` (one of CONTROLLERS): "smc" the sliding-mode law of the paper
    (gcs_swarm.guidance.smc) with gains `smc`, whose estimates respect the spec 5 `limits`; "pid" the baseline
    (gcs_swarm.guidance.pid) with gains `pid`. None: the default gains and limits. ValueError for another
    name."""
    if name == "smc":
        return SMCController(smc or SMCParams(), g, limits or Limits())
    if name == "pid":
        return PIDController(pid or PIDParams(), g)
    raise ValueError(f"controller must be one of {CONTROLLERS}, not {name!r}")
