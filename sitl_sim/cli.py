"""`sitl-sim`: the command line of the simulator (a contract other tools rely on; docs/sitl.md).

    sitl-sim --vehicles N [--base-port P=14540] [--bind 127.0.0.1] [--sysid-base 1]
             [--speedup X | --lockstep] [--rate-hz 1000] [--home LAT,LON,ALT] [--mission FILE.yaml]
             [--truth-log PATH] [--seed S]  (+ --lockstep-hz, --lockstep-timeout, --outer-hz,
             --truth-rate-hz, --ready-delay)
             [--link-loss P] [--link-delay-ms MS] [--link-jitter-ms MS] [--link-dup P] [--link-corrupt P]
             [--link-reorder P] [--link-from S] [--link-outage [I@]START:DURATION ...]
             [--link-radio NAME|none] [--link-capacity-bps B] [--link-bits-per-byte N]
             [--link-overhead-bytes N] [--link-overhead-us US] [--[no-]link-half-duplex] [--[no-]link-shared]
             [--link-buffer-bytes N] [--[no-]link-radio-status] [--link-capacity-change START:BPS ...]
             [--signing-key FILE] [--autopilot ardupilot|px4[,...]]

Prints one line per vehicle (index, sysid, UDP address), then READY, and runs until SIGINT/SIGTERM.
Bad arguments: one line "sitl-sim: error: ..." and exit status 2; a port that cannot be bound: exit 1.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import ipaddress
import logging
import math
import signal
import socket
import sys
from pathlib import Path
from typing import NoReturn

import numpy as np

from sitl_sim.autopilot.params import PARAM_NAME_RELEASES
from sitl_sim.autopilot.registry import parse_autopilots
from sitl_sim.clock import plan_timing
from sitl_sim.network.link_faults import LinkFaults, Outage, parse_outage
from sitl_sim.network.radio import parse_capacity_change
from sitl_sim.orphan import ParentWatch, detach_output
from sitl_sim.simulator import SimConfig, Simulator
from sitl_sim.world import Obstacles
from swarm_common.obstacle_shapes import pack_shapes
from swarm_common.radio_presets import RADIO_OVERRIDES, RADIO_PRESETS, RadioError, RadioSpec, radio_spec
from swarm_common.signing_keys import SigningKeyError, read_key

DEFAULT_HOME = (-35.363261, 149.165230, 584.0)  # ArduPilot SITL's default location (CMAC)
LINE_SPACING_M = 5.0  # default start line along East


# LinkFaults' fields that --link-<field> (dashes for underscores) and the mission's world.link set by name
LINK_RATE_FIELDS = ("loss", "delay_ms", "jitter_ms", "dup", "corrupt", "reorder")
# the radio's figures settable as --link-<key> (dashes for underscores): type and help
RADIO_FLAGS: dict[str, tuple[type, str]] = {
    "capacity_bps": (float, "air capacity, bit/s (needed without a preset)"),
    "bits_per_byte": (float, "bit times on the air per byte (SiK: 10.2 at 64 kbit/s)"),
    "overhead_bytes": (int, "bytes the radio adds to each packet"),
    "overhead_us": (float, "air time of each packet besides its bytes, us"),
    "half_duplex": (bool, "up and down share the air time"),
    "shared": (bool, "every vehicle and the ground share one medium"),
    "buffer_bytes": (int, "each transmitting radio's buffer, bytes (0: one second of capacity)"),
    "radio_status": (bool, "the ground radio sends RADIO_STATUS once a second"),
}
assert tuple(RADIO_FLAGS) == RADIO_OVERRIDES
ORPHAN_LOG = "simulator-orphan.log"  # beside the truth log: what the simulator says after its parent died


class OneLineParser(argparse.ArgumentParser):
    """argparse with single-line errors: "sitl-sim: error: <message>" on stderr, exit status 2."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: error: {message} (see --help)\n")


