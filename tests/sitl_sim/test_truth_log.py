"""Truth-log format: the documented columns, readable by numpy, obstacle sidecar path."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from sitl_sim.truth_log import OBSTACLE_HEADER, VEHICLE_HEADER, TruthLog, obstacles_path

CONTRACT = "t,vehicle,sysid,x,y,z,vx,vy,vz,qw,qx,qy,qz,roll,pitch,yaw,f1,f2,f3,f4,mode,armed,crashed,landed"


def test_columns_and_numpy_round_trip(tmp_path):
    log = TruthLog(tmp_path / "run.csv", np.array([1, 2]))
    pos = np.array([[1.0, 2.0, 3.0], [-4.0, 5.5, 0.0]])
    quat = np.array([[1.0, 0.0, 0.0, 0.0], [0.5, 0.5, 0.5, 0.5]])
    flags = np.array([[4, 1, 0, 0], [9, 0, 1, 1]])
    for t in (0.0, 0.02):
        log.write(
            t,
            pos,
            pos * 2,
            quat,
            pos / 10,
            np.ones((2, 4)),
            flags,
            np.array([[7.0, 8.0, 9.0]]),
            np.array([3.0]),
        )
    log.close()
    log.close()  # idempotent
    assert VEHICLE_HEADER == CONTRACT and OBSTACLE_HEADER == "t,obstacle,x,y,z,radius"
    data = np.genfromtxt(tmp_path / "run.csv", names=True, delimiter=",")
    assert data.dtype.names == tuple(CONTRACT.split(","))
    assert (
        len(data) == 4 and list(data["sysid"]) == [1, 2, 1, 2] and list(data["t"]) == [0.0, 0.0, 0.02, 0.02]
    )
    assert np.allclose(data[data["vehicle"] == 1][["x", "y", "z"]].tolist(), [[-4.0, 5.5, 0.0]] * 2)
    assert list(data["mode"][:2]) == [4, 9] and list(data["crashed"][:2]) == [0, 1]
    obstacles = np.genfromtxt(tmp_path / "run.obstacles.csv", names=True, delimiter=",")
    assert obstacles.shape == (2,) and np.all(obstacles["radius"] == 3.0)


def test_sidecar_path():
    assert obstacles_path(Path("out/run.csv")) == Path("out/run.obstacles.csv")
    assert obstacles_path(Path("out/run")) == Path("out/run.obstacles.csv")
