"""A run folder read back for evaluation: trajectories from ground truth (the simulator's truth log) or the
ground station's telemetry record, and the commanded attitudes from the record.
Positions ENU metres, times s."""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np

from gcs_swarm.evaluation import metrics
from gcs_swarm.flight.run_folder import RECORD_FILE, TRUTH_FILE


@dataclass(frozen=True)
class Trajectories:
    """Positions of N vehicles on a common time base. t (T,) s; pos, vel (T, N, 3) ENU; crashed (T, N) bool;
    obstacle centres (T, K, 3) and radii (K,)."""

    t: np.ndarray
    pos: np.ndarray
    vel: np.ndarray
    crashed: np.ndarray
    obstacle_centres: np.ndarray
    obstacle_radii: np.ndarray
    source: str

    @cached_property
    def closest_pair(self) -> np.ndarray:
        """(T,) m: the smallest distance between two vehicles at each sample (metrics.closest_pair_distance),
        computed once for the report and its figures."""
        return metrics.closest_pair_distance(self.pos)

    @cached_property
    def nearest_neighbour(self) -> np.ndarray:
        """(T, N) m: each vehicle's distance to its nearest other vehicle at each sample
        (metrics.nearest_neighbour_distance), computed once for the report and its figures."""
        return metrics.nearest_neighbour_distance(self.pos)


def read_columns(path: Path, columns: list[str]) -> dict[str, np.ndarray]:
    """Numeric columns of a CSV file with a header line, as float arrays (rows,). A last line cut short (a
    killed writer) is dropped. KeyError names a missing column."""
    text = path.read_text()
    if not text.endswith("\n"):
        text = text[: text.rfind("\n") + 1]
    lines = text.splitlines()
    header = lines[0].split(",") if lines else []
    missing = [c for c in columns if c not in header]
    if missing:
        raise KeyError(f"{path.name}: no column {', '.join(missing)}")
    if len(lines) < 2:
        return {c: np.zeros(0) for c in columns}
    index = [header.index(c) for c in columns]
    data = np.loadtxt(lines[1:], delimiter=",", usecols=index, ndmin=2)
    return {c: data[:, k] for k, c in enumerate(columns)}


def by_vehicle(
    table: dict[str, np.ndarray], key: str, columns: list[str], n: int | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Pivot long rows (one per vehicle per sample, in vehicle order; `key` holds the vehicle's 0-based
    index) into t (T,) and values (T, N, len(columns)). N = n, or one more than the largest index; rows of an
    index outside 0..N-1 are left out. A sample starts where t changes or the index does not grow. NaN where
    a vehicle has no row in a sample (silent, or never logged); a last sample with fewer rows than the
    fullest one (a log cut mid-sample by a killed process) is dropped."""
    index = table[key].astype(int)
    n = n if n is not None else (int(index.max()) + 1 if len(index) else 1)
    t_rows = table["t"]
    starts = np.ones(len(t_rows), dtype=bool)
    starts[1:] = (t_rows[1:] != t_rows[:-1]) | (index[1:] <= index[:-1])
    sample = np.cumsum(starts) - 1
    rows = np.bincount(sample) if len(sample) else np.zeros(0, dtype=int)
    count = len(rows) - 1 if len(rows) > 1 and rows[-1] < rows.max() else len(rows)
    keep = (sample < count) & (index >= 0) & (index < n)
    values = np.full((count, n, len(columns)), np.nan)
    values[sample[keep], index[keep]] = np.stack([table[c][keep] for c in columns], axis=-1)
    return t_rows[starts][:count], values


def load_truth(path: Path, n: int | None = None) -> Trajectories:
    """Read the simulator's truth log (and its .obstacles.csv sidecar); n vehicles (None: as many as the log
    names)."""
    columns = ["x", "y", "z", "vx", "vy", "vz", "crashed"]
    t, v = by_vehicle(read_columns(path, ["t", "vehicle", *columns]), "vehicle", columns, n)
    obstacle_path = path.with_suffix(".obstacles.csv")
    centres = np.zeros((len(t), 0, 3))
    radii = np.zeros(0)
    if obstacle_path.exists() and obstacle_path.stat().st_size > 0:
        columns = ["x", "y", "z", "radius"]
        otable = read_columns(obstacle_path, ["t", "obstacle", *columns])
        if len(otable["t"]):
            ot, ov = by_vehicle(otable, "obstacle", columns)
            idx = np.clip(np.searchsorted(ot, t), 0, len(ot) - 1)
            centres, radii = ov[idx, :, :3], ov[0, :, 3]
    return Trajectories(t, v[..., :3], v[..., 3:6], v[..., 6] > 0.5, centres, radii, "truth")


def load_record(path: Path, obstacles: list[Any], n: int | None = None) -> Trajectories:
    """The ground station's telemetry record as trajectories (used when no truth log exists); n vehicles
    (None: as many as the record names)."""
    columns = ["x", "y", "z", "vx", "vy", "vz"]
    t, v = by_vehicle(read_columns(path, ["t", "vehicle", *columns]), "vehicle", columns, n)
    centres = np.array([[o.center_at(tt) for o in obstacles] for tt in t]).reshape(len(t), len(obstacles), 3)
    radii = np.array([o.radius for o in obstacles], dtype=float)
    crashed = np.zeros(v.shape[:2], dtype=bool)
    return Trajectories(t, v[..., :3], v[..., 3:6], crashed, centres, radii, "telemetry")


@dataclass(frozen=True)
class CommandLog:
    """What the ground station commanded per control tick (record.csv): t (T,) s; attitude_d (T, N, 3)
    commanded roll, pitch, yaw rad; psi_l (T,) rad the leader heading psi_L (spec 6)."""

    t: np.ndarray
    attitude_d: np.ndarray
    psi_l: np.ndarray


def load_commands(record_path: Path, n: int | None = None) -> CommandLog | None:
    """The run record's commands of n vehicles (None: as many as the record names); None without a record or
    without a tick in it."""
    if not record_path.exists() or record_path.stat().st_size == 0:
        return None
    columns = ["roll_d", "pitch_d", "yaw_d", "psi_l"]
    table = read_columns(record_path, ["t", "vehicle", *columns])
    if len(table["t"]) == 0:
        return None
    t, v = by_vehicle(table, "vehicle", columns, n)
    with np.errstate(all="ignore"):
        psi_l = np.fmax.reduce(v[..., 3], axis=1)  # the same on every row of a tick: any row that has it
    return CommandLog(t, v[..., :3], psi_l)


def load_trajectories(run_dir: Path, mission: Any) -> Trajectories:
    """Ground truth when the run has a truth log, else the ground station's telemetry record."""
    truth_path = run_dir / TRUTH_FILE
    n = len(mission.vehicles)
    if truth_path.exists() and truth_path.stat().st_size > 0:
        return load_truth(truth_path, n)
    return load_record(run_dir / RECORD_FILE, list(mission.obstacles), n)