def build_parser() -> OneLineParser:
    """The argument parser (all options documented in --help and docs/sitl.md)."""
    parser = OneLineParser(
        prog="sitl-sim",
        description="Simulated quadrotors speaking MAVLink 2 over UDP, one port per vehicle, each behaving "
        "on the wire as ArduCopter or as PX4 (--autopilot).",
        epilog="Reference: docs/sitl.md (modes, parameters, MAVLink surface, lockstep rule, truth log).",
    )
    add = parser.add_argument
    add("--vehicles", type=int, metavar="N", help="number of vehicles (default with --mission: its vehicles)")
    add(
        "--base-port",
        type=int,
        default=14540,
        metavar="P",
        help="vehicle i listens on UDP P+i (default 14540)",
    )
    add("--bind", default="127.0.0.1", metavar="ADDR", help="IPv4 address to bind (default 127.0.0.1)")
    add("--sysid-base", type=int, default=1, metavar="S", help="vehicle i has MAVLink sysid S+i (default 1)")
    clock = parser.add_mutually_exclusive_group()
    clock.add_argument(
        "--speedup", type=float, default=1.0, metavar="X", help="X times real time (default 1)"
    )
    clock.add_argument(
        "--lockstep", action="store_true", help="advance only as the clients answer (see docs)"
    )
    add("--lockstep-hz", type=float, default=50.0, metavar="HZ", help="lockstep frame rate (default 50)")
    add("--lockstep-timeout", type=float, default=5.0, metavar="S", help="drop silent lockstep clients (5 s)")
    add(
        "--lockstep-delay",
        type=int,
        choices=(0, 1),
        default=1,
        metavar="FRAMES",
        help="lockstep frames from telemetry to the commands answering it taking effect: 1 (default) "
        "pipelines the simulator with its clients, 0 alternates with them",
    )
    add(
        "--lockstep-spin-us",
        type=float,
        default=1000.0,
        metavar="US",
        help="in lockstep, poll this long for the clients' answers before blocking (default 1000; 0: block "
        "at once)",
    )
    add("--rate-hz", type=float, default=1000.0, metavar="HZ", help="physics rate (default 1000)")
    add("--outer-hz", type=float, default=100.0, metavar="HZ", help="autopilot outer-loop rate (default 100)")
    add("--home", metavar="LAT,LON,ALT", help="geodetic ENU origin (default: mission origin, else CMAC)")
    add(
        "--mission", type=Path, metavar="FILE.yaml", help="mission file: starts, obstacles, wind, link faults"
    )
    add(
        "--truth-log",
        type=Path,
        metavar="PATH",
        help="ground-truth CSV (obstacles in PATH with suffix .obstacles.csv)",
    )
    add("--truth-rate-hz", type=float, default=50.0, metavar="HZ", help="truth-log sample rate (default 50)")
    add("--seed", type=int, default=0, metavar="S", help="random seed of the wind turbulence (default 0)")
    add(
        "--ready-delay",
        type=float,
        metavar="S",
        help="simulated s from boot until the EKF has a position and pre-arm checks pass, for every vehicle "
        "(default per autopilot: 40 for ArduCopter, as a real ArduCopter 4.7 SITL: GPS 3D fix at 10 s, EKF "
        "using GPS at 42 s; 5 for PX4, whose real SIH SITL is ready for takeoff 4.4-4.6 s after boot)",
    )
    add(
        "--autopilot",
        metavar="NAME[,NAME...]",
        help="the autopilot each vehicle behaves as on the wire: ardupilot (ArduCopter 4.7) or px4 (PX4 "
        "v1.14+ multicopter); one name for all vehicles or a comma list, one per vehicle (default: the "
        "mission's vehicles[i].autopilot / run.simulator.autopilot, else ardupilot; docs/sitl.md)",
    )
    add(
        "--param-names",
        choices=PARAM_NAME_RELEASES,
        default="4.7",
        help="the ArduCopter release whose parameter names the vehicles show: 4.7 (MAV_SYSID, MAV_GCS_SYSID; "
        "default) or 4.6 (SYSID_THISMAV, SYSID_MYGCS)",
    )
    add(
        "--exit-with-parent",
        action="store_true",
        help="the parent (gcs-swarm) holds a pipe on stdin: when it closes, fly on until every vehicle is "
        "landed and disarmed, then exit (docs/sitl.md)",
    )
    add(
        "--orphan-speedup",
        type=float,
        default=math.inf,
        metavar="X",
        help="with --lockstep and --exit-with-parent: run X times real time once the parent is gone "
        "(default inf: as fast as possible); real-time and --speedup runs keep their pace",
    )
    add(
        "--orphan-grace",
        type=float,
        default=300.0,
        metavar="S",
        help="with --exit-with-parent: exit at most S simulated s after the parent is gone (default 300: "
        "a hovering vehicle's battery reserve; BRAKE holds for ever)",
    )
    add(
        "--signing-key",
        type=Path,
        metavar="FILE",
        help="MAVLink 2 signing: FILE holds the 32-byte key as 64 hex characters; vehicles then accept only "
        "messages signed with it and sign what they send",
    )
    link = parser.add_argument_group(
        "link faults (every vehicle, both directions; each option overrides the mission's world.link value; "
        "docs/sitl.md)"
    )
    link.add_argument("--link-loss", type=float, metavar="P", help="packet loss probability (default 0)")
    link.add_argument("--link-delay-ms", type=float, metavar="MS", help="one-way delay, sim ms (default 0)")
    link.add_argument("--link-jitter-ms", type=float, metavar="MS", help="extra delay 0..MS (default 0)")
    link.add_argument("--link-dup", type=float, metavar="P", help="duplication probability (default 0)")
    link.add_argument("--link-corrupt", type=float, metavar="P", help="corruption probability (default 0)")
    link.add_argument("--link-reorder", type=float, metavar="P", help="hold-back probability (default 0)")
    link.add_argument("--link-from", type=float, metavar="S", help="rates act from sim s S on (default 0)")
    link.add_argument(
        "--link-outage",
        action="append",
        metavar="[I@]START:DURATION",
        help="no packet on vehicle I's link (default: all) for DURATION sim s (may be inf); repeatable; "
        "replaces the mission's outages",
    )
    radio = parser.add_argument_group(
        "radio (capacity, buffers, duplex, shared medium under every link; each option overrides the "
        "mission's world.link value; docs/radio.md)"
    )
    radio.add_argument(
        "--link-radio",
        metavar="NAME",
        help=f"radio preset ({', '.join(RADIO_PRESETS)}) or none; replaces the mission's radio and its "
        "overrides (default: the mission's, else none: unlimited capacity)",
    )
    for key, (kind, helptext) in RADIO_FLAGS.items():
        flag = f"--link-{key.replace('_', '-')}"
        if kind is bool:
            radio.add_argument(flag, action=argparse.BooleanOptionalAction, default=None, help=helptext)
        else:
            radio.add_argument(flag, type=kind, metavar=key.upper(), help=helptext)
    radio.add_argument(
        "--link-capacity-change",
        action="append",
        metavar="START:BPS",
        help="from sim s START on, the radio's capacity is BPS bit/s (needs a radio); repeatable",
    )
    return parser


