"""Compiled and interpreted guidance fly the same: a FleetController flown on a synthetic scene in this
process (numba-compiled kernels) and in a subprocess with NUMBA_DISABLE_JIT=1 (the same kernels run as plain
Python) gives the same commands, bit for bit.

The scene: a leader and four followers in a V, two obstacles beside and across the path, a point-mass plant
driven by the commands (so any difference would grow), a stretch of degraded flight (wider spacing), a
vehicle that drops out and comes back; once with the constant and once with the formula separation mode.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from gcs_swarm.guidance.fleet_controller import FleetController
from gcs_swarm.guidance.formation import formation_offsets
from gcs_swarm.guidance.inversion import thrust_vector
from gcs_swarm.guidance.params import G, SeparationParams
from tests.gcs_swarm.guidance.interpreted import interpreted_arrays

TICKS = 300
DT = 0.02


def fly(mode: str) -> np.ndarray:
    """(TICKS, N, 7) roll, pitch, yaw, thrust and the reference position of every tick of one flight."""
    n = 5
    offsets = np.zeros((n, 3))
    offsets[1:] = formation_offsets("v", n - 1, 8.0)
    ctl = FleetController(
        n, 0, offsets, np.array([[150.0, 20.0, 15.0]]), separation=SeparationParams(mode=mode), z_min=2.0
    )
    pos = np.array(
        [[0.0, 0.0, 12.0], [-6.0, 5.0, 12.0], [-5.0, -6.0, 11.0], [-12.0, 11.0, 13.0], [-11.0, -12.0, 12.0]]
    )
    vel = np.zeros((n, 3))
    att = np.zeros((n, 3))
    centres, radii = np.array([[40.0, 4.0, 12.0], [80.0, 25.0, 10.0]]), np.array([6.0, 8.0])
    ctl.reset(pos, vel, att[:, 2])
    out = np.empty((TICKS, n, 7))
    for k in range(TICKS):
        active = np.ones(n, dtype=bool)
        if 120 <= k < 140:
            active[3] = False  # drops out and comes back
        ctl.set_degraded(0.6, 1.4) if 60 <= k < 100 else ctl.set_degraded(1.0, 1.0)
        cmd = ctl.tick(k * DT, pos, vel, att, centres, radii, active)
        out[k, :, 0], out[k, :, 1], out[k, :, 2], out[k, :, 3] = (
            cmd.roll_d,
            cmd.pitch_d,
            cmd.yaw_d,
            cmd.thrust_acc,
        )
        out[k, :, 4:] = cmd.ref_pos
        roll = np.where(active, cmd.roll_d, att[:, 0])
        pitch = np.where(active, cmd.pitch_d, att[:, 1])
        yaw = np.where(active, cmd.yaw_d, att[:, 2])
        thrust = np.where(active, cmd.thrust_acc, G)
        acc = thrust_vector(roll, pitch, yaw, thrust) - np.array([0.0, 0.0, G]) - 0.25 * vel
        vel = vel + acc * DT
        pos = pos + vel * DT
        att = np.column_stack([roll, pitch, yaw])
    return out


def test_compiled_and_interpreted_guidance_give_the_same_commands(tmp_path: Path) -> None:
    """Exactly the same bits: numba's and CPython's sqrt and hypot are both correctly rounded; the cos, sin,
    arctan2 and arcsin between the kernels are numpy's, called on the same arrays in both processes; and the
    powers and atan2 inside kernels (the obstacle repulsion's rho^n, psi_L's heading_step) are libm's pow and
    atan2 in both, compiled or not."""
    compiled = {mode: fly(mode) for mode in ("constant", "formula")}
    every_mode = "{mode: fly(mode) for mode in ('constant', 'formula')}"
    module = "tests.gcs_swarm.guidance.test_interpreted_tick"
    interpreted = interpreted_arrays(module, every_mode, tmp_path / "interpreted.npz", 120)
    for mode, commands in compiled.items():
        assert np.isfinite(commands[:, [0, 1, 2, 4]]).sum() > 0.9 * commands[:, [0, 1, 2, 4]].size
        assert commands.tobytes() == interpreted[mode].tobytes(), mode
