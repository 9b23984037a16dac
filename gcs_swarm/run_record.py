"""The run record: what the ground station believed and commanded, one CSV row per vehicle per control tick.

Columns (ENU metres, rad, m/s^2): t, vehicle, phase, x, y, z, vx, vy, vz, roll, pitch, yaw (measured, from
telemetry), ref_x, ref_y, ref_z, ref_vx, ref_vy, ref_vz (reference generator, spec 8), slot_x, slot_y, slot_z,
fx, fy, fz (total field force, spec 4), roll_d, pitch_d, yaw_d, thrust_acc, thrust (normalised), emergency,
active, psi_l. Flushed every second of vehicle time so a killed ground station leaves a readable record.
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

COLUMNS = (
    "t,vehicle,phase,x,y,z,vx,vy,vz,roll,pitch,yaw,ref_x,ref_y,ref_z,ref_vx,ref_vy,ref_vz,"
    "slot_x,slot_y,slot_z,fx,fy,fz,roll_d,pitch_d,yaw_d,thrust_acc,thrust,emergency,active,psi_l"
).split(",")


class RunRecord:
    """Appends tick rows to `path` (CSV with a header)."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self._file = path.open("w", newline="")
        self._writer = csv.writer(self._file)
        self._writer.writerow(COLUMNS)
        self._last_flush_t = 0.0

    def write_tick(
        self,
        t: float,
        phase: str,
        pos: np.ndarray,
        vel: np.ndarray,
        att: np.ndarray,
        command: object,
        thrust: np.ndarray,
        active: np.ndarray,
    ) -> None:
        """One row per vehicle. `command` is a guidance Command (arrays of shape (N,...) as attributes)."""
        c = command
        n = pos.shape[0]
        block = np.column_stack(
            [
                pos,
                vel,
                att,
                c.ref_pos,  # type: ignore[attr-defined]
                c.ref_vel,  # type: ignore[attr-defined]
                c.slots,  # type: ignore[attr-defined]
                c.field_force,  # type: ignore[attr-defined]
                c.roll_d,  # type: ignore[attr-defined]
                c.pitch_d,  # type: ignore[attr-defined]
                c.yaw_d,  # type: ignore[attr-defined]
                c.thrust_acc,  # type: ignore[attr-defined]
                thrust,
            ]
        )
        emergency = np.asarray(c.emergency, dtype=int)  # type: ignore[attr-defined]
        psi_l = float(c.psi_leader)  # type: ignore[attr-defined]
        for i in range(n):
            self._writer.writerow(
                [
                    f"{t:.3f}",
                    i,
                    phase,
                    *(f"{v:.6g}" for v in block[i]),
                    int(emergency[i]),
                    int(active[i]),
                    f"{psi_l:.6g}",
                ]
            )
        if t - self._last_flush_t >= 1.0:
            self._file.flush()
            self._last_flush_t = t

    def close(self) -> None:
        self._file.close()