def link_radio(
    parser: OneLineParser, args: argparse.Namespace, name: str | None, overrides: dict[str, object]
) -> RadioSpec | None:
    """The radio of the mission's world.link (preset `name` and its `overrides`) under the --link-* radio
    options: --link-radio replaces the preset and its overrides, each other option one figure; checked by
    swarm_common.radio_presets.radio_spec (one-line errors)."""
    if args.link_radio is not None:
        name = None if args.link_radio == "none" else args.link_radio
        overrides = {}
    given = {key: getattr(args, f"link_{key}") for key in RADIO_FLAGS}
    overrides = {**overrides, **{key: value for key, value in given.items() if value is not None}}
    try:
        return radio_spec(name, overrides)
    except RadioError as exc:
        flag = "--link-radio" if exc.key == "radio" else f"--link-{exc.key.replace('_', '-')}"
        parser.error(f"{flag}: {exc}")


def link_faults(
    parser: OneLineParser,
    args: argparse.Namespace,
    vehicles: int,
    base: LinkFaults,
    radio_name: str | None = None,
    radio_overrides: dict[str, object] | None = None,
) -> LinkFaults:
    """The --link-* options, checked (one-line errors), over `base` (the mission's world.link): an option
    given replaces its value; any --link-outage replaces all of base's outages; the radio is the mission's
    preset `radio_name` with its `radio_overrides` under the radio options (link_radio)."""
    for option in ("loss", "dup", "corrupt", "reorder"):
        value = getattr(args, f"link_{option}")
        if value is not None and not 0.0 <= value <= 1.0:
            parser.error(f"--link-{option} must be a probability in 0..1, not {value:g}")
    for option in ("delay_ms", "jitter_ms"):
        value = getattr(args, f"link_{option}")
        if value is not None and not 0.0 <= value <= 10000.0:
            parser.error(f"--link-{option.replace('_', '-')} must be 0..10000 ms, not {value:g}")
    if args.link_from is not None and not 0.0 <= args.link_from < math.inf:
        parser.error(f"--link-from must be >= 0 s, not {args.link_from:g}")
    given = {field: getattr(args, f"link_{field}") for field in LINK_RATE_FIELDS}
    given["start_s"] = args.link_from
    if args.link_outage is not None:
        parsed: list[Outage] = []
        for text in args.link_outage:
            try:
                parsed.append(parse_outage(text, vehicles))
            except ValueError as exc:
                parser.error(str(exc))
        given["outages"] = tuple(parsed)
    given["radio"] = link_radio(parser, args, radio_name, radio_overrides or {})
    if args.link_capacity_change is not None:
        if given["radio"] is None:
            parser.error("--link-capacity-change needs a radio (--link-radio or the mission's world.link)")
        try:
            given["capacity_changes"] = tuple(parse_capacity_change(t) for t in args.link_capacity_change)
        except ValueError as exc:
            parser.error(str(exc))
    return dataclasses.replace(base, **{field: value for field, value in given.items() if value is not None})


