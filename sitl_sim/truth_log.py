"""Ground-truth CSV log of the simulated world (the contract every metric is computed from).

PATH: header then one row per vehicle per sample,
    t,vehicle,sysid,x,y,z,vx,vy,vz,qw,qx,qy,qz,roll,pitch,yaw,f1,f2,f3,f4,mode,armed,crashed,landed
t simulated s since boot; vehicle 0-based; ENU m and m/s in the mission frame; quaternion body FLU -> world
ENU; Euler ZYX rad; motor thrusts N (ArduCopter motor order); mode = ArduCopter custom_mode; flags 0/1
(landed = the autopilot's land_complete). PATH with its suffix replaced by `.obstacles.csv`:
    t,obstacle,x,y,z,radius
Numbers are printed with fixed precision so that identical runs give identical bytes. Each file's rows go as
numbers to a formatting process of its own (swarm_common.row_log_process), which turns them into text on the
other core, below the control loops, where formatting was a large part of a small fleet's simulator frame
(BENCHMARKS.md). Rows are handed over in batches of about 200 rows or 10 samples and at least every second:
the simulator never waits on the disk.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from swarm_common.row_log_process import RowLogProcess

VEHICLE_HEADER = (
    "t,vehicle,sysid,x,y,z,vx,vy,vz,qw,qx,qy,qz,roll,pitch,yaw,f1,f2,f3,f4,mode,armed,crashed,landed"
)
OBSTACLE_HEADER = "t,obstacle,x,y,z,radius"
VEHICLE_ROW = "%.4f,%d,%d" + ",%.4f" * 6 + ",%.6f" * 7 + ",%.4f" * 4 + ",%d,%d,%d,%d\n"
OBSTACLE_ROW = "%.4f,%d,%.4f,%.4f,%.4f,%.4f\n"


def obstacles_path(path: Path) -> Path:
    """The obstacle sidecar of a truth log: PATH with its suffix replaced by .obstacles.csv."""
    return path.with_suffix(".obstacles.csv")


class TruthLog:
    """Writes samples of N vehicles and K obstacles; `close` writes everything and closes both files."""

    def __init__(self, path: Path, sysids: np.ndarray) -> None:
        self.path = path
        self.sysids = np.asarray(sysids, dtype=float)
        n = len(self.sysids)
        self._table = np.empty((n, 24))  # one sample, the columns of VEHICLE_HEADER (filled in place)
        self._table[:, 1] = np.arange(n)
        self._table[:, 2] = self.sysids
        self.vehicles = RowLogProcess(path, "truth log")
        try:
            self.obstacles = RowLogProcess(obstacles_path(path), "truth obstacles")
        except BaseException:
            self.vehicles.close()
            raise
        self.vehicles.write((VEHICLE_HEADER + "\n").encode("ascii"))
        self.obstacles.write((OBSTACLE_HEADER + "\n").encode("ascii"))

    def write(
        self,
        t: float,
        pos: np.ndarray,
        vel: np.ndarray,
        quat: np.ndarray,
        euler: np.ndarray,
        motor: np.ndarray,
        flags: np.ndarray,
        obstacle_centers: np.ndarray,
        obstacle_radii: np.ndarray,
    ) -> None:
        """One sample at t (s): pos, vel, euler (N,3), quat (N,4), motor (N,4), flags (N,4) = mode, armed,
        crashed, landed; obstacle centres (K,3) and radii (K,)."""
        table = self._table
        table[:, 0] = t
        table[:, 3:6] = pos
        table[:, 6:9] = vel
        table[:, 9:13] = quat
        table[:, 13:16] = euler
        table[:, 16:20] = motor
        table[:, 20:24] = flags
        self.vehicles.write_rows(VEHICLE_ROW, table)  # copied out: the table is refilled next sample
        k = len(obstacle_radii)
        if k:
            rows = np.column_stack((np.full(k, t), np.arange(k), obstacle_centers, obstacle_radii))
            self.obstacles.write_rows(OBSTACLE_ROW, rows)

    def close(self) -> None:
        """Write every sample and close both files (idempotent)."""
        try:
            self.vehicles.close()
        finally:
            self.obstacles.close()
