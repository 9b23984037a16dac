"""Truth-log format: the documented columns, readable by numpy, obstacle sidecar path; each sample holds the
values given at its write, whatever the caller does with its arrays afterwards (a formatting process turns
them into text later)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

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


@pytest.mark.parametrize("n", [3, 250])  # 3: ten samples a hand-over; 250: one
def test_each_sample_keeps_the_values_of_its_write(tmp_path, n):
    """Samples reach the formatting process later, in batches: arrays changed in place after `write` (the
    simulator's state arrays are, and so is the log's own table) must not reach the samples already
    written. The expected text is built here with f-strings, not with the log's templates."""
    log = TruthLog(tmp_path / "run.csv", np.arange(5, 5 + n))
    rng = np.random.default_rng(3)
    arrays = [rng.normal(size=shape) for shape in ((n, 3), (n, 3), (n, 4), (n, 3), (n, 4))]
    flags, centers, radii = np.zeros((n, 4)), np.zeros((1, 3)), np.array([2.0])
    expected_rows, expected_obstacles = [], []
    for k in range(20):
        t = 0.02 * k
        log.write(t, *arrays, flags, centers, radii)
        pos, vel, quat, euler, motor = arrays
        for i in range(n):
            expected_rows.append(
                f"{t:.4f},{i},{5 + i},"
                + ",".join(f"{v:.4f}" for v in (*pos[i], *vel[i]))
                + ","
                + ",".join(f"{v:.6f}" for v in (*quat[i], *euler[i]))
                + ","
                + ",".join(f"{v:.4f}" for v in motor[i])
                + ","
                + ",".join(f"{int(v)}" for v in flags[i])
            )
        x, y, z = centers[0]
        expected_obstacles.append(f"{t:.4f},0,{x:.4f},{y:.4f},{z:.4f},2.0000")
        for a in (*arrays, flags, centers):  # in place, at once: the batch may not have been handed over yet
            a += rng.normal(size=a.shape) if a is not flags else 1.0
    log.close()
    assert (tmp_path / "run.csv").read_text().splitlines() == [CONTRACT, *expected_rows]
    assert (tmp_path / "run.obstacles.csv").read_text().splitlines() == [OBSTACLE_HEADER, *expected_obstacles]


def test_sidecar_path():
    assert obstacles_path(Path("out/run.csv")) == Path("out/run.obstacles.csv")
    assert obstacles_path(Path("out/run")) == Path("out/run.obstacles.csv")
