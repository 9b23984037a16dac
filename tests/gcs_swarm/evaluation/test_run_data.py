"""Run folders read back (gcs_swarm.evaluation.run_data): long rows pivoted into (T, N, ...) arrays whatever
rows are missing: a vehicle silent for a while or never logged, a log cut mid-sample."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from gcs_swarm.evaluation.run_data import load_commands, load_truth
from gcs_swarm.flight.run_record import COLUMNS
from tests.gcs_swarm.evaluation.conftest import TRUTH_COLUMNS


def _truth(path: Path, rows: list[tuple[float, int, float]], cut: bool = False) -> Path:
    """truth.csv with rows (t, vehicle, x); every other column 0."""
    lines = [",".join(TRUTH_COLUMNS)]
    for t, vehicle, x in rows:
        values = dict.fromkeys(TRUTH_COLUMNS, "0") | {"t": f"{t:.4f}", "vehicle": str(vehicle), "x": str(x)}
        lines.append(",".join(values[c] for c in TRUTH_COLUMNS))
    text = "\n".join(lines) + "\n"
    path.write_text(text[:-5] if cut else text)
    return path


def test_a_vehicle_silent_for_a_while_gets_nan_there(tmp_path: Path) -> None:
    # three samples of vehicles 0..2; vehicle 1 has no row at t = 0.1 (x = 10 * vehicle + sample)
    rows = [(0.0, 0, 0.0), (0.0, 1, 10.0), (0.0, 2, 20.0), (0.1, 0, 1.0), (0.1, 2, 21.0)]
    rows += [(0.2, 0, 2.0), (0.2, 1, 12.0), (0.2, 2, 22.0)]
    traj = load_truth(_truth(tmp_path / "truth.csv", rows), 3)
    np.testing.assert_array_equal(traj.t, [0.0, 0.1, 0.2])
    np.testing.assert_array_equal(traj.pos[:, :, 0], [[0, 10, 20], [1, np.nan, 21], [2, 12, 22]])


def test_a_vehicle_never_logged_is_a_nan_column_of_the_mission_size(tmp_path: Path) -> None:
    rows = [(0.0, 0, 0.0), (0.0, 2, 20.0), (0.1, 0, 1.0), (0.1, 2, 21.0)]
    traj = load_truth(_truth(tmp_path / "truth.csv", rows), 4)
    assert traj.pos.shape == (2, 4, 3)
    assert np.isnan(traj.pos[:, 1]).all() and np.isnan(traj.pos[:, 3]).all()
    np.testing.assert_array_equal(traj.pos[:, 2, 0], [20.0, 21.0])


def test_a_sample_cut_by_a_killed_writer_is_dropped(tmp_path: Path) -> None:
    # the last line cut short (dropped by read_columns) leaves t = 0.1 with one row of two: dropped
    rows = [(0.0, 0, 0.0), (0.0, 1, 10.0), (0.1, 0, 1.0), (0.1, 1, 11.0)]
    traj = load_truth(_truth(tmp_path / "truth.csv", rows, cut=True), 2)
    np.testing.assert_array_equal(traj.t, [0.0])


def test_ticks_with_equal_printed_times_stay_apart(tmp_path: Path) -> None:
    """record.csv prints t with 6 significant digits: ticks 0.02 s apart after 10000 s print alike. A new
    sample starts where the vehicle index does not grow, so they stay two ticks."""
    record = tmp_path / "record.csv"
    lines = [",".join(COLUMNS)]
    for pitch in (0.1, 0.2):
        for vehicle in (0, 1):
            values = dict.fromkeys(COLUMNS, "0") | {
                "t": "12345.6",
                "vehicle": str(vehicle),
                "phase": "formation",
            }
            values |= {"pitch_d": str(pitch + vehicle), "psi_l": "0.5"}
            lines.append(",".join(values[c] for c in COLUMNS))
    record.write_text("\n".join(lines) + "\n")
    commands = load_commands(record, 2)
    assert commands is not None
    np.testing.assert_allclose(commands.attitude_d[:, :, 1], [[0.1, 1.1], [0.2, 1.2]])
    np.testing.assert_array_equal(commands.psi_l, [0.5, 0.5])
