"""A synthetic run folder: three vehicles of missions/quickstart.yaml flying a straight leg in their V slots,
with truth.csv (+ .obstacles.csv), record.csv and flight.json as `gcs-swarm run` writes them."""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from gcs_swarm.flight.run_record import COLUMNS
from gcs_swarm.guidance.formation import slot_positions
from gcs_swarm.mission import Mission, load_mission
from gcs_swarm.mission.geometry import mission_offsets

ROOT = Path(__file__).resolve().parents[3]
TRUTH_COLUMNS = (
    "t,vehicle,sysid,x,y,z,vx,vy,vz,qw,qx,qy,qz,roll,pitch,yaw,f1,f2,f3,f4,mode,armed,crashed,landed".split(
        ","
    )
)
HEADING = math.atan2(120.0, 160.0)  # rad, the quickstart leg's course
SPEED = 5.0  # m/s
DURATION = 30.0  # s


def write_run_folder(
    run_dir: Path, mission: Mission, clock0: float = 0.0, squeeze: tuple[float, float] | None = None
) -> Path:
    """Truth at 50 Hz and a record at 50 Hz of the three vehicles holding their slots on a straight leg that
    ends at the goal; commanded pitch ramps 0 -> 0.2 rad over the first 2 s, then holds. Every time is
    shifted by clock0 s (vehicles that booted long before the run); `squeeze` = (t0, t1) s puts vehicle 2
    2 m beside the leader in that interval (inside D_Emg = 3 m)."""
    run_dir.mkdir(parents=True, exist_ok=True)
    offsets = mission_offsets(mission)
    t = np.arange(0.0, DURATION + 1e-9, 0.02)
    direction = np.array([math.cos(HEADING), math.sin(HEADING), 0.0])
    goal = np.asarray(mission.goal, dtype=float)
    leader = goal - direction * SPEED * (DURATION - t[:, None])
    leader = np.minimum.reduce([leader, np.broadcast_to(goal, leader.shape)], axis=0)
    pos = slot_positions(leader, np.full(len(t), HEADING), offsets)  # (T, N, 3)
    if squeeze is not None:
        inside = (t >= squeeze[0]) & (t < squeeze[1])
        pos[inside, 2] = pos[inside, 0] + np.array([0.0, 0.0, 2.0])
    t = t + clock0
    vel = np.broadcast_to(direction * SPEED, pos.shape)
    n = pos.shape[1]
    rows = []
    for k, tk in enumerate(t):
        for i in range(n):
            p, v = pos[k, i], vel[k, i]
            rows.append([f"{tk:.4f}", i, i + 1, *p, *v, 1, 0, 0, 0, 0, 0, HEADING, 2, 2, 2, 2, 4, 1, 0, 0])
    with (run_dir / "truth.csv").open("w") as f:
        f.write(",".join(TRUTH_COLUMNS) + "\n")
        f.writelines(",".join(str(x) for x in r) + "\n" for r in rows)
    (run_dir / "truth.obstacles.csv").write_text("t,obstacle,x,y,z,radius\n")
    pitch = np.minimum(t / 2.0, 1.0) * 0.2
    with (run_dir / "record.csv").open("w") as f:
        f.write(",".join(COLUMNS) + "\n")
        for k, tk in enumerate(t):
            for i in range(n):
                values = dict.fromkeys(COLUMNS, "0")
                values |= {"t": f"{tk:.3f}", "vehicle": str(i), "phase": "formation"}
                values |= {c: str(x) for c, x in zip(("x", "y", "z"), pos[k, i], strict=True)}
                values |= {"pitch_d": str(pitch[k]), "yaw_d": str(HEADING), "psi_l": str(HEADING)}
                f.write(",".join(values[c] for c in COLUMNS) + "\n")
    flight = {
        "mission": mission.name,
        "mission_path": str(mission.path),
        "arrived": True,
        "t_formation_start": clock0,
        "t_formation_end": clock0 + DURATION,
        "final_targets": pos[-1].tolist(),
        "offsets": offsets.tolist(),
        "lost": [],
        "events": [],
        "ticks": len(t),
        "wall_duration_s": 1.0,
    }
    (run_dir / "flight.json").write_text(json.dumps(flight))
    return run_dir


@pytest.fixture
def make_run_folder() -> Callable[..., Path]:
    """`write_run_folder` itself, for tests that write several folders or shift the clock."""
    return write_run_folder


@pytest.fixture
def quickstart_mission() -> Mission:
    return load_mission(ROOT / "missions" / "quickstart.yaml")


@pytest.fixture
def run_folder(tmp_path: Path, quickstart_mission: Mission) -> Path:
    return write_run_folder(tmp_path / "run", quickstart_mission)
