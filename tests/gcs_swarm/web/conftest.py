"""A run folder written by hand: three vehicles, three truth samples, two record ticks, a flight.json with
events, a lost vehicle and a change of leader; the mission is quickstart's with a moving obstacle, a fence, an
exclusion zone, a prism and a cylinder added. Every number the tests expect is read off these lines."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[3]

TRUTH_HEADER = (
    "t,vehicle,sysid,x,y,z,vx,vy,vz,qw,qx,qy,qz,roll,pitch,yaw,f1,f2,f3,f4,mode,armed,crashed,landed"
)
# t, vehicle, x, y, z, yaw (rad ENU), mode (ArduCopter custom_mode: 0 STABILIZE, 4 GUIDED, 9 LAND), crashed
TRUTH_ROWS = [
    (0.0, 0, 0.0, 0.0, 0.0, 0.5, 0, 0),
    (0.0, 1, -1.5, -10.0, 0.0, 0.5, 0, 0),
    (0.0, 2, -10.0, 1.5, 0.0, 0.5, 0, 0),
    (1.0, 0, 1.0, 2.0, 10.0, 0.6, 4, 0),
    (1.0, 1, -0.5, -8.0, 10.0, 0.7, 4, 0),
    (1.0, 2, -9.0, 3.5, 10.0, 0.8, 4, 0),
    (2.0, 0, 2.0, 4.0, 10.0, 0.6, 4, 0),
    (2.0, 1, 0.5, -6.0, 10.0, 0.7, 4, 0),
    (2.0, 2, -8.0, 5.5, 3.0, 0.8, 9, 1),
]
RECORD_HEADER = (
    "t,vehicle,phase,x,y,z,vx,vy,vz,roll,pitch,yaw,ref_x,ref_y,ref_z,ref_vx,ref_vy,ref_vz,"
    "slot_x,slot_y,slot_z,fx,fy,fz,roll_d,pitch_d,yaw_d,thrust_acc,thrust,emergency,active,psi_l"
)
# t, vehicle, phase, x, y, yaw, slot_x, slot_y: formation ticks at 1.0 s and 1.5 s
RECORD_ROWS = [
    (1.0, 0, "formation", 1.0, 2.0, 0.6, 1.0, 2.0),
    (1.0, 1, "formation", -0.5, -8.0, 0.7, -6.0, -5.0),
    (1.0, 2, "formation", -9.0, 3.5, 0.8, -6.0, 9.0),
    (1.5, 0, "hold", 1.5, 3.0, 0.6, 1.5, 3.0),
    (1.5, 1, "hold", 0.0, -7.0, 0.7, -5.5, -4.0),
    (1.5, 2, "hold", -8.5, 4.5, 0.8, -5.5, 10.0),
]


def truth_text() -> str:
    lines = [TRUTH_HEADER]
    for t, k, x, y, z, yaw, mode, crashed in TRUTH_ROWS:
        lines.append(f"{t},{k},{k + 1},{x},{y},{z},0,0,0,1,0,0,0,0,0,{yaw},0,0,0,0,{mode},1,{crashed},0")
    return "\n".join(lines) + "\n"


def record_text() -> str:
    lines = [RECORD_HEADER]
    for t, k, phase, x, y, yaw, sx, sy in RECORD_ROWS:
        lines.append(f"{t},{k},{phase},{x},{y},10,0,0,0,0,0,{yaw},0,0,0,0,0,0,{sx},{sy},10" + ",0" * 11)
    return "\r\n".join(lines) + "\r\n"


FLIGHT = {
    "events": [
        "command mode: attitude targets at 50 Hz, no link budget",
        "t=1.20 s formation narrows: column",
        "t=1.90 s lead taken over: now in LOITER, not commanded any more (rejoin lead hands it back)",
    ],
    "lost_at_s": {"left": 1.8},
    "formation_timeline": [
        {"t": 1.0, "leader": 0, "offsets": []},
        {"t": 1.9, "leader": 1, "offsets": []},
    ],
}


def write_mission(path: Path) -> Path:
    data = yaml.safe_load((ROOT / "missions" / "quickstart.yaml").read_text())
    data["world"]["obstacles"][0]["velocity"] = [2, -1, 0]  # the first obstacle moves: c(t) = c0 + v t
    data["world"]["prisms"] = [
        {"name": "block", "polygon": [[20, 60], [30, 60], [30, 70], [20, 70]], "top": 15}
    ]
    data["world"]["cylinders"] = [{"name": "mast", "center": [40, -20], "radius": 2, "top": 10}]
    fence = data["safety"].setdefault("geofence", {})
    fence["polygon"] = [[-60, -60], [220, -60], [220, 200], [-60, 200]]
    fence["exclusions"] = [{"name": "pond", "center": [150, 20], "radius": 5}]
    path.write_text(yaml.safe_dump(data))
    return path


@pytest.fixture
def run_dir(tmp_path: Path) -> Path:
    """The hand-written run folder (its mission beside it, named by flight.json)."""
    folder = tmp_path / "run"
    folder.mkdir()
    mission = write_mission(tmp_path / "mission.yaml")
    (folder / "truth.csv").write_text(truth_text())
    (folder / "record.csv").write_bytes(record_text().encode())
    (folder / "flight.json").write_text(json.dumps({**FLIGHT, "mission_path": str(mission)}))
    return folder