def _check(parser: OneLineParser, ok: bool, message: str) -> None:
    if not ok:
        parser.error(message)


def _finite_positive(value: float) -> bool:
    return math.isfinite(value) and value > 0


def parse_home(parser: OneLineParser, text: str) -> tuple[float, float, float]:
    """LAT,LON,ALT -> floats, or a one-line error."""
    try:
        lat, lon, alt = (float(part) for part in text.split(","))
    except ValueError:
        parser.error(f"--home must be LAT,LON,ALT (three numbers), not {text!r}")
    _check(parser, math.isfinite(lat) and -90.0 <= lat <= 90.0, f"--home latitude {lat:g} is not in -90..90")
    _check(
        parser, math.isfinite(lon) and -180.0 <= lon <= 180.0, f"--home longitude {lon:g} is not in -180..180"
    )
    _check(
        parser,
        math.isfinite(alt) and -1000.0 <= alt <= 10000.0,
        f"--home altitude {alt:g} m is not plausible",
    )
    return lat, lon, alt


def build_config(parser: OneLineParser, args: argparse.Namespace) -> SimConfig:
    """Validate the arguments (one-line errors, exit 2) and load the mission's world."""
    home = None
    autopilots: tuple[str, ...] = ()
    obstacles = Obstacles(np.zeros((0, 3)), np.zeros(0), np.zeros((0, 3)))
    wind = (0.0, 0.0, 0.0)
    link = LinkFaults()
    radio_name: str | None = None
    radio_overrides: dict[str, object] = {}
    if args.mission is not None:
        try:
            from gcs_swarm.mission import MissionError, load_world
        except ImportError as exc:
            parser.error(f"--mission needs gcs_swarm.mission, which cannot be imported ({exc})")
        try:
            world = load_world(args.mission)
        except MissionError as exc:
            parser.error(str(exc))
        except OSError as exc:
            parser.error(f"cannot read mission {args.mission}: {exc.strerror or exc}")
        n = len(world.starts)
        _check(
            parser, args.vehicles in (None, n), f"--vehicles {args.vehicles} but the mission has {n} vehicles"
        )
        start_pos = np.array([s.position for s in world.starts], dtype=float)
        start_vel = np.array([s.velocity for s in world.starts], dtype=float)
        start_yaw = np.radians([s.yaw_deg for s in world.starts])
        if world.obstacles or world.prisms or world.cylinders:
            obstacles = Obstacles(
                np.array([o.center for o in world.obstacles]).reshape(-1, 3),
                np.array([o.radius for o in world.obstacles]),
                np.array([o.velocity for o in world.obstacles]).reshape(-1, 3),
                pack_shapes(
                    cylinders=[(c.center, c.radius, c.bottom, c.top) for c in world.cylinders],
                    prisms=[(p.footprint, p.bottom, p.top) for p in world.prisms],
                ),
            )
        wind = (world.wind.speed, world.wind.direction_deg, world.wind.turbulence)
        lat, lon, alt = world.origin
        home = (float(lat), float(lon), float(alt))
        # the mission's world.link as the simulator's LinkFaults (outage vehicles are indices already)
        outages = tuple(Outage(o.vehicle, o.start_s, o.duration_s) for o in world.link.outages)
        rates = {field: getattr(world.link, field) for field in LINK_RATE_FIELDS}
        link = LinkFaults(**rates, outages=outages, start_s=world.link.from_s)
        radio_name = world.link.radio
        radio_overrides = {key: getattr(world.link, key) for key in RADIO_OVERRIDES}
        autopilots = tuple(world.autopilots)
    else:
        _check(parser, args.vehicles is not None, "--vehicles N is required without --mission")
        n = args.vehicles
        _check(parser, n >= 1, f"--vehicles must be >= 1, not {n}")
        start_pos = np.column_stack((LINE_SPACING_M * np.arange(n), np.zeros(n), np.zeros(n)))
        start_vel = np.zeros((n, 3))
        start_yaw = np.full(n, math.pi / 2)  # facing north, like ArduPilot SITL
    if args.home is not None:
        home = parse_home(parser, args.home)
    if args.autopilot is not None:
        try:
            autopilots = parse_autopilots(args.autopilot, n)
        except ValueError as exc:
            parser.error(str(exc))
    try:
        ipaddress.IPv4Address(args.bind)
    except ValueError:
        parser.error(f"--bind must be an IPv4 address such as 127.0.0.1, not {args.bind!r}")
    checks = (
        (1 <= args.sysid_base <= 255, f"--sysid-base must be in 1..255, not {args.sysid_base}"),
        (args.sysid_base + n - 1 <= 255, f"{n} vehicles from sysid {args.sysid_base} exceed sysid 255"),
        (1 <= args.base_port <= 65535, f"--base-port must be in 1..65535, not {args.base_port}"),
        (args.base_port + n - 1 <= 65535, f"{n} vehicles from port {args.base_port} exceed port 65535"),
        (_finite_positive(args.speedup) and args.speedup <= 1e6, "--speedup must be a number in (0, 1e6]"),
        (_finite_positive(args.lockstep_hz), "--lockstep-hz must be > 0"),
        (_finite_positive(args.lockstep_timeout), "--lockstep-timeout must be > 0 s"),
        (
            0.0 <= args.lockstep_spin_us <= 20000.0,
            "--lockstep-spin-us must be a number of microseconds in 0..20000",
        ),
        (args.orphan_speedup > 0, "--orphan-speedup must be > 0 (inf: as fast as possible)"),
        (_finite_positive(args.orphan_grace), "--orphan-grace must be > 0 s"),
        (
            _finite_positive(args.rate_hz) and args.rate_hz == round(args.rate_hz) and args.rate_hz <= 100000,
            "--rate-hz must be a whole number of Hz in 1..100000",
        ),
        (_finite_positive(args.outer_hz), "--outer-hz must be > 0"),
        (_finite_positive(args.truth_rate_hz), "--truth-rate-hz must be > 0"),
        (args.seed >= 0, f"--seed must be >= 0, not {args.seed}"),
        (
            args.ready_delay is None or (math.isfinite(args.ready_delay) and 0 <= args.ready_delay <= 600),
            "--ready-delay must be 0..600 s",
        ),
    )
    for ok, message in checks:
        _check(parser, ok, message)
    if args.truth_log is not None:
        parent = args.truth_log.resolve().parent
        _check(parser, parent.is_dir(), f"--truth-log directory {parent} does not exist")
    try:
        timing = plan_timing(
            args.rate_hz, args.outer_hz, args.lockstep_hz if args.lockstep else None, args.truth_rate_hz
        )
    except ValueError as exc:
        parser.error(str(exc))
    return SimConfig(
        base_port=args.base_port,
        bind=args.bind,
        sysid_base=args.sysid_base,
        timing=timing,
        speedup=args.speedup,
        lockstep=args.lockstep,
        lockstep_timeout=args.lockstep_timeout,
        lockstep_delay=args.lockstep_delay,
        lockstep_spin_s=args.lockstep_spin_us * 1e-6,
        home=home or DEFAULT_HOME,
        start_pos=start_pos,
        start_vel=start_vel,
        start_yaw=start_yaw,
        obstacles=obstacles,
        wind=wind,
        truth_log=args.truth_log,
        seed=args.seed,
        ready_delay=args.ready_delay,
        link=link_faults(parser, args, n, link, radio_name, radio_overrides),
        signing_key=signing_key(parser, args.signing_key),
        param_names=args.param_names,
        orphan_speedup=args.orphan_speedup,
        orphan_grace_s=args.orphan_grace,
        autopilots=autopilots,
    )


