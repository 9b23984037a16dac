"""The run record: what the ground station believed and commanded, one CSV row per vehicle per control tick.

Columns (ENU metres, rad, m/s^2): t, vehicle, phase, x, y, z, vx, vy, vz, roll, pitch, yaw (measured, from
telemetry), ref_x, ref_y, ref_z, ref_vx, ref_vy, ref_vz (reference generator, spec 8), slot_x, slot_y, slot_z,
fx, fy, fz (total field force, spec 4), roll_d, pitch_d, yaw_d, thrust_acc, thrust (normalised), emergency,
active, psi_l. Each tick's rows go to a writer thread (swarm_common.background_writer) in batches of about
200 rows or 10 ticks and at least every second, so a killed ground station leaves a readable record and the
control loop never waits on the disk; from 200 vehicles on, the thread also formats them (1.2 ms of a tick).
"""

from __future__ import annotations

import csv
import functools
import io
from pathlib import Path
from typing import Any

import numpy as np

from swarm_common.background_writer import BackgroundWriter

COLUMNS = (
    "t,vehicle,phase,x,y,z,vx,vy,vz,roll,pitch,yaw,ref_x,ref_y,ref_z,ref_vx,ref_vy,ref_vz,"
    "slot_x,slot_y,slot_z,fx,fy,fz,roll_d,pitch_d,yaw_d,thrust_acc,thrust,emergency,active,psi_l"
).split(",")


class RunRecord:
    """Appends tick rows to `path`: CSV with a header, CRLF line ends (as Python's csv module writes them).

    Rows are formatted a tick at a time with printf-style formats ("%.6g" per number) and written in one
    call: the same text as csv.writer with f"{v:.6g}" fields, at a fraction of the per-value cost.
    """

    def __init__(self, path: Path) -> None:
        self.path = path
        self._writer = BackgroundWriter(path, "run record")
        header = io.StringIO()
        csv.writer(header).writerow(COLUMNS)
        self._writer.write(header.getvalue().encode())
        numbers = ",".join(["%.6g"] * _NUMERIC_COLUMNS)
        self._row = f"%.3f,%d,%s,{numbers},%d,%d,%.6g\r\n"  # t, vehicle, phase, numbers, flags, psi_l

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
        c: Any = command  # duck-typed: a Command or anything with its attributes
        block = np.column_stack(
            [
                pos,
                vel,
                att,
                c.ref_pos,
                c.ref_vel,
                c.slots,
                c.field_force,
                c.roll_d,
                c.pitch_d,
                c.yaw_d,
                c.thrust_acc,
                thrust,
            ]
        )
        if block.shape[1] != _NUMERIC_COLUMNS:
            raise ValueError(f"a record row needs {_NUMERIC_COLUMNS} numbers, got {block.shape[1]}")
        rows = block.tolist()
        emergency = np.asarray(c.emergency, dtype=int).tolist()
        flags = np.asarray(active, dtype=int).tolist()
        psi_l = float(c.psi_leader)
        row, field = self._row, _csv_field(phase)

        def render() -> bytes:  # from the copies above (in the writer's thread at 200 vehicles and more)
            return "".join(
                row % (t, i, field, *values, emergency[i], flags[i], psi_l) for i, values in enumerate(rows)
            ).encode()

        self._writer.write_rows(render, len(rows))

    def close(self) -> None:
        """Write every row and close the file (idempotent)."""
        self._writer.close()


_NUMERIC_COLUMNS = len(COLUMNS) - 6  # all but t, vehicle, phase, emergency, active, psi_l


@functools.lru_cache(maxsize=32)
def _csv_field(text: str) -> str:
    """`text` as csv.writer writes a field (quoted when it holds a comma, quote or line break)."""
    out = io.StringIO()
    csv.writer(out).writerow([text, ""])  # the record's own dialect; then drop ",\r\n"
    return out.getvalue()[:-3]
