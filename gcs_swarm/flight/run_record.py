"""The run record: what the ground station believed and commanded, one CSV row per vehicle per control tick.

Columns (ENU metres, rad, m/s^2): t, vehicle, phase, x, y, z, vx, vy, vz, roll, pitch, yaw (measured, from
telemetry), ref_x, ref_y, ref_z, ref_vx, ref_vy, ref_vz (reference generator, spec 8), slot_x, slot_y, slot_z,
fx, fy, fz (total field force, spec 4), roll_d, pitch_d, yaw_d, thrust_acc, thrust (normalised), emergency,
active, psi_l. Each tick's rows go, as numbers, to a process that formats and writes them
(swarm_common.row_log_process), in batches of about 200 rows or 10 ticks and at least every second, so a
killed ground station leaves a readable record and the control loop neither formats nor waits on the disk.
"""

from __future__ import annotations

import csv
import functools
import io
from pathlib import Path
from typing import Any

import numpy as np

from swarm_common.row_log_process import RowLogProcess

COLUMNS = (
    "t,vehicle,phase,x,y,z,vx,vy,vz,roll,pitch,yaw,ref_x,ref_y,ref_z,ref_vx,ref_vy,ref_vz,"
    "slot_x,slot_y,slot_z,fx,fy,fz,roll_d,pitch_d,yaw_d,thrust_acc,thrust,emergency,active,psi_l"
).split(",")


class RunRecord:
    """Appends tick rows to `path`: CSV with a header, CRLF line ends (as Python's csv module writes them).

    Each tick's rows go as numbers to a formatting process (swarm_common.row_log_process), which writes them
    with printf-style formats ("%.6g" per number): the same text as csv.writer with f"{v:.6g}" fields, and
    none of the formatting on the control loop (about 60 us of a 6-vehicle tick).
    """

    def __init__(self, path: Path) -> None:
        self.path = path
        self._log = RowLogProcess(path, "run record")
        header = io.StringIO()
        csv.writer(header).writerow(COLUMNS)
        self._log.write(header.getvalue().encode())
        self._numbers = ",".join(["%.6g"] * _NUMERIC_COLUMNS)

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
        n = len(pos)
        block = np.column_stack(
            [
                np.full(n, t),
                np.arange(n),
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
                c.emergency,
                active,
                np.full(n, float(c.psi_leader)),
            ]
        )
        if block.shape[1] != len(COLUMNS) - 1:  # all but the phase, which the template holds
            raise ValueError(f"a record row needs {_NUMERIC_COLUMNS} numbers, got {block.shape[1] - 6}")
        self._log.write_rows(self._template(phase), block)

    @functools.lru_cache(maxsize=32)  # noqa: B019 - a handful of phases per record, the record lives a flight
    def _template(self, phase: str) -> str:
        """The row template of ticks in `phase`: t, vehicle, the phase as a CSV field, the numbers, the
        emergency and active flags, psi_l."""
        field = _csv_field(phase).replace("%", "%%")
        return f"%.3f,%d,{field},{self._numbers},%d,%d,%.6g\r\n"

    def close(self) -> None:
        """Write every row and close the file (idempotent)."""
        self._log.close()


_NUMERIC_COLUMNS = len(COLUMNS) - 6  # all but t, vehicle, phase, emergency, active, psi_l


@functools.lru_cache(maxsize=32)
def _csv_field(text: str) -> str:
    """`text` as csv.writer writes a field (quoted when it holds a comma, quote or line break)."""
    out = io.StringIO()
    csv.writer(out).writerow([text, ""])  # the record's own dialect; then drop ",\r\n"
    return out.getvalue()[:-3]
