"""`gcs-swarm montecarlo` and `gcs-swarm compare` end to end: real lockstep flights of a tiny mission (three
vehicles, airborne at 5 m, a 30 m leg), on free ports, bounded in time, every process cleaned up."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from dask import distributed

from gcs_swarm.evaluation.campaign_store import RESULTS_FILE, SUMMARY_FILE
from gcs_swarm.evaluation.montecarlo import CampaignOptions, montecarlo_command
from tests.e2e.flights import ROOT, derived_mission

SUMMARY_KEYS = {"runs", "success_rate", "success_ci95", "collision_rate", "variants"}


@pytest.fixture
def tiny(tmp_path: Path) -> Path:
    starts = [[0.0, 0.0, 5.0], [-1.5, -10.0, 5.0], [-10.0, 1.5, 5.0]]
    vehicles = [
        {"name": name, "role": role, "start": {"position": p, "yaw_deg": 37.0}}
        for name, role, p in zip(
            ("lead", "right", "left"), ("leader", "follower", "follower"), starts, strict=True
        )
    ]
    return derived_mission(
        tmp_path,
        "quickstart.yaml",
        "tiny",
        vehicles=vehicles,
        formation={"altitude": 5.0},
        goal=[24.0, 18.0, 5.0],
        world={"obstacles": [{"center": [12.0, 4.0, 5.0], "radius": 1.5}]},
        run={"airborne_start": True, "time_limit_s": 15.0},
    )


@pytest.fixture
def ranges(tmp_path: Path) -> Path:
    path = tmp_path / "ranges.yaml"
    path.write_text(
        "obstacles: {count: [1, 1], radius: [1, 1.5], cross_track: [-6, 6], keep_out: 2}\n"
        "starts: {position_jitter: 1, velocity: 0.5}\n"
        "wind: {speed: [0, 2], turbulence: [0, 0]}\n"
    )
    return path


def _montecarlo(mission: Path, ranges: Path, out: Path) -> list[str]:
    return [
        sys.executable,
        "-m",
        "gcs_swarm",
        "montecarlo",
        str(mission),
        "--runs",
        "2",
        "--seed",
        "7",
        "--jobs",
        "1",
        "--ranges",
        str(ranges),
        "--out",
        str(out),
    ]


def _default_sigint() -> None:
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _group_gone(pgid: int) -> bool:
    try:
        os.killpg(pgid, 0)
    except ProcessLookupError:
        return True
    return False


def test_montecarlo_interrupted_then_resumed_loses_and_repeats_nothing(
    tiny: Path, ranges: Path, tmp_path: Path
) -> None:
    out = tmp_path / "campaign"
    results = out / RESULTS_FILE
    cmd = _montecarlo(tiny, ranges, out)
    proc = subprocess.Popen(
        cmd,
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        start_new_session=True,
        # Ctrl-C as at a terminal, even when pytest itself runs in the background (`cmd &` starts it with
        # SIGINT ignored, and Python then leaves SIGINT ignored in every process it starts)
        preexec_fn=_default_sigint,
    )
    try:
        deadline = time.monotonic() + 120
        while not (results.exists() and results.read_text().count("\n") >= 1):
            assert proc.poll() is None, proc.stdout.read().decode() if proc.stdout else ""
            assert time.monotonic() < deadline, "no run finished within 120 s"
            time.sleep(0.1)
        os.killpg(proc.pid, signal.SIGINT)  # Ctrl-C at the terminal: the whole process group
        output = proc.communicate(timeout=60)[0].decode()
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait(10)
    deadline = time.monotonic() + 15
    while not _group_gone(proc.pid) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert _group_gone(proc.pid), "a worker or simulator outlived the interrupted campaign"
    assert proc.returncode == 130, output
    assert "rerun the same command to resume" in output
    kept = [json.loads(line)["seed"] for line in results.read_text().splitlines()]
    # the interrupted run is not recorded as finished; on a loaded machine the second run may have finished
    # (and been recorded) before the interrupt reached the campaign, and then nothing was interrupted
    assert kept in ([7], [7, 8])

    resumed = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert resumed.returncode == 0, resumed.stdout + resumed.stderr
    assert f"{len(kept)} of 2 runs done, {2 - len(kept)} to fly" in resumed.stdout
    lines = results.read_text().splitlines()
    assert sorted(json.loads(line)["seed"] for line in lines) == [7, 8]

    again = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert again.returncode == 0, again.stdout + again.stderr
    assert "2 of 2 runs done, 0 to fly" in again.stdout
    assert results.read_text().splitlines() == lines  # nothing flown, nothing appended

    summary = json.loads((out / SUMMARY_FILE).read_text())
    assert SUMMARY_KEYS <= summary.keys()
    assert summary["runs"] == 2
    assert 0.0 <= summary["success_ci95"][0] <= summary["success_rate"] <= summary["success_ci95"][1] <= 1.0
    assert list(summary["variants"]) == ["iaapf"]
    for line in lines:
        row = json.loads(line)
        assert row["variant"] == "iaapf" and "error" not in row
        assert row["min_separation_m"] > 0 and row["sim_duration_s"] > 0
        run_dir = Path(row["run_dir"])
        assert (run_dir / "report.json").exists() and (run_dir / "mission.yaml").exists()
        assert not (run_dir / "truth.csv").exists()  # bulky logs only with --keep-runs


def test_montecarlo_on_a_dask_cluster(tiny: Path, ranges: Path, tmp_path: Path) -> None:
    out = tmp_path / "dask"
    said: list[str] = []
    with distributed.LocalCluster(
        processes=False, n_workers=1, threads_per_worker=1, dashboard_address=None
    ) as cluster:
        options = CampaignOptions(
            runs=1, seed=3, scheduler=cluster.scheduler_address, out_dir=out, ranges_path=ranges
        )
        status = montecarlo_command(str(tiny), options, said.append)
    assert status == 0, said
    assert any("on Dask at" in s for s in said)
    rows = [json.loads(line) for line in (out / RESULTS_FILE).read_text().splitlines()]
    assert [(r["seed"], r["variant"]) for r in rows] == [(3, "iaapf")]
    assert "error" not in rows[0] and rows[0]["sim_duration_s"] > 0
    summary = json.loads((out / SUMMARY_FILE).read_text())
    assert summary["runs"] == 1 and SUMMARY_KEYS <= summary.keys()


def test_compare_apf_and_iaapf(tiny: Path, tmp_path: Path) -> None:
    out = tmp_path / "compare"
    cmd = [
        sys.executable,
        "-m",
        "gcs_swarm",
        "compare",
        str(tiny),
        "--variants",
        "apf,iaapf",
        "--out",
        str(out),
    ]
    proc = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    result = json.loads((out / "compare.json").read_text())
    assert [v["label"] for v in result["variants"]] == ["apf", "iaapf"]
    assert [v["method"] for v in result["variants"]] == ["apf", "iaapf"]
    for v in result["variants"]:
        assert v["status"] in (0, 1) and v["sim_duration_s"] > 0
        assert (out / v["label"] / "report.json").exists()
    table = (out / "compare.md").read_text()
    assert "| figure | apf | iaapf |" in table
    assert (out / "compare.png").stat().st_size > 1000  # matplotlib is in the test extra


def test_compare_refuses_an_unknown_variant(tiny: Path, tmp_path: Path) -> None:
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "gcs_swarm",
            "compare",
            str(tiny),
            "--variants",
            "apf,rrt",
            "--out",
            str(tmp_path),
        ],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert proc.returncode == 2
    assert "error: unknown variant 'rrt'" in proc.stdout
    assert "Traceback" not in proc.stdout + proc.stderr
