"""The ground station knows its link budget (issue 38 item 2), end to end: the quickstart flown by the real
`gcs-swarm run` against the real simulator in lockstep, with `world.link.budget_bps` far below what the
ground station's streams need. flight.json and report.json carry each vehicle's measured bytes/s each way,
and going over the budget is an event; the flight itself is unchanged by the budget (exit status 0)."""

from __future__ import annotations

import json
from pathlib import Path

from tests.e2e.flights import derived_mission, fly

BUDGET_BPS = 8000.0  # bit/s: 1000 bytes/s up and down together
RATE_HZ = 50  # the quickstart's control rate: SET_ATTITUDE_TARGET and both telemetry streams at 50 Hz
# Lower bounds on the wire (MAVLink 2 framing 12 bytes; trailing zero payload bytes cut, so only the fields
# that cannot be zero count): SET_ATTITUDE_TARGET time_boot_ms, q, three body rates, thrust (36 bytes) and a
# non-zero target_system: 37 + 12 = 49 bytes. GLOBAL_POSITION_INT up to alt (584 m AMSL, offset 12..16):
# 16 + 12 = 28; ATTITUDE up to yaw (offset 12..16): 28. Each per 1/RATE_HZ s.
UP_FLOOR_B_S = RATE_HZ * 49
DOWN_FLOOR_B_S = RATE_HZ * (28 + 28)


def test_link_use_is_measured_and_going_over_the_budget_is_an_event(tmp_path: Path) -> None:
    mission = derived_mission(
        tmp_path,
        "quickstart.yaml",
        "budget",
        # attitude targets forced: the streams of today, far over the budget (else position targets)
        world={"link": {"budget_bps": BUDGET_BPS, "command_mode": "attitude"}},
    )
    run = fly(mission, tmp_path / "run", timeout_s=400)
    assert "Traceback" not in run.output, run.output[-3000:]
    assert run.status == 0, run.output[-3000:]
    flight = json.loads((run.run_dir / "flight.json").read_text())
    use = flight["link_use"]
    assert set(use) == {"lead", "right", "left"}
    for name, figures in use.items():
        assert figures["budget_B_s"] == BUDGET_BPS / 8
        assert figures["down_peak_B_s"] >= DOWN_FLOOR_B_S, (name, figures)
        assert figures["up_peak_B_s"] >= UP_FLOOR_B_S, (name, figures)  # in formation flight
        assert figures["up_mean_B_s"] <= figures["up_peak_B_s"]
        assert figures["down_mean_B_s"] <= figures["down_peak_B_s"]
        # the means are bytes over the time measured (rounded to 0.1 B/s)
        error = abs(figures["down_mean_B_s"] * figures["measured_s"] - figures["bytes_down"])
        assert error <= 0.05 * figures["measured_s"] + 1e-6
        assert figures["over_budget_s"] > 10.0
        assert figures["radio_status"] is None  # no radio in this world
        over = [
            e for e in flight["events"] if f"s {name}: link use" in e and "over its budget of 1000 B/s" in e
        ]
        assert over, flight["events"]
    report = json.loads((run.run_dir / "report.json").read_text())
    assert report["link_use"] == use
    assert "Link use, MAVLink bytes/s" in (run.run_dir / "report.md").read_text()


SIK64_B_S = 64000 / 10.2  # bytes/s a SiK pair at 64 kbit/s carries, up and down together (docs/radio.md)
SIK_BUFFER_B = 1850  # bytes each transmitting SiK radio buffers (serial.c RX_BUFF_MAX, docs/radio.md)


def test_over_a_sik_radio_the_use_is_at_most_its_capacity_and_radio_status_is_heard(tmp_path: Path) -> None:
    """The quickstart behind the simulator's SiK 64 kbit/s radio (half duplex, RADIO_STATUS once a second),
    with the budget set to what that radio carries (64000 / 10.2 bytes/s, as 8-bit bits). Whatever the flight
    makes of such a link (issue 38: it does not get airborne), each vehicle's measured up + down over the
    flight cannot exceed the radio's capacity (plus what its two buffers held at the end), its ground radio's
    RADIO_STATUS reports are kept, and the streams the ground station asks for fill the radio: over budget."""
    mission = derived_mission(
        tmp_path,
        "quickstart.yaml",
        "sik",
        # attitude targets forced: the streams of today, which overfill the radio (else position targets)
        world={"link": {"budget_bps": SIK64_B_S * 8, "command_mode": "attitude"}},
    )
    run = fly(mission, tmp_path / "run", timeout_s=400, extra=["--sim-arg=--link-radio=sik64"])
    assert "Traceback" not in run.output, run.output[-3000:]
    flight = json.loads((run.run_dir / "flight.json").read_text())
    for name, figures in flight["link_use"].items():
        total = figures["bytes_up"] + figures["bytes_down"]
        assert total / figures["measured_s"] <= SIK64_B_S + 2 * SIK_BUFFER_B / figures["measured_s"], figures
        radio = figures["radio_status"]
        # one report a simulated second while the ground station listens (it measures from connect)
        assert radio is not None and radio["reports"] >= figures["measured_s"] - 5, radio
        assert 0 <= radio["txbuf_min_pct"] <= 100
        assert figures["over_budget_s"] > 0, figures
        assert any(f"s {name}: link use" in e for e in flight["events"]), flight["events"]