def signing_key(parser: OneLineParser, path: Path | None) -> bytes | None:
    """The --signing-key file's key, or a one-line error that never shows the file's content."""
    if path is None:
        return None
    try:
        return read_key(path)
    except SigningKeyError as exc:
        parser.error(f"--signing-key: {exc}")


def log_to_stderr() -> None:
    """The simulator's log (the `sitl_sim.*` loggers) goes to stderr as "sitl-sim: <message>" lines; a
    handler exception follows its line with the traceback."""
    logger = logging.getLogger("sitl_sim")
    if not logger.handlers:
        handler = logging.StreamHandler(sys.stderr)
        handler.setFormatter(logging.Formatter("sitl-sim: %(message)s"))
        logger.addHandler(handler)
    logger.setLevel(logging.INFO)


def main(argv: list[str] | None = None) -> int:
    """Run the simulator; returns the exit status (0 after SIGINT/SIGTERM)."""
    log_to_stderr()
    parser = build_parser()
    args = parser.parse_args(argv)
    config = build_config(parser, args)
    try:
        sim = Simulator(config)
    except OSError as exc:
        where = (
            exc.filename
            or f"udp {config.bind} ports {config.base_port}..{config.base_port + config.vehicles - 1}"
        )
        print(f"sitl-sim: error: cannot open {where}: {exc.strerror or exc}", file=sys.stderr)
        return 1
    stop_requested = False

    def request_stop(signum: int, frame: object) -> None:
        nonlocal stop_requested
        stop_requested = True

    wake_read, wake_write = socket.socketpair()
    wake_write.setblocking(False)
    previous_fd = signal.set_wakeup_fd(wake_write.fileno())
    previous = {sig: signal.signal(sig, request_stop) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        for endpoint in sim.endpoints:
            port = config.base_port + endpoint.index
            print(f"vehicle {endpoint.index} sysid {endpoint.sysid} udp {config.bind}:{port}")
        print("READY", flush=True)
        if args.exit_with_parent:
            log = None if config.truth_log is None else str(config.truth_log.parent / ORPHAN_LOG)

            def parent_gone() -> None:
                detach_output(log)
                sim.mark_parent_gone()
                with contextlib.suppress(OSError):
                    wake_write.send(b"\0")

            ParentWatch(sys.stdin.fileno(), parent_gone).start()
        sim.run(lambda: stop_requested, wake_read)
        for line in sim.counters_report():
            print(f"sitl-sim: {line}", file=sys.stderr)
    finally:
        sim.close()
        for sig, handler in previous.items():
            signal.signal(sig, handler)
        signal.set_wakeup_fd(previous_fd)
        wake_read.close()
        wake_write.close()
    return 0
