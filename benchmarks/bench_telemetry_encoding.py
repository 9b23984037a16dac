"""Cost of the simulator's per-frame telemetry encoding: ATTITUDE and GLOBAL_POSITION_INT of every vehicle at
one 50 Hz frame end, in process (no sockets), us per message, old path vs new path.

new: TelemetryView.encode as the simulator calls it (sitl_sim/network/streams.py): the fleet's payloads packed
     at once (numpy, in wire order), then each vehicle's header and CRC (Framer.frame_payload).
old: the per-vehicle path of commit ffa5f5b, reproduced below: the fleet arrays as Python lists, each
     message's fields rounded and packed one vehicle at a time, then framed (Framer.frame's body as a plain
     function here: if anything a little faster than the original method).

Each frame builds a fresh TelemetryView (a new instant: every fleet array is computed again) and encodes the
2 N messages in the simulator's order (vehicle, then ATTITUDE before GLOBAL_POSITION_INT). Both paths are
checked to give the same bytes before they are timed; old and new alternate within each repeat. Prints the
median and the spread (min..max) over the repeats.

    python benchmarks/bench_telemetry_encoding.py [--vehicles 200] [--repeats 5] [--frames 250]
"""

from __future__ import annotations

import argparse
import math
import statistics
import struct
import time
from collections.abc import Callable
from functools import cached_property

import numpy as np
from fastcrc.crc16 import mcrf4xx
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from sitl_sim.autopilot.copter import Autopilot
from sitl_sim.clock import plan_timing
from sitl_sim.network.streams import Framer, Geodesy, TelemetryView, ned_telemetry
from sitl_sim.simulator import SimConfig, Simulator
from sitl_sim.world import Obstacles
from swarm_common.ports import free_udp_base
from swarm_common.rotations import euler_to_quaternion

FRAME_US = 20_000  # 50 Hz
STREAMS = (mavlink2.MAVLINK_MSG_ID_ATTITUDE, mavlink2.MAVLINK_MSG_ID_GLOBAL_POSITION_INT)


# --- the old per-vehicle path (commit ffa5f5b) -------------------------------------------------------------

HEADER, CRC = struct.Struct("<BBBBBBBHB"), struct.Struct("<H")


def old_frame(mav: mavlink2.MAVLink, cls: type[mavlink2.MAVLink_message], *values: float) -> bytes:
    """Framer.frame of ffa5f5b: pack the field values, truncate, header, CRC."""
    payload = cls.unpacker.pack(*values).rstrip(b"\0") or b"\0"
    header = HEADER.pack(
        253, len(payload), 0, 0, mav.seq, mav.srcSystem, mav.srcComponent, cls.id & 0xFFFF, cls.id >> 16
    )
    mav.seq = (mav.seq + 1) % 256
    body = header + payload
    return body + CRC.pack(mcrf4xx(body[1:] + bytes((cls.crc_extra,)), 0xFFFF))


class OldView:
    """TelemetryView of ffa5f5b for these two streams: fleet arrays as Python lists, computed on first use."""

    def __init__(self, autopilot: Autopilot, time_us: int, geodesy: Geodesy) -> None:
        self.ap = autopilot
        self.time_boot_ms = time_us // 1000
        self.geodesy = geodesy

    @cached_property
    def ned(self) -> list[list[float]]:
        state = self.ap.state
        return ned_telemetry(state.pos, state.vel, state.quat, state.omega, self.ap.origin).tolist()

    @cached_property
    def global_position(self) -> tuple[list, list, list, list]:
        geodetic = self.geodesy.to_geodetic(self.ap.state.pos) * np.array([1e7, 1e7, 1000.0])
        rel = (self.ap.state.pos[:, 2] - self.ap.home[:, 2]) * 1000.0
        lat, lon, alt = np.round(geodetic).astype(np.int64).T.tolist()
        return lat, lon, alt, np.round(rel).astype(np.int64).tolist()

    def encode(self, mav: mavlink2.MAVLink, msg_id: int, i: int) -> bytes | None:
        return OLD_ENCODERS[msg_id](self, mav, i)


def old_attitude(v: OldView, mav: mavlink2.MAVLink, i: int) -> bytes:
    return old_frame(mav, mavlink2.MAVLink_attitude_message, v.time_boot_ms, *v.ned[i][4:10])


def old_global_position(v: OldView, mav: mavlink2.MAVLink, i: int) -> bytes | None:
    if not v.ap.position_ok(i):
        return None
    lat, lon, alt, rel = v.global_position
    row = v.ned[i]
    hdg = round(math.degrees(row[6]) * 100.0) % 36000
    vn, ve, vd = (max(-32768, min(32767, round(c * 100.0))) for c in row[13:16])
    return old_frame(
        mav, mavlink2.MAVLink_global_position_int_message, v.time_boot_ms, lat[i], lon[i], alt[i], rel[i],
        vn, ve, vd, hdg,
    )  # fmt: skip


