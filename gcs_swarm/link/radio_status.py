"""What a vehicle's radio says of itself: the RADIO_STATUS reports heard on its connection (a SiK radio sends
one a second from sysid 51, compid 68; SiK Firmware/radio/mavlink.c MAVLink_report), kept for link.link_use.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from gcs_swarm.link.connection import MAVLinkMessage


@dataclass
class RadioStatus:
    """The RADIO_STATUS reports heard on one vehicle's connection: how many, the latest fields (MAVLink
    units: rssi/noise in the radio's own units, txbuf % free, rxerrors/fixed counts) and the lowest txbuf."""

    reports: int = 0
    rssi: int | None = None
    remrssi: int | None = None
    noise: int | None = None
    remnoise: int | None = None
    rxerrors: int | None = None
    fixed: int | None = None
    txbuf: int | None = None
    min_txbuf: int | None = None

    def update(self, msg: MAVLinkMessage) -> None:
        """A RADIO_STATUS arrived."""
        self.reports += 1
        self.rssi, self.remrssi = int(msg.rssi), int(msg.remrssi)
        self.noise, self.remnoise = int(msg.noise), int(msg.remnoise)
        self.rxerrors, self.fixed, self.txbuf = int(msg.rxerrors), int(msg.fixed), int(msg.txbuf)
        self.min_txbuf = self.txbuf if self.min_txbuf is None else min(self.min_txbuf, self.txbuf)

    def summary(self) -> dict[str, int | None] | None:
        """For flight.json: the count, the latest fields and the lowest txbuf; None when none was heard."""
        if not self.reports:
            return None
        return {
            "reports": self.reports,
            "txbuf_min_pct": self.min_txbuf,
            "txbuf_last_pct": self.txbuf,
            "rssi": self.rssi,
            "remrssi": self.remrssi,
            "noise": self.noise,
            "remnoise": self.remnoise,
            "rxerrors": self.rxerrors,
            "fixed": self.fixed,
        }
