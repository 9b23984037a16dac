"""The bundled site mission (issue 37 item 6): missions/cmac_site.yaml over ArduPilot SITL's home field, its
fence and no-fly zones from a QGroundControl .plan, its buildings and trees from a GeoJSON, three legs in
latitude/longitude with two changes of formation. Flown in lockstep against sitl-sim, and (opt-in, `-m
ardupilot`) against three real ArduCopter SITL processes. Every figure is checked on the flight's own record
of positions with shapely, independently of the report."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import shapely
import yaml
from shapely.geometry import Point, Polygon

from gcs_swarm.cli import main
from gcs_swarm.mission import Mission, load_mission
from swarm_common.ports import free_udp_base
from tests.e2e.ardupilot_sitl import SitlBuild, start_vehicles, stop_vehicles
from tests.e2e.flights import MISSIONS, ROOT, SHORT_BOOT, fly, numbers

MISSION = MISSIONS / "cmac_site.yaml"
BUILD = SitlBuild.from_environment()


def test_the_site_mission_carries_its_fence_zones_buildings_trees_and_legs() -> None:
    mission = load_mission(MISSION)
    assert mission.origin == (-35.363261, 149.16523, 584.0)  # the .plan's planned home
    assert len(mission.fence.polygon) == 5 and len(mission.fence.exclusions) == 2
    # each named by its file and feature, so that a message points at the map
    assert [p.name for p in mission.prisms] == [
        f"cmac/field.geojson: feature {k} ('{name}')"
        for k, name in enumerate(("hangar", "north shed", "south shed"))
    ]
    assert len(mission.cylinders) == 4 and mission.cylinders[-1].name.endswith("('old oak')")
    assert [(leg.shape, leg.speed) for leg in mission.legs] == [("v", 10.0), ("column", 6.0), ("line", 8.0)]
    # the legs' ends, written in lat/lon, lie where the site was drawn in ENU (scripted from ENU metres)
    np.testing.assert_allclose(
        np.array(mission.waypoints), [[0, 150, 10], [200, 150, 10], [200, 0, 15]], atol=0.05
    )


def test_check_names_the_site_it_found(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["check", str(MISSION)]) == 0
    printed = capsys.readouterr().out
    assert "0 obstacles, 3 buildings, 4 trees or masts, 2 exclusion zones, 3 legs, a fence polygon" in printed
    assert "goal [200.0, 0.0, 15.0]" in printed and "cannot be flown yet" not in printed


def _clearances(mission: Mission, xyz: np.ndarray) -> tuple[float, float]:
    """(closest approach to any building or tree, to any fence edge or zone) m of the points (P, 3), by
    shapely: a shape's distance is its footprint's horizontal distance d at heights between its base and its
    top, else sqrt(d^2 + dz^2) with dz the height above the top (or below the base). Every point must lie
    inside the fence polygon."""
    points = shapely.points(xyz[:, :2])
    to_shape = np.inf
    footprints = [(Polygon(p.footprint), p.bottom, p.top) for p in mission.prisms]
    footprints += [(Point(c.center).buffer(c.radius, 256), c.bottom, c.top) for c in mission.cylinders]
    for footprint, bottom, top in footprints:
        across = shapely.distance(footprint, points)
        dz = np.maximum(xyz[:, 2] - top, 0.0) + np.maximum(bottom - xyz[:, 2], 0.0)
        to_shape = min(to_shape, float(np.hypot(across, dz).min()))
    fence = Polygon(mission.fence.polygon)
    assert shapely.contains(fence, points).all()
    zones = [fence.exterior] + [
        Polygon(z.polygon) if z.polygon is not None else Point(z.center).buffer(z.radius, 256)
        for z in mission.fence.exclusions
    ]
    to_fence = min(float(shapely.distance(zone, points).min()) for zone in zones)
    return to_shape, to_fence


def _check_flight(mission: Mission, run_dir: Path, xyz: np.ndarray) -> None:
    report = json.loads((run_dir / "report.json").read_text())
    assert report["reached"] and report["collisions"] == 0 and report["fence_breaches"] == 0
    flight = json.loads((run_dir / "flight.json").read_text())
    assert [row["shape"] for row in flight["legs"]] == ["v", "column", "line"]
    to_shape, to_fence = _clearances(mission, xyz)
    # the clearance the issue asks for: the vehicle radius plus the safe distance s_s (1 m)
    assert to_shape >= mission.safety.collision_radius + mission.safety.separation.s_s
    assert to_fence > mission.safety.collision_radius


def test_the_site_mission_flies_against_sitl_sim(tmp_path: Path) -> None:
    mission = load_mission(MISSION)
    flight = fly(MISSION, tmp_path / "run", extra=["--time-mode", "lockstep", SHORT_BOOT])
    assert flight.status == 0, flight.output[-2000:]
    truth = np.genfromtxt(flight.run_dir / "truth.csv", delimiter=",", names=True)
    airborne = truth[truth["z"] > 0.5]
    _check_flight(mission, flight.run_dir, np.column_stack([airborne["x"], airborne["y"], airborne["z"]]))
    # between the sheds (x 80..112) the formation flies as a column: every vehicle within 3 m of the gap's
    # middle line y = 150, 11 m from either wall
    between = airborne[(airborne["x"] > 80) & (airborne["x"] < 112)]
    assert len(between) and np.abs(between["y"] - 150.0).max() < 3.0
    assert "fig_site.png" in flight.report["figures"]  # the flight drawn over its site


@pytest.mark.ardupilot
@pytest.mark.skipif(BUILD is None, reason="ARDUPILOT_SITL does not name an ArduCopter SITL binary")
def test_the_site_mission_flies_three_stock_arducopters(tmp_path: Path) -> None:
    """The same mission flown by `gcs-swarm run --connect-only` against three real `arducopter` processes at
    the mission's starts (about three minutes of wall time: a real vehicle needs ~45 s before GPS)."""
    assert BUILD is not None
    data = numbers(yaml.safe_load(MISSION.read_text()))
    base = free_udp_base(3)
    for k, vehicle in enumerate(data["vehicles"]):
        vehicle["connection"] = f"udpin:127.0.0.1:{base + k}"
    data["world"]["import"] = [str(MISSIONS / name) for name in data["world"]["import"]]
    # fly the vehicles that are running; a real SITL needs 60-70 s from boot to pass pre-arm
    data["run"].update(
        time_limit_s=300, preflight_timeout_s=180, takeoff_timeout_s=60, simulator={"embedded": False}
    )
    path = tmp_path / "cmac_site.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    mission = load_mission(path)
    procs = start_vehicles(mission, BUILD, tmp_path / "vehicles")
    try:
        cmd = [
            sys.executable,
            "-m",
            "gcs_swarm",
            "run",
            str(path),
            "--connect-only",
            "--out",
            str(tmp_path / "run"),
        ]
        proc = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=600)
    finally:
        stop_vehicles(procs)
    assert proc.returncode == 0, (proc.stdout + proc.stderr)[-3000:]
    # no simulator of ours: the vehicles' own position reports (the run's record) are the positions
    record = np.genfromtxt(
        tmp_path / "run" / "record.csv", delimiter=",", names=True, dtype=None, encoding=None
    )
    flying = record[record["phase"] == "formation"]
    _check_flight(mission, tmp_path / "run", np.column_stack([flying["x"], flying["y"], flying["z"]]))
