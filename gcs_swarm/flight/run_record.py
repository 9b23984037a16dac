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
    none of the formatting on the control loop.
    """

    def __init__(self, path: Path) -> None:
        self.path = path
        self._log = RowLogProcess(path, "run record")
        header = io.StringIO()
        csv.writer(header).writerow(COLUMNS)
        self._log.write(header.getvalue().encode())
        self._numbers = ",".join(["%.6g"] * _NUMERIC_COLUMNS)
        self._table: np.ndarray | None = None  # _block's table

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
        block = self._block(n)
        try:
            block[:, 0] = t
            for columns, values in (
                (_POS, pos),
                (_VEL, vel),
                (_ATT, att),
                (_REF_POS, c.ref_pos),
                (_REF_VEL, c.ref_vel),
                (_SLOT, c.slots),
                (_FORCE, c.field_force),
            ):
                block[:, columns] = values
            for column, value in (
                (_ROLL_D, c.roll_d),
                (_PITCH_D, c.pitch_d),
                (_YAW_D, c.yaw_d),
                (_THRUST_ACC, c.thrust_acc),
                (_THRUST, thrust),
                (_EMERGENCY, c.emergency),
                (_ACTIVE, active),
            ):
                block[:, column] = value
        except ValueError as err:  # an array of the wrong shape
            raise ValueError(f"a record row needs {_NUMERIC_COLUMNS} numbers in its columns: {err}") from None
        block[:, _PSI_L] = float(c.psi_leader)
        self._log.write_rows(self._template(phase), block)

    def _block(self, n: int) -> np.ndarray:
        """The (n, columns but the phase) float64 table a tick's rows are assembled in, reused from tick to
        tick (RowLogProcess.write_rows copies it out); its vehicle column filled once."""
        if self._table is None or len(self._table) != n:
            self._table = np.empty((n, len(COLUMNS) - 1))
            self._table[:, 1] = np.arange(n)
        return self._table

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


def _column(name: str) -> int:
    """Where COLUMNS' `name` sits in the numbers of a row (t, vehicle, then the phase, which is left out)."""
    return COLUMNS.index(name) - 1


def _columns3(first: str) -> slice:
    """Where the three columns from COLUMNS' `first` sit in the numbers of a row."""
    return slice(_column(first), _column(first) + 3)


_POS, _VEL, _ATT = _columns3("x"), _columns3("vx"), _columns3("roll")
_REF_POS, _REF_VEL = _columns3("ref_x"), _columns3("ref_vx")
_SLOT, _FORCE = _columns3("slot_x"), _columns3("fx")
_ROLL_D, _PITCH_D, _YAW_D = _column("roll_d"), _column("pitch_d"), _column("yaw_d")
_THRUST_ACC, _THRUST = _column("thrust_acc"), _column("thrust")
_EMERGENCY, _ACTIVE, _PSI_L = _column("emergency"), _column("active"), _column("psi_l")


@functools.lru_cache(maxsize=32)
def _csv_field(text: str) -> str:
    """`text` as csv.writer writes a field (quoted when it holds a comma, quote or line break)."""
    out = io.StringIO()
    csv.writer(out).writerow([text, ""])  # the record's own dialect; then drop ",\r\n"
    return out.getvalue()[:-3]
