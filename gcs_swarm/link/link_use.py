"""The ground station's link budget: MAVLink bytes per second each way on each vehicle's connection, measured
over windows of vehicle time, against the mission's budget (world.link.budget_bps), and what the vehicle's
radio says of its load in RADIO_STATUS (docs/mission-schema.md "link.budget_bps").

The bytes are counted where packets already pass, one integer add each (channel.LinkStats.bytes_sent and
bytes_received: Channel._transmit, Network.accept, the intake kernel's taken telemetry, the packets a
read-write forward routes to a vehicle); framing and signature included, as on the wire. `LinkUse.sample`
runs once per WINDOW_MS of the fleet's vehicle clock (Fleet.pump compares one integer) and turns the counters
into rates: up = ground station to vehicle, down = vehicle to ground station, bytes/s of vehicle time (in
lockstep the simulated second a radio would carry them in).

RADIO_STATUS (a SiK radio's report, sysid 51 compid 68, once a second: rssi, remrssi, noise, remnoise,
rxerrors, fixed, txbuf) carries no capacity: the budget cannot be read from it. txbuf, the free share (%) of
the reporting radio's transmit buffer, shows overload instead: ArduPilot slows its streams when it falls below
TXBUF_LOW and speeds them up again above TXBUF_RECOVERED (GCS_Common.cpp GCS_MAVLINK::handle_radio_status);
the same thresholds make events here.

Each window also measures the downlink, which is what overflows on a slow radio (docs/command-modes.md):
the rate at which GLOBAL_POSITION_INT arrived (`position_hz`, against the rate asked for) and the telemetry's
age at the window's end (`age_s`: the vehicle's newest time_boot_ms minus its latest position's; in lockstep
the simulator's clock ticks bypass the radio, so queueing on the air shows as age). command_mode's
CommandModeWatch reads them.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from gcs_swarm.link.vehicle import VehicleLink

WINDOW_MS = 1000  # vehicle ms per measurement window
TXBUF_LOW = 50  # % free in the radio's transmit buffer below which it cannot carry what it is given
TXBUF_RECOVERED = 90  # % free above which the radio has caught up again
UP, DOWN = 0, 1  # columns of the (N, 2) rate arrays: ground station -> vehicle, vehicle -> ground station


class LinkUse:
    """Bytes/s each way per vehicle of `links` (row i = links[i]) over windows of WINDOW_MS vehicle ms, their
    mean and peak, and events when a window's up + down goes over `budget_bps` (bit/s, 8 bits a byte; None:
    no budget) or the radio's txbuf falls below TXBUF_LOW. `rate` (N, 2) B/s up, down of the latest window
    (NaN before the first); `events`: "t=T s name: text" lines for flight.json (the same text goes to each
    link's events, which the console shows)."""

    def __init__(self, links: Sequence[VehicleLink], budget_bps: float | None = None) -> None:
        self.links = links
        self.budget_bps = budget_bps
        n = len(links)
        self.next_ms = 0  # fleet clock ms at which `sample` is due
        self.rate = np.full((n, 2), math.nan)
        self.peak = np.zeros((n, 2))
        self.over_s = np.zeros(n)  # vehicle s of windows over the budget
        self.events: list[str] = []
        self._first: tuple[int, np.ndarray] | None = None  # (clock ms, bytes (N, 2)) of the first sample
        self._last: tuple[int, np.ndarray] | None = None
        self._over = np.zeros(n, dtype=bool)
        self._txbuf_low = np.zeros(n, dtype=bool)
        self.windows = 0  # windows closed (rates measured) so far
        self.position_hz = np.full(n, math.nan)  # (N,) GLOBAL_POSITION_INT received per s, latest window
        self.age_s = np.full(n, math.nan)  # (N,) s, telemetry age at the latest window's end (NaN: none)
        self._positions = np.zeros(n, dtype=np.int64)  # position_count at the last sample

    @property
    def budget_B_s(self) -> float | None:
        """The budget in bytes/s, up and down together (None: none)."""
        return None if self.budget_bps is None else self.budget_bps / 8.0

    def _counters(self) -> np.ndarray:
        return np.array(
            [(link.channel.stats.bytes_sent, link.channel.stats.bytes_received) for link in self.links],
            dtype=np.int64,
        ).reshape(len(self.links), 2)

    def sample(self, clock_ms: int) -> None:
        """Close the window ending at fleet clock `clock_ms` (Fleet.pump calls it once clock_ms >= next_ms):
        its rates, the peaks, the budget and radio events."""
        counts = self._counters()
        st = self.links[0].state if self.links else None
        rows = [link.index for link in self.links]
        positions = np.zeros(0, dtype=np.int64) if st is None else st.position_count[rows].astype(np.int64)
        self.next_ms = clock_ms + WINDOW_MS
        if self._last is None:
            self._first = self._last = (clock_ms, counts)
            self._positions = positions
            return
        t_last, last = self._last
        span_s = (clock_ms - t_last) / 1000.0
        self._last = (clock_ms, counts)
        if span_s <= 0:
            return
        self.rate = (counts - last) / span_s
        self.windows += 1
        self.position_hz = (positions - self._positions) / span_s
        self._positions = positions
        if st is not None:
            heard = st.position_ms[rows] >= 0
            self.age_s = np.where(heard, (st.time_ms[rows] - st.position_ms[rows]) / 1000.0, math.nan)
        np.maximum(self.peak, self.rate, out=self.peak)
        budget = self.budget_B_s
        if budget is not None:
            over = self.rate.sum(axis=1) > budget
            self.over_s[over] += span_s
            for k in np.flatnonzero(over != self._over):
                up, down = self.rate[k]
                text = (
                    f"link use {up:.0f} B/s up + {down:.0f} B/s down over its budget of {budget:.0f} B/s "
                    f"({self.budget_bps:g} bit/s)"
                    if over[k]
                    else f"link use back within its budget of {budget:.0f} B/s"
                )
                self._event(int(k), text)
            self._over = over
        for i, link in enumerate(self.links):
            txbuf = link.radio.txbuf
            if txbuf is None:
                continue
            if not self._txbuf_low[i] and txbuf < TXBUF_LOW:
                self._txbuf_low[i] = True
                self._event(i, f"radio transmit buffer {txbuf}% free: the link carries less than it is given")
            elif self._txbuf_low[i] and txbuf > TXBUF_RECOVERED:
                self._txbuf_low[i] = False
                self._event(i, f"radio transmit buffer {txbuf}% free again")

    def fleet_event(self, text: str) -> float:
        """An event of the whole fleet (e.g. a change of command mode): every link's events (the console)
        and `events` ("t=T s text", T the newest vehicle time); T, s."""
        for link in self.links:
            link.add_event(text)
        t_s = max(max((int(link.state.time_ms[link.index]) for link in self.links), default=0), 0) / 1000.0
        self.events.append(f"t={t_s:.2f} s {text}")
        return t_s

    def _event(self, i: int, text: str) -> None:
        link = self.links[i]
        link.add_event(text)
        t_s = max(int(link.state.time_ms[i]), 0) / 1000.0
        self.events.append(f"t={t_s:.2f} s {link.name}: {text}")

    def summary(self) -> dict[str, dict[str, Any]]:
        """flight.json `link_use`, per vehicle name: mean and peak bytes/s up and down over the windows
        measured (mean: bytes over the vehicle time between the first and the last window's end), the bytes,
        that time, the budget in bytes/s, the time over it, and the RADIO_STATUS summary (None: none)."""
        out: dict[str, dict[str, Any]] = {}
        span_s = 0.0
        bytes_ = np.zeros((len(self.links), 2), dtype=np.int64)
        if self._first is not None and self._last is not None:
            span_s = (self._last[0] - self._first[0]) / 1000.0
            bytes_ = self._last[1] - self._first[1]
        measured = span_s > 0
        for i, link in enumerate(self.links):
            out[link.name] = {
                "up_mean_B_s": round(float(bytes_[i, UP]) / span_s, 1) if measured else None,
                "up_peak_B_s": round(float(self.peak[i, UP]), 1) if measured else None,
                "down_mean_B_s": round(float(bytes_[i, DOWN]) / span_s, 1) if measured else None,
                "down_peak_B_s": round(float(self.peak[i, DOWN]), 1) if measured else None,
                "bytes_up": int(bytes_[i, UP]),
                "bytes_down": int(bytes_[i, DOWN]),
                "measured_s": round(span_s, 3),
                "budget_B_s": self.budget_B_s,
                "over_budget_s": round(float(self.over_s[i]), 3),
                "radio_status": link.radio.summary(),
            }
        return out
