"""The quickstart flown through the simulator's radio model (docs/radio.md), set in the mission's world.link:
over a wide radio it flies as over loopback; over an absurdly narrow one the radio's counters show drops."""

from __future__ import annotations

import re
from pathlib import Path

from tests.e2e.flights import derived_mission, fly


def _counts(run_dir: Path, name: str) -> list[int]:
    """Each vehicle's counter `name` from the simulator's exit lines (simulator.log)."""
    return [int(n) for n in re.findall(rf"{name}=(\d+)", (run_dir / "simulator.log").read_text())]


def test_quickstart_over_a_wide_radio_reaches_and_a_narrow_one_drops(tmp_path: Path) -> None:
    """1 Mbit/s half duplex per vehicle carries the quickstart's traffic (some 38 kbit/s down, 13 up per
    vehicle) with room to spare: reached, no collision, nothing dropped. At 2 kbit/s (250 bytes/s, less than
    one 50 Hz telemetry stream) the radios' buffers overflow both ways; the run ends without a traceback."""
    wide = derived_mission(
        tmp_path,
        "quickstart.yaml",
        "radio_wide",
        world={"link": {"capacity_bps": 1.0e6, "half_duplex": True}},
    )
    run = fly(wide, tmp_path / "wide", timeout_s=400)
    assert run.status == 0, run.output[-2000:]
    assert run.report["reached"] and run.report["collisions"] == 0
    assert len(_counts(run.run_dir, "radio_down_packets")) == 3
    assert _counts(run.run_dir, "radio_down_dropped") == [0, 0, 0] == _counts(run.run_dir, "radio_up_dropped")
    narrow = derived_mission(
        tmp_path,
        "quickstart.yaml",
        "radio_narrow",
        # attitude targets forced: a budget of 250 B/s carries no command mode, the flight would be refused
        world={"link": {"capacity_bps": 2000.0, "half_duplex": True, "command_mode": "attitude"}},
    )
    run = fly(narrow, tmp_path / "narrow", timeout_s=400)
    assert "Traceback" not in run.output, run.output[-2000:]
    assert (
        min(_counts(run.run_dir, "radio_down_dropped")) > 0
        and min(_counts(run.run_dir, "radio_up_dropped")) > 0
    )
