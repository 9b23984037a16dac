"""The same mission written in ENU metres and in latitude/longitude flies the same flight (issue 37): two
real lockstep flights (`gcs-swarm run` and the simulator on 127.0.0.1 free ports), ground truth compared row
by row.

The geographic mission is written from the ENU one with pymap3d.enu2geodetic, the inverse of the loader's
conversion; the positions it loads differ by nanometres, so the truth logs (0.1 mm resolution) agree within
1 cm.
"""

from __future__ import annotations

import csv
from pathlib import Path

import pymap3d
import pytest

from tests.e2e.flights import SHORT_BOOT, fly

pytestmark = pytest.mark.e2e
ORIGIN = (-35.363261, 149.165230, 584.0)
MISSION = """origin: {{lat: -35.363261, lon: 149.165230, alt: 584.0}}
run: {{time_limit_s: 120}}
vehicles:
  - {{name: lead, role: leader, start: {{position: {s0}, yaw_deg: 37}}}}
  - {{name: right, start: {{position: {s1}, yaw_deg: 37}}}}
goal: {goal}
world:
  obstacles:
    - {{center: {obstacle}, radius: 3}}
"""


def _geo(e: float, n: float, u: float, ground: bool = False) -> str:
    lat, lon, h = pymap3d.enu2geodetic(e, n, u, *ORIGIN)
    if ground:
        return f"{{lat: {float(lat)!r}, lon: {float(lon)!r}}}"
    return f"{{lat: {float(lat)!r}, lon: {float(lon)!r}, amsl: {float(h)!r}}}"


def _positions(run_dir: Path) -> list[tuple[str, str, float, float, float]]:
    with (run_dir / "truth.csv").open() as f:
        return [
            (r["t"], r["vehicle"], float(r["x"]), float(r["y"]), float(r["z"])) for r in csv.DictReader(f)
        ]


def test_enu_and_latitude_longitude_missions_fly_the_same_within_1_cm(tmp_path: Path) -> None:
    enu = tmp_path / "pair_enu.yaml"
    enu.write_text(
        MISSION.format(s0="[0, 0, 0]", s1="[-1.5, -10, 0]", goal="[40, 30, 10]", obstacle="[20, 17, 10]")
    )
    geo = tmp_path / "pair_geo.yaml"
    geo.write_text(
        MISSION.format(
            s0=_geo(0, 0, 0, ground=True),
            s1=_geo(-1.5, -10, 0, ground=True),
            goal=_geo(40, 30, 10),
            obstacle=_geo(20, 17, 10),
        )
    )
    flights = [
        fly(path, tmp_path / f"run_{path.stem}", extra=["--time-mode", "lockstep", SHORT_BOOT])
        for path in (enu, geo)
    ]
    for flight in flights:
        assert flight.status == 0, flight.output[-2000:]
        assert flight.report["reached"] and flight.report["collisions"] == 0
    a, b = (_positions(flight.run_dir) for flight in flights)
    assert len(a) == len(b) > 1000
    for row_a, row_b in zip(a, b, strict=True):
        assert row_a[:2] == row_b[:2]  # same time, same vehicle
        assert max(abs(p - q) for p, q in zip(row_a[2:], row_b[2:], strict=True)) <= 0.01
