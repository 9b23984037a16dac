"""The in-flight change of command mode (link.command_mode.CommandModeWatch): the windows of measured downlink
it judges, the dwell before a step, the settling after one, the steps down and never up, the rate chosen
from what the link carried, and the telemetry asked again.

The watch reads link_use's per-window figures; here they are set by hand, window by window, on a stand-in
with the same fields (LinkUse itself is tested on sockets in test_link_use.py). Bytes each plan needs, by hand
from the wire sizes of test_command_mode.py's module doc (SET_POSITION_TARGET_GLOBAL_INT 65, HEARTBEAT 21,
ATTITUDE + GLOBAL_POSITION_INT 80, the four health messages 171 bytes at 1 Hz):
    position at r Hz: up 65 r + 21, down 80 r + 171 + 21
    10 Hz: 671 + 992 = 1663;  5 Hz: 346 + 592 = 938;  4 Hz: 281 + 512 = 793 B/s.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

from gcs_swarm.link.command_mode import (
    ATTITUDE,
    DEFAULT_STEP_DOWN,
    POSITION,
    SETTLE_WINDOWS,
    CommandModeWatch,
    CommandPlan,
    StepDown,
    command_plan,
)

AGE_MAX_S = DEFAULT_STEP_DOWN.queue_age_s  # 0.15 s (world.link.step_down.queue_age_s)
DEGRADED_WINDOWS = DEFAULT_STEP_DOWN.after_s  # 2 windows of 1 s (world.link.step_down.after_s)
FRESH_S = 0.03  # a healthy lockstep radio: one or two frames of age
QUEUED_S = 0.35  # a SiK buffer full at 64 kbit/s and more


@dataclass
class Use:
    """A LinkUse stand-in: what CommandModeWatch reads of it, set by `window`."""

    n: int
    windows: int = 0
    events: list[str] = field(default_factory=list)

    def __post_init__(self) -> None:
        self.position_hz = np.full(self.n, math.nan)
        self.age_s = np.full(self.n, math.nan)
        self.rate = np.full((self.n, 2), math.nan)

    def window(self, hz: float, age: float, carried: float = 6000.0, vehicle: int | None = None) -> None:
        """Close one window: `vehicle` (None: every one) got positions at hz Hz, age s old at its end, its
        link carrying `carried` B/s (half up, half down); the others healthy at 50 Hz."""
        self.windows += 1
        rows = range(self.n) if vehicle is None else [vehicle]
        self.position_hz[:], self.age_s[:], self.rate[:] = 50.0, FRESH_S, 1000.0
        for i in rows:
            self.position_hz[i], self.age_s[i] = hz, age
            self.rate[i] = carried / 2

    def fleet_event(self, text: str) -> float:
        """Keep the event; its time: one s of vehicle time a window."""
        self.events.append(text)
        return float(self.windows)


class Streams:
    def __init__(self) -> None:
        self.asked: list[dict[Any, float]] = []

    def ask(self, rates: dict[Any, float]) -> None:
        self.asked.append(dict(rates))


def _links(n: int, txbuf: int | None = None) -> list[Any]:
    return [
        SimpleNamespace(name=name, sysid=i + 1, radio=SimpleNamespace(txbuf=txbuf), streams=Streams())
        for i, name in enumerate(["lead", "right", "left"][:n])
    ]


def _sample(watch: CommandModeWatch, plan: CommandPlan) -> CommandPlan:
    """watch.sample, never None for a plan."""
    after = watch.sample(plan)
    assert after is not None
    return after


def _attitude_plan() -> CommandPlan:
    plan = command_plan(None, 50.0)
    assert plan.mode == ATTITUDE
    return plan


def test_healthy_windows_keep_the_paper_s_attitude_targets() -> None:
    links, use = _links(3), Use(3)
    watch = CommandModeWatch(links, use)  # type: ignore[arg-type]
    plan = _attitude_plan()
    for _ in range(20):
        use.window(50.0, FRESH_S)
        assert watch.sample(plan) is plan
    assert use.events == [] and all(link.streams.asked == [] for link in links)


def test_one_vehicle_queueing_for_the_dwell_steps_the_fleet_to_position_targets_once() -> None:
    """Age 0.35 s > AGE_MAX_S + 1/50 Hz = 0.17 s: degraded. One window short of the dwell, then a healthy
    one, clear the count; DEGRADED_WINDOWS in a row step down. The link carried 6000 B/s: half of it (3000)
    carries position targets at 10 Hz (1663 B/s, module doc), so 10 Hz."""
    assert AGE_MAX_S + 1 / 50.0 < QUEUED_S
    links, use = _links(3), Use(3)
    watch = CommandModeWatch(links, use)  # type: ignore[arg-type]
    plan = _attitude_plan()
    for _ in range(DEGRADED_WINDOWS - 1):
        use.window(40.0, QUEUED_S, vehicle=1)
        assert watch.sample(plan) is plan
    use.window(50.0, FRESH_S)
    assert watch.sample(plan) is plan
    for _ in range(DEGRADED_WINDOWS - 1):
        use.window(40.0, QUEUED_S, vehicle=1)
        assert watch.sample(plan) is plan
    use.window(40.0, QUEUED_S, vehicle=1)
    step = watch.sample(plan)
    assert step is not None
    assert (step.mode, step.setpoint_hz, step.state_hz, step.status_hz) == (POSITION, 10.0, 10.0, 1.0)
    assert (step.up_B_s, step.down_B_s) == (671.0, 992.0)
    assert use.events == [
        "command mode: position targets at 10 Hz (1663 B/s), telemetry at 10 Hz, instead of attitude targets "
        "at 50 Hz because right's telemetry was 0.35 s old (positions at 40 of 50 Hz) "
        f"for {DEGRADED_WINDOWS} s"
    ]
    for link in links:  # every vehicle asked for the slower telemetry at once
        assert link.streams.asked == [step.telemetry]
        assert link.streams.asked[0]["GLOBAL_POSITION_INT"] == 10.0
    # the step as data (flight.json command_mode_changes): the window it closed is the 2 * DEGRADED_WINDOWS-th
    # (one short, a healthy one, then the dwell), which the stand-in's clock makes that many seconds
    assert watch.changes == [
        {
            "t_s": 2.0 * DEGRADED_WINDOWS,
            "from_mode": "attitude",
            "from_hz": 50.0,
            "to_mode": "position",
            "to_hz": 10.0,
            "vehicle": "right",
            "reason": "telemetry was 0.35 s old (positions at 40 of 50 Hz)",
            "planned_up_B_s": 671.0,
            "planned_down_B_s": 992.0,
        }
    ]


def test_after_a_step_the_watch_settles_then_steps_down_rate_by_rate_and_never_back_up() -> None:
    """Position mode at r Hz: degraded above AGE_MAX_S + 1/r s (0.25 s at 10 Hz, 0.35 s at 5 Hz): 0.6 s
    is. SETTLE_WINDOWS windows after a step are not judged; then DEGRADED_WINDOWS degraded windows each step
    to the next slower rate: a link carrying 2000 B/s fits 5 Hz in its half (938 <= 1000, module doc), then
    4 Hz (the only slower one); at 4 Hz nothing is slower: said once. Healthy windows never step back up."""
    links, use = _links(2), Use(2)
    watch = CommandModeWatch(links, use)  # type: ignore[arg-type]
    plan = _attitude_plan()
    for _ in range(DEGRADED_WINDOWS):
        use.window(40.0, QUEUED_S)
        plan = _sample(watch, plan)
    assert plan.setpoint_hz == 10.0
    rates = [plan.setpoint_hz]
    for _ in range(SETTLE_WINDOWS):  # degraded, but not judged
        use.window(10.0, 0.6, carried=2000.0)
        assert watch.sample(plan) is plan
    for expected in (5.0, 4.0):
        for _ in range(DEGRADED_WINDOWS):
            use.window(plan.state_hz, 0.6, carried=2000.0)
            plan = _sample(watch, plan)
        rates.append(plan.setpoint_hz)
        assert plan.setpoint_hz == expected
        for _ in range(SETTLE_WINDOWS):
            use.window(plan.state_hz, 0.6, carried=2000.0)
            plan = _sample(watch, plan)
    assert (plan.up_B_s, plan.down_B_s) == (281.0, 512.0)  # 4 Hz, module doc
    for _ in range(2 * DEGRADED_WINDOWS):
        use.window(plan.state_hz, 0.6, carried=2000.0)
        assert watch.sample(plan) is plan
    for _ in range(30):
        use.window(50.0, FRESH_S, carried=20000.0)
        assert watch.sample(plan) is plan
    assert rates == [10.0, 5.0, 4.0]
    assert len(use.events) == 4
    # three steps as data; "the slowest, kept" is an event, not a change
    assert [(c["from_mode"], c["from_hz"], c["to_hz"]) for c in watch.changes] == [
        ("attitude", 50.0, 10.0),
        ("position", 10.0, 5.0),
        ("position", 5.0, 4.0),
    ]
    assert use.events[1].startswith("command mode: position targets at 5 Hz (938 B/s), telemetry at 5 Hz, ")
    assert "instead of position targets at 10 Hz because lead's telemetry was 0.60 s old" in use.events[1]
    assert use.events[2].startswith("command mode: position targets at 4 Hz (793 B/s)")
    # nothing slower than 4 Hz: said once, the plan kept
    assert use.events[3].startswith("command mode: position targets at 4 Hz are the slowest, kept because ")
    assert watch.exhausted


def test_a_silent_window_is_not_congestion_and_clears_the_count() -> None:
    """An outage or a reboot (no position at all) is the loss watches' business: it breaks the run of
    degraded windows."""
    links, use = _links(1), Use(1)
    watch = CommandModeWatch(links, use)  # type: ignore[arg-type]
    plan = _attitude_plan()
    for hz, age in (
        [(40.0, QUEUED_S)] * (DEGRADED_WINDOWS - 1)
        + [(0.0, 2.0)]
        + [(40.0, QUEUED_S)] * (DEGRADED_WINDOWS - 1)
    ):
        use.window(hz, age)
        assert watch.sample(plan) is plan
    assert use.events == []


def test_loss_without_queueing_is_not_congestion() -> None:
    """Positions at half their rate (loss, reordering) but fresh: no step."""
    links, use = _links(1), Use(1)
    watch = CommandModeWatch(links, use)  # type: ignore[arg-type]
    plan = _attitude_plan()
    for _ in range(10):
        use.window(25.0, FRESH_S)
        assert watch.sample(plan) is plan


def test_a_full_radio_buffer_reported_by_radio_status_is_degraded() -> None:
    """RADIO_STATUS txbuf 30 % < link_use.TXBUF_LOW (50 %): degraded even with fresh telemetry."""
    links, use = _links(1, txbuf=30), Use(1)
    watch = CommandModeWatch(links, use)  # type: ignore[arg-type]
    plan = _attitude_plan()
    for _ in range(DEGRADED_WINDOWS):
        use.window(50.0, FRESH_S)
        plan = _sample(watch, plan)
    assert plan.mode == POSITION
    assert use.events[0].endswith(f"because lead's radio buffer was 30% free for {DEGRADED_WINDOWS} s")


def test_a_forced_mode_is_kept() -> None:
    links, use = _links(1), Use(1)
    watch = CommandModeWatch(links, use)  # type: ignore[arg-type]
    plan = command_plan(None, 50.0, mode="attitude")
    for _ in range(10):
        use.window(40.0, QUEUED_S)
        assert watch.sample(plan) is plan


@pytest.mark.parametrize("still_hz", [50.0, 12.0])
def test_a_lost_stream_request_is_asked_again_while_positions_come_too_fast(still_hz: float) -> None:
    """After the step to 10 Hz: a vehicle still sending positions faster than 1.5 x 10 = 15 Hz (its request
    lost on the congested link) is asked again every window; at 12 Hz it is not."""
    links, use = _links(1), Use(1)
    watch = CommandModeWatch(links, use)  # type: ignore[arg-type]
    plan = _attitude_plan()
    for _ in range(DEGRADED_WINDOWS):
        use.window(40.0, QUEUED_S)
        plan = _sample(watch, plan)
    assert len(links[0].streams.asked) == 1
    for _ in range(3):
        use.window(still_hz, FRESH_S)
        assert watch.sample(plan) is plan
    assert len(links[0].streams.asked) == (4 if still_hz == 50.0 else 1)


def test_with_step_down_disabled_the_mode_chosen_before_take_off_is_kept() -> None:
    """world.link.step_down.enabled false: queueing and a full radio buffer change nothing."""
    links, use = _links(2, txbuf=10), Use(2)
    watch = CommandModeWatch(links, use, StepDown(enabled=False))  # type: ignore[arg-type]
    plan = _attitude_plan()
    for _ in range(10):
        use.window(40.0, QUEUED_S)
        assert watch.sample(plan) is plan
    assert use.events == [] and watch.changes == [] and all(link.streams.asked == [] for link in links)


def test_the_mission_s_queue_age_and_dwell_are_the_thresholds() -> None:
    """queue_age_s 0.4 at attitude targets at 50 Hz: degraded above 0.4 + 1/50 = 0.42 s of age, so the
    default's 0.35 s is healthy and 0.5 s is not; after_s 3: three degraded windows (of 1 s) step, two do
    not."""
    links, use = _links(1), Use(1)
    watch = CommandModeWatch(links, use, StepDown(queue_age_s=0.4, after_s=3))  # type: ignore[arg-type]
    plan = _attitude_plan()
    for _ in range(10):
        use.window(40.0, QUEUED_S)
        assert watch.sample(plan) is plan
    for _ in range(2):
        use.window(40.0, 0.5)
        assert watch.sample(plan) is plan
    use.window(40.0, 0.5)
    step = _sample(watch, plan)
    assert step.mode == POSITION
    assert use.events[0].endswith(
        "because lead's telemetry was 0.50 s old (positions at 40 of 50 Hz) for 3 s"
    )
    assert [c["t_s"] for c in watch.changes] == [13.0]  # the 13th window
