"""RunRecord writes the same bytes as the csv module with f"{v:.6g}" fields (the format report.py and
evaluation/ read), for ordinary, extreme and non-finite values, each row with the values of its write_tick
(its formatting process formats later)."""

from __future__ import annotations

import csv
import math
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from gcs_swarm.evaluation.run_data import read_columns
from gcs_swarm.flight.run_record import COLUMNS, RunRecord

SPECIAL = [0.0, -0.0, math.nan, math.inf, -math.inf, 1e16, 1.5e-7, 123456.5, 2.5e-310, -1.7e308]


def command(rng: np.random.Generator, n: int) -> SimpleNamespace:
    def vec(*shape: int) -> np.ndarray:
        a = rng.normal(scale=rng.choice([1e-9, 1.0, 1e3, 1e7]), size=shape)
        a.flat[rng.integers(0, a.size)] = rng.choice(SPECIAL)
        return a

    return SimpleNamespace(
        ref_pos=vec(n, 3),
        ref_vel=vec(n, 3),
        slots=vec(n, 3),
        field_force=vec(n, 3),
        roll_d=vec(n),
        pitch_d=vec(n),
        yaw_d=vec(n),
        thrust_acc=vec(n),
        emergency=rng.integers(0, 2, n).astype(bool),
        psi_leader=float(rng.choice([0.7, -3.14159, math.nan])),
    )


def reference_rows(t: float, phase: str, pos, vel, att, c, thrust, active) -> list[list[str]]:  # noqa: ANN001
    """The record's original writer: csv rows of f-string formatted fields."""
    block = np.column_stack(
        [pos, vel, att, c.ref_pos, c.ref_vel, c.slots, c.field_force, c.roll_d, c.pitch_d, c.yaw_d]
        + [c.thrust_acc, thrust]
    )
    emergency = np.asarray(c.emergency, dtype=int)
    return [
        [f"{t:.3f}", str(i), phase, *(f"{v:.6g}" for v in block[i])]
        + [str(int(emergency[i])), str(int(active[i])), f"{c.psi_leader:.6g}"]
        for i in range(pos.shape[0])
    ]


@pytest.mark.parametrize("phase", ["formation", 'odd, "phase"'])
def test_rows_match_the_csv_module_byte_for_byte(tmp_path: Path, phase: str) -> None:
    rng = np.random.default_rng(7)
    path, expected = tmp_path / "record.csv", tmp_path / "expected.csv"
    record = RunRecord(path)
    with expected.open("w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(COLUMNS)
        for k, n in enumerate([1, 3, 9, 9, 40, 250, 7]):  # 250 rows: a hand-over of their own
            t = 11.44 + 0.02 * k
            pos, vel, att = (rng.normal(scale=100.0, size=(n, 3)) for _ in range(3))
            att[0, 2] = math.nan
            thrust, active = rng.uniform(0, 1, n), rng.integers(0, 2, n).astype(bool)
            c = command(rng, n)
            record.write_tick(t, phase, pos, vel, att, c, thrust, active)
            writer.writerows(reference_rows(t, phase, pos, vel, att, c, thrust, active))
            # the process formats later: changes in place must not reach the rows written
            for a in (pos, vel, att, thrust, c.ref_pos, c.slots, c.roll_d):
                a += 1.0
            active[:] = ~active
            c.emergency[:] = ~c.emergency
    record.close()
    assert path.read_bytes() == expected.read_bytes()
    if phase == "formation":  # what report.py reads back (it does not parse quoted fields)
        assert read_columns(path, ["t", "x"])["x"].shape == (319,)


def test_a_row_of_the_wrong_width_is_refused(tmp_path: Path) -> None:
    record = RunRecord(tmp_path / "record.csv")
    c, short = command(np.random.default_rng(1), 2), np.zeros((2, 2))
    with pytest.raises(ValueError, match="26 numbers"):
        record.write_tick(1.0, "formation", short, short, short, c, np.zeros(2), np.ones(2, dtype=bool))
    record.close()


def test_many_ticks_match_the_csv_module(tmp_path: Path) -> None:
    """Three seconds of 50 Hz ticks of up to 100 vehicles (flushes on the way), the caller reusing its arrays
    after each tick: the file is what csv.writer writes for each tick as it was."""
    rng = np.random.default_rng(11)
    path, expected = tmp_path / "record.csv", tmp_path / "expected.csv"
    record = RunRecord(path)
    pos, vel, att = (np.zeros((100, 3)) for _ in range(3))
    with expected.open("w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(COLUMNS)
        for k in range(150):
            n = [100, 1, 17][k % 3]
            t = 0.02 * k
            for a in (pos, vel, att):
                a[:] = rng.normal(scale=50.0, size=a.shape)
            thrust, active = rng.uniform(0, 1, n), rng.integers(0, 2, n).astype(bool)
            c = command(rng, n)
            record.write_tick(t, "formation", pos[:n], vel[:n], att[:n], c, thrust, active)
            writer.writerows(reference_rows(t, "formation", pos[:n], vel[:n], att[:n], c, thrust, active))
    record.close()
    record.close()  # idempotent
    assert path.read_bytes() == expected.read_bytes()
