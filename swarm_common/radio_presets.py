"""Radios a simulated link can be: capacity, bytes on the air, buffer, duplex (docs/radio.md).

A `RadioSpec` is what the simulator's radio model (sitl_sim.network.radio) needs to time and drop packets;
`RADIO_PRESETS` names common radios, each figure derived in docs/radio.md from the source written beside it.
Both programs read this table: the mission checks a `world.link.radio` name and its overrides here, the
simulator models the radio. `radio_spec` is the one rule that turns a preset name and overrides into a spec.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass


@dataclass(frozen=True)
class RadioSpec:
    """One radio link (a pair of radios, or every vehicle and the ground on one medium when `shared`).

    A packet of L bytes (its MAVLink bytes as sent: framing and signature included; uplink: the ground
    station's whole datagram) occupies the air for
        (L + overhead_bytes) * bits_per_byte / capacity_bps  s  +  overhead_us  us      (docs/radio.md eq. 1)
    and waits behind every packet that entered the same medium before it (one FIFO time line per medium; one
    for both directions when half duplex, one per direction otherwise). Each transmitting radio (the
    vehicle's for the downlink, the ground radio for the uplink: one for the whole swarm when `shared`) holds
    at most buffer_bytes of packets not yet on the air; a packet that does not fit is dropped.
    """

    capacity_bps: float  # bit/s of air time, > 0
    bits_per_byte: float = 8.0  # bit times on the air per byte of packet (serial 8N1, radio framing, ECC)
    overhead_bytes: int = 0  # bytes the radio adds to each packet (headers, trailers, checksums)
    overhead_us: float = 0.0  # air time of each packet besides its bytes (preamble, gaps, backoff, ACK), us
    half_duplex: bool = False  # up and down share one air time line
    shared: bool = False  # every vehicle and the ground station share one medium (and one ground radio)
    buffer_bytes: int = 0  # bytes each transmitting radio buffers; 0: one second at capacity_bps / 8
    radio_status: bool = False  # the ground radio sends RADIO_STATUS (sysid 51, compid 68) once a second
    source: str = ""  # where the figures come from (docs/radio.md has the derivation)

    @property
    def buffer_limit(self) -> int:
        """Bytes each transmitting radio buffers (buffer_bytes, or one second of capacity when 0)."""
        return self.buffer_bytes or max(1, int(self.capacity_bps / 8))

    def air_time_ns(self, size: int) -> int:
        """Air time of a packet of `size` bytes, ns (docs/radio.md eq. 1, rounded to the ns)."""
        bits = (size + self.overhead_bytes) * self.bits_per_byte
        return round(bits * 1e9 / self.capacity_bps + self.overhead_us * 1e3)


# SiK (ArduPilot/SiK Firmware/radio): tdm.c tdm_init times a byte and a packet from AIR_SPEED; at saturation
# in both directions it moves 741 bytes per transmit window of each radio (docs/radio.md derives 10.2, 11.4
# and 13.5 bit times per byte at 64, 128 and 250 kbit/s); serial.c RX_BUFF_MAX 1850 bytes (Si1000) is the
# buffer of bytes waiting to go on the air, whose free share mavlink.c reports as RADIO_STATUS.txbuf.
_SIK_SOURCE = (
    "ArduPilot SiK firmware: parameters.c (AIR_SPEED 64 default, SERIAL_SPEED 57, ECC 0), tdm.c tdm_init "
    "(ticks_per_byte, packet_latency, window), serial.c RX_BUFF_MAX 1850, mavlink.c MAVLink_report; "
    "https://github.com/ArduPilot/SiK, https://ardupilot.org/copter/docs/common-sik-telemetry-radio.html"
)
# 802.11 OFDM timing, IEEE 802.11-2016 clauses 17-19: per packet DIFS + mean backoff + preamble + SIFS + ACK
_WIFI_SOURCE = (
    "IEEE Std 802.11-2016 clause 18/19 (ERP-OFDM, 2.4 GHz): 24 Mbit/s data rate, slot 9 us, SIFS 10 us, "
    "DIFS 28 us, mean backoff CWmin 15 -> 67.5 us, preamble 20 us + signal extension 6 us, ACK 34 us; "
    "MAC header 24 + FCS 4 + LLC/SNAP 8 + IPv4 20 + UDP 8 bytes; buffer: Linux net.core.wmem_default "
    "212992 bytes (https://www.kernel.org/doc/html/latest/admin-guide/sysctl/net.html)"
)
_MESH_SOURCE = (
    "802.11s-style mesh radio (Doodle Labs Mesh Rider / Microhard pMDDL-like) at the edge of its range: "
    "IEEE Std 802.11-2016 clause 19 HT MCS0 20 MHz 6.5 Mbit/s, 5 GHz slot 9 us, SIFS 16 us, DIFS 34 us, mean "
    "backoff 67.5 us, HT-mixed preamble 36 us, ACK at 6 Mbit/s 44 us; 4-address QoS MAC header 32 + mesh "
    "control 6 + FCS 4 + LLC/SNAP 8 + IPv4 20 + UDP 8 bytes; one hop (no relay)"
)
RADIO_PRESETS: dict[str, RadioSpec] = {
    "sik64": RadioSpec(64000.0, 10.2, 0, 0.0, True, False, 1850, True, _SIK_SOURCE),
    "sik128": RadioSpec(128000.0, 11.4, 0, 0.0, True, False, 1850, True, _SIK_SOURCE),
    "sik250": RadioSpec(250000.0, 13.5, 0, 0.0, True, False, 1850, True, _SIK_SOURCE),
    "wifi": RadioSpec(24e6, 8.0, 64, 165.5, True, True, 212992, False, _WIFI_SOURCE),
    "mesh": RadioSpec(6.5e6, 8.0, 78, 197.5, True, True, 212992, False, _MESH_SOURCE),
}
# the keys of world.link / --link-* that override a preset's figure (RadioSpec's fields but its source)
RADIO_OVERRIDES = tuple(f.name for f in dataclasses.fields(RadioSpec) if f.name != "source")
# each numeric setting's accepted range (inclusive) and unit, as errors name them (here and in the mission)
RADIO_RANGES: dict[str, tuple[float, float, str]] = {
    "capacity_bps": (1.0, 1e11, "bit/s"),
    "bits_per_byte": (1.0, 100.0, ""),
    "overhead_bytes": (0, 65535, "bytes"),
    "overhead_us": (0.0, 1e6, "us"),
    "buffer_bytes": (0, 2**31 - 1, "bytes (0: one second of capacity)"),
}


class RadioError(ValueError):
    """A radio setting that cannot be: `key` (a RADIO_OVERRIDES name, or "radio") and one sentence."""

    def __init__(self, key: str, sentence: str) -> None:
        super().__init__(sentence)
        self.key = key


def radio_spec(name: str | None, overrides: dict[str, object]) -> RadioSpec | None:
    """The radio named `name` (a RADIO_PRESETS key; None: no preset) with `overrides` (RADIO_OVERRIDES keys
    whose values are not None) applied; None when neither a name nor an override is given (an ideal link).

    RadioError (one sentence, and the key it is about) for an unknown name or key, a value of the wrong type
    or out of its range, or overrides without a preset and without capacity_bps (nothing to take the capacity
    from)."""
    given = {key: value for key, value in overrides.items() if value is not None}
    for key, value in given.items():
        if key not in RADIO_OVERRIDES:
            raise RadioError(key, f"unknown radio setting {key!r} (settings: {', '.join(RADIO_OVERRIDES)})")
        if key in ("half_duplex", "shared", "radio_status"):
            if not isinstance(value, bool):
                raise RadioError(key, f"{key} must be true or false, not {value!r}")
            continue
        integer = key in ("overhead_bytes", "buffer_bytes")
        if isinstance(value, bool) or not isinstance(value, int if integer else (int, float)):
            kind = "a whole number" if integer else "a number"
            raise RadioError(key, f"{key} must be {kind}, not {value!r}")
        low, high, unit = RADIO_RANGES[key]
        if not (math.isfinite(value) and low <= value <= high):
            raise RadioError(key, f"{key} must be in {low:g}..{high:g} {unit}, not {value:g}".rstrip())
    if name is None:
        if not given:
            return None
        if "capacity_bps" not in given:
            keys = ", ".join(sorted(given))
            raise RadioError(sorted(given)[0], f"{keys} without a radio preset needs capacity_bps")
        return RadioSpec(**{"source": "given", **given})  # type: ignore[arg-type]
    if name not in RADIO_PRESETS:
        raise RadioError("radio", f"unknown radio {name!r} (presets: {', '.join(RADIO_PRESETS)})")
    return dataclasses.replace(RADIO_PRESETS[name], **given)  # type: ignore[arg-type]