OLD_ENCODERS: dict[int, Callable[[OldView, mavlink2.MAVLink, int], bytes | None]] = {
    mavlink2.MAVLINK_MSG_ID_ATTITUDE: old_attitude,
    mavlink2.MAVLINK_MSG_ID_GLOBAL_POSITION_INT: old_global_position,
}


# --- the measurement ---------------------------------------------------------------------------------------


def flying_fleet(n: int) -> Simulator:
    """n airborne vehicles (position estimate ready) in varied states: within 2 km, up to 20 m/s, any
    heading, tilted up to 0.4 rad, turning."""
    rng = np.random.default_rng(0)
    pos = np.column_stack((rng.uniform(-2000.0, 2000.0, (n, 2)), rng.uniform(5.0, 120.0, n)))
    config = SimConfig(
        base_port=free_udp_base(n), bind="127.0.0.1", sysid_base=1,
        timing=plan_timing(1000.0, 100.0, None, 50.0), speedup=1.0, lockstep=False, lockstep_timeout=5.0,
        lockstep_delay=1, home=(-35.36, 149.16, 584.0),
        start_pos=pos, start_vel=np.zeros((n, 3)), start_yaw=np.zeros(n),
        obstacles=Obstacles(np.zeros((0, 3)), np.zeros(0), np.zeros((0, 3))), wind=(0.0, 0.0, 0.0),
        truth_log=None, seed=0, ready_delay=0.0,
    )  # fmt: skip
    sim = Simulator(config)
    state = sim.autopilot.state
    state.vel[:] = rng.uniform(-20.0, 20.0, (n, 3))
    euler = np.column_stack((rng.uniform(-0.4, 0.4, (n, 2)), rng.uniform(-np.pi, np.pi, n)))
    state.quat[:] = euler_to_quaternion(euler)
    state.omega[:] = rng.uniform(-1.0, 1.0, (n, 3))
    return sim


def encode_frame(view: TelemetryView | OldView, senders: list, n: int) -> list[bytes | None]:
    """The 2 n messages of one frame, in the simulator's order."""
    return [view.encode(senders[i], msg_id, i) for i in range(n) for msg_id in STREAMS]


def time_path(sim: Simulator, old: bool, frames: int) -> float:
    """Wall us per message over `frames` frames, each a fresh view at its own instant."""
    n, ap, geodesy = sim.autopilot.n, sim.autopilot, sim.geodesy
    framers = [Framer(int(sysid), 1) for sysid in sim.sysids]
    senders = [f.mav for f in framers] if old else framers
    start = time.perf_counter()
    for k in range(frames):
        t = k * FRAME_US
        view = OldView(ap, t, geodesy) if old else TelemetryView(ap, t, geodesy, 0)
        encode_frame(view, senders, n)
    return (time.perf_counter() - start) / (frames * n * len(STREAMS)) * 1e6


def check_same_bytes(sim: Simulator) -> None:
    """Both paths frame the same packets (same sequence numbers too) over a few frames."""
    n, ap, geodesy = sim.autopilot.n, sim.autopilot, sim.geodesy
    old_senders = [mavlink2.MAVLink(None, srcSystem=int(s), srcComponent=1) for s in sim.sysids]
    new_senders = [Framer(int(s), 1) for s in sim.sysids]
    for k in range(300):  # past a sequence number wrap
        t = k * FRAME_US
        old = encode_frame(OldView(ap, t, geodesy), old_senders, n)
        new = encode_frame(TelemetryView(ap, t, geodesy, 0), new_senders, n)
        assert old == new, f"frame {k}: the paths differ"


def spread(values: list[float]) -> str:
    return f"{statistics.median(values):6.3f} ({min(values):.3f}..{max(values):.3f})"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--vehicles", type=int, nargs="+", default=[200])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--frames", type=int, default=250, help="frames timed per path and repeat")
    args = parser.parse_args()
    print(f"ATTITUDE + GLOBAL_POSITION_INT per 50 Hz frame, {args.frames} frames x {args.repeats} repeats")
    columns = ("old us/msg, median (min..max)", "new us/msg, median (min..max)")
    print(f"{'N':>4}  {columns[0]:>30}  {columns[1]:>30}  {'old/new':>7}")
    for n in args.vehicles:
        sim = flying_fleet(n)
        try:
            check_same_bytes(sim)
            old, new = [], []
            for _ in range(args.repeats):
                old.append(time_path(sim, True, args.frames))
                new.append(time_path(sim, False, args.frames))
        finally:
            sim.close()
        ratio = statistics.median(old) / statistics.median(new)
        print(f"{n:>4}  {spread(old):>30}  {spread(new):>30}  {ratio:>7.2f}", flush=True)


if __name__ == "__main__":
    main()
