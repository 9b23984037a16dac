"""The console's command language: parsing, validation, completion and help. Pure: no I/O, no fleet.

`parse(line, vocabulary)` turns one typed line into a `Request` or raises `CommandError` with one sentence
saying what is wrong and what would be right; it raises nothing else, whatever the line. Names follow
MAVProxy where it has them: `mode GUIDED` (or just `guided`), `arm throttle`, `param set NAME VALUE`.
Vehicle targets are `all` (the default), a vehicle name or its sysid. Positions are mission-frame ENU metres.
"""

from __future__ import annotations

import difflib
import math
import shlex
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

from gcs_swarm.console.snapshot import Snapshot
from gcs_swarm.flight.phase import Phase
from gcs_swarm.guidance.formation import SHAPES
from gcs_swarm.link.autopilots import MODE_NAMES
from gcs_swarm.mission import Mission

PHASE_NAMES = tuple(Phase)
KNOWN_PARAMS = (
    "ANGLE_MAX",
    "ARMING_CHECK",
    "DISARM_DELAY",
    "FS_GCS_ENABLE",
    "FS_GCS_TIMEOUT",
    "FS_THR_ENABLE",
    "GUID_OPTIONS",
    "GUID_TIMEOUT",
    "LAND_SPEED",
    "MOT_THST_HOVER",
    "PSC_POSXY_P",
    "PSC_POSZ_P",
    "PSC_VELXY_I",
    "PSC_VELXY_P",
    "PSC_VELZ_P",
    "RTL_ALT",
    "SYSID_MYGCS",
    "SYSID_THISMAV",
    "WPNAV_ACCEL",
    "WPNAV_SPEED",
    "WPNAV_SPEED_DN",
    "WPNAV_SPEED_UP",
)
"""ArduCopter parameters offered for completion until the vehicles' own lists are fetched (`param fetch`)."""


class CommandError(Exception):
    """A typed command that cannot be run, with one sentence saying why."""


TARGET_HELP = "TARGET is all (default), a vehicle name or a sysid"
ALIASES = {"exit": "quit", "q": "quit", "?": "help", "stop": "abort"}


@dataclass(frozen=True)
class Vocabulary:
    """What commands may refer to: the fleet (names and sysids in vehicle order), parameter names, and the
    mission's safety envelope for goals and altitudes (m)."""

    names: tuple[str, ...]
    sysids: tuple[int | None, ...]
    params: tuple[str, ...] = KNOWN_PARAMS
    min_altitude: float = 0.0
    max_altitude: float = math.inf
    geofence_radius: float = math.inf
    shapes: tuple[str, ...] = SHAPES
    obstacles: tuple[tuple[float, float, float, float], ...] = field(default=())  # static: x, y, z, radius


def vocabulary_for(mission: Mission, snapshot: Snapshot) -> Vocabulary:
    """The vocabulary of a mission's fleet: sysids as the vehicles reported them (else as configured),
    parameter names as the vehicles listed them once fetched (else KNOWN_PARAMS), the mission's envelope."""
    sysids = tuple(
        row.sysid if row.sysid is not None else spec.sysid
        for row, spec in zip(snapshot.rows, mission.vehicles, strict=True)
    )
    fetched = len(snapshot.params) > len(KNOWN_PARAMS)
    params = snapshot.params if fetched else tuple(sorted({*KNOWN_PARAMS, *snapshot.params}))
    safety = mission.safety
    static = tuple(
        (float(o.center[0]), float(o.center[1]), float(o.center[2]), float(o.radius))
        for o in mission.obstacles
        if not o.velocity.any()
    )
    return Vocabulary(
        names=tuple(v.name for v in mission.vehicles),
        sysids=sysids,
        params=params,
        min_altitude=safety.min_altitude,
        max_altitude=safety.geofence_max_alt,
        geofence_radius=safety.geofence_radius,
        shapes=(*SHAPES, "offsets") if mission.formation.shape == "offsets" else SHAPES,
        obstacles=static,
    )


@dataclass(frozen=True)
class Verb:
    """One console command: `usage` and `summary` (its help line and completion entry), `parse` (the words
    after the verb -> a Request, or CommandError with one sentence), `confirm`: it arms or launches vehicles,
    so the console asks before running it unless --yes."""

    usage: str
    summary: str
    parse: Callable[[str, list[str], str, Vocabulary], Request]
    confirm: bool = False


@dataclass(frozen=True)
class Request:
    """One validated command. `vehicles` are vehicle indices (every vehicle when `every`)."""

    verb: str  # canonical: a COMMANDS name, or param_get / param_set / param_fetch / wait_phase
    line: str = ""
    vehicles: tuple[int, ...] = ()
    every: bool = False
    name: str = ""  # mode, parameter, shape, phase or help topic
    value: float | None = None  # altitude m, parameter value, spacing m, seconds
    point: tuple[float, float, float] | None = None  # goal, ENU m

    @property
    def needs_confirmation(self) -> bool:
        return self.verb in CONFIRM_VERBS


def parse(line: str, vocabulary: Vocabulary) -> Request | None:
    """The Request for one typed line; None for a blank line or a comment; CommandError otherwise."""
    try:
        words = shlex.split(line, comments=True)
    except ValueError as exc:
        raise CommandError(f"cannot read the line: {exc}") from None
    if not words:
        return None
    head = words[0].lower()
    head = ALIASES.get(head, head)
    args = words[1:]
    text = line.strip()
    if head in VERBS:
        return VERBS[head].parse(head, args, text, vocabulary)
    if head.upper() in MODE_NAMES:  # MAVProxy: a mode name alone sets that mode
        return _mode_request(head.upper(), args, text, vocabulary)
    hint = _closest(head, COMMANDS)
    raise CommandError(f"unknown command {words[0]!r}{hint}; type help for the list")


def help_lines(topic: str | None = None) -> list[str]:
    """Help text: every command, or one command's usage and meaning; CommandError for an unknown topic."""
    if topic is None:
        width = max(len(h.usage) for h in VERBS.values())
        lines = [f"{h.usage:<{width}}  {h.summary}" for h in VERBS.values()]
        return [*lines, TARGET_HELP + "; a mode name alone (guided, loiter, ...) = mode NAME"]
    key = ALIASES.get(topic.lower(), topic.lower())
    if key not in VERBS:
        raise CommandError(f"no help for {topic!r}{_closest(key, COMMANDS)}; type help for the list")
    entry = VERBS[key]
    lines = [f"{entry.usage}: {entry.summary}"]
    if "TARGET" in entry.usage:
        lines.append(TARGET_HELP)
    if key == "mode":
        lines.append(f"modes: {', '.join(MODE_NAMES)}")
    if key == "wait":
        lines.append(f"phases: {', '.join(PHASE_NAMES)}")
    return lines


# ----------------------------------------------------------------------------- completion


def complete(text: str, vocabulary: Vocabulary) -> list[str]:
    """Completions of the last (partial) word of `text`, given the words before it."""
    words = text.split()
    if text and not text[-1].isspace():
        partial, before = words[-1], words[:-1]
    else:
        partial, before = "", words
    return [c for c in _candidates(before, vocabulary) if c.lower().startswith(partial.lower())]


def _candidates(before: Sequence[str], vocabulary: Vocabulary) -> list[str]:
    targets = ["all", *vocabulary.names, *(str(s) for s in vocabulary.sysids if s is not None)]
    modes = list(MODE_NAMES)
    if not before:
        return [*COMMANDS, *(m.lower() for m in modes if m.lower() not in COMMANDS)]
    head = ALIASES.get(before[0].lower(), before[0].lower())
    n = len(before) - 1  # index of the argument being typed
    if head == "help":
        return list(COMMANDS) if n == 0 else []
    if head in ("disarm", "land", "rtl") or head.upper() in MODE_NAMES:
        return targets if n == 0 else []
    if head == "arm":
        return (["throttle", *targets] if n == 0 else targets) if n <= 1 else []
    if head == "mode":
        return modes if n == 0 else (targets if n == 1 else [])
    if head == "takeoff":
        return targets if n == 1 else []
    if head in ("rejoin", "leader"):
        return list(vocabulary.names) if n == 0 else []
    if head == "formation":
        return list(vocabulary.shapes) if n == 0 else []
    if head == "wait":
        return ["phase"] if n == 0 else (list(PHASE_NAMES) if n == 1 and before[1] == "phase" else [])
    if head == "param":
        if n == 0:
            return ["get", "set", "fetch", "show"]
        sub = before[1].lower()
        if sub == "fetch":
            return targets if n == 1 else []
        if n == 1:
            return list(vocabulary.params)
        return targets if (sub in ("get", "show") and n == 2) or (sub == "set" and n == 3) else []
    return []


# ----------------------------------------------------------------------------- per-command parsers


def _no_args(verb: str, args: list[str], line: str, vocabulary: Vocabulary) -> Request:
    if args:
        raise CommandError(f"{verb} takes no arguments (got {' '.join(args)!r})")
    return Request(verb, line)


def _help(verb: str, args: list[str], line: str, vocabulary: Vocabulary) -> Request:
    if len(args) > 1:
        raise CommandError("usage: help [COMMAND]")
    if args:
        help_lines(args[0])  # unknown topics are refused here
    return Request("help", line, name=args[0].lower() if args else "")


def _targeted(verb: str, args: list[str], line: str, vocabulary: Vocabulary) -> Request:
    """arm [throttle] [TARGET], disarm / land / rtl [TARGET]."""
    if verb == "arm" and args and args[0].lower() == "throttle":
        args = args[1:]
    if len(args) > 1:
        raise CommandError(f"usage: {VERBS[verb].usage} ({TARGET_HELP})")
    vehicles, every = _target(args[0] if args else None, vocabulary)
    return Request(verb, line, vehicles, every)


def _one_vehicle(verb: str, args: list[str], line: str, vocabulary: Vocabulary) -> Request:
    """rejoin VEHICLE, leader VEHICLE: exactly one vehicle, by name or sysid."""
    if len(args) != 1 or args[0].lower() == "all":
        raise CommandError(f"usage: {VERBS[verb].usage} (one vehicle: a name or a sysid)")
    vehicles, _ = _target(args[0], vocabulary)
    return Request(verb, line, vehicles)


def _mode(verb: str, args: list[str], line: str, vocabulary: Vocabulary) -> Request:
    if not args or len(args) > 2:
        raise CommandError(f"usage: mode NAME [TARGET], NAME one of {', '.join(MODE_NAMES)}")
    name = args[0].upper()
    if name not in MODE_NAMES:
        hint = _closest(name, tuple(MODE_NAMES))
        raise CommandError(f"unknown flight mode {args[0]!r}{hint} (modes: {', '.join(MODE_NAMES)})")
    return _mode_request(name, args[1:], line, vocabulary)


def _mode_request(name: str, args: list[str], line: str, vocabulary: Vocabulary) -> Request:
    if len(args) > 1:
        raise CommandError(f"usage: mode {name} [TARGET] ({TARGET_HELP})")
    vehicles, every = _target(args[0] if args else None, vocabulary)
    return Request("mode", line, vehicles, every, name=name)


def _takeoff(verb: str, args: list[str], line: str, vocabulary: Vocabulary) -> Request:
    if not args or len(args) > 2:
        raise CommandError(f"usage: takeoff ALT [TARGET] (ALT m above home; {TARGET_HELP})")
    alt = _number(args[0], "the takeoff altitude")
    ceiling = vocabulary.max_altitude
    if not 0 < alt <= ceiling:
        raise CommandError(f"takeoff altitude {alt:g} m is outside 0..{ceiling:g} m (the geofence ceiling)")
    vehicles, every = _target(args[1] if len(args) > 1 else None, vocabulary)
    return Request("takeoff", line, vehicles, every, value=alt)


def _goal(verb: str, args: list[str], line: str, vocabulary: Vocabulary) -> Request:
    if len(args) != 3:
        raise CommandError("usage: goal X Y Z (m, ENU: x East, y North, z up)")
    x, y, z = (_number(a, f"goal {axis}") for a, axis in zip(args, "xyz", strict=True))
    v = vocabulary
    if not v.min_altitude <= z <= v.max_altitude:
        raise CommandError(
            f"goal z = {z:g} m is outside the altitude band {v.min_altitude:g}..{v.max_altitude:g} m"
        )
    if math.hypot(x, y) > v.geofence_radius:
        raise CommandError(
            f"goal is {math.hypot(x, y):.0f} m from the origin, "
            f"outside the geofence ({v.geofence_radius:g} m)"
        )
    for k, (ox, oy, oz, r) in enumerate(v.obstacles):
        if math.dist((x, y, z), (ox, oy, oz)) <= r:
            raise CommandError(f"goal lies inside obstacle {k} (centre {ox:g} {oy:g} {oz:g}, radius {r:g} m)")
    return Request("goal", line, point=(x, y, z))


def _formation(verb: str, args: list[str], line: str, vocabulary: Vocabulary) -> Request:
    if not args or len(args) > 2:
        raise CommandError(f"usage: formation SHAPE [SPACING] (shapes: {', '.join(vocabulary.shapes)})")
    shape = args[0].lower()
    if shape not in vocabulary.shapes:
        hint = _closest(shape, vocabulary.shapes)
        raise CommandError(
            f"unknown formation shape {args[0]!r}{hint} (shapes: {', '.join(vocabulary.shapes)})"
        )
    spacing = None
    if len(args) == 2:
        spacing = _number(args[1], "the spacing")
        if not 0 < spacing <= vocabulary.geofence_radius:
            raise CommandError(f"spacing {spacing:g} m must be > 0 m and inside the geofence")
    return Request("formation", line, name=shape, value=spacing)


def _param(verb: str, args: list[str], line: str, vocabulary: Vocabulary) -> Request:
    usage = (
        "usage: param get NAME [TARGET] | param set NAME VALUE [TARGET] | param fetch [TARGET] "
        f"({TARGET_HELP})"
    )
    if not args:
        raise CommandError(usage)
    sub, rest = args[0].lower(), args[1:]
    if sub == "fetch":
        if len(rest) > 1:
            raise CommandError(usage)
        vehicles, every = _target(rest[0] if rest else None, vocabulary)
        return Request("param_fetch", line, vehicles, every)
    if sub in ("get", "show") and 1 <= len(rest) <= 2:
        vehicles, every = _target(rest[1] if len(rest) > 1 else None, vocabulary)
        return Request("param_get", line, vehicles, every, name=_param_name(rest[0]))
    if sub == "set" and 2 <= len(rest) <= 3:
        value = _number(rest[1], f"the value of {rest[0]}")
        vehicles, every = _target(rest[2] if len(rest) > 2 else None, vocabulary)
        return Request("param_set", line, vehicles, every, name=_param_name(rest[0]), value=value)
    raise CommandError(usage)


def _wait(verb: str, args: list[str], line: str, vocabulary: Vocabulary) -> Request:
    usage = "usage: wait SECONDS | wait phase NAME [SECONDS] (vehicle time)"
    if args and args[0].lower() == "phase":
        if not 2 <= len(args) <= 3:
            raise CommandError(usage)
        phase = args[1].lower()
        if phase not in PHASE_NAMES:
            raise CommandError(f"unknown phase {args[1]!r} (phases: {', '.join(PHASE_NAMES)})")
        limit = _seconds(args[2]) if len(args) == 3 else None
        return Request("wait_phase", line, name=phase, value=limit)
    if len(args) != 1:
        raise CommandError(usage)
    return Request("wait", line, value=_seconds(args[0]))


VERBS: dict[str, Verb] = {
    "start": Verb(
        "start", "fly the mission: preflight, GUIDED, arm, take off, formation flight", _no_args, confirm=True
    ),
    "hold": Verb("hold", "every vehicle brakes and holds its position (formation flight pauses)", _no_args),
    "resume": Verb("resume", "back to formation flight from where the vehicles are", _no_args),
    "abort": Verb("abort", "stop the mission: every vehicle lands now", _no_args),
    "goal": Verb("goal X Y Z", "move the leader's goal to X Y Z (m, ENU) in flight", _goal),
    "rejoin": Verb(
        "rejoin VEHICLE",
        "hand back a vehicle taken over (another GCS, RC, failsafe): GUIDED, to its slot",
        _one_vehicle,
    ),
    "leader": Verb(
        "leader VEHICLE", "this vehicle leads from now on (the leader was taken over)", _one_vehicle
    ),
    "formation": Verb(
        "formation SHAPE [SPACING]",
        f"reshape in flight ({', '.join(SHAPES)}; SPACING m), inter-UAV avoidance stays on",
        _formation,
    ),
    "arm": Verb(
        "arm [throttle] [TARGET]",
        "arm the motors (MAVProxy's `arm throttle` works too)",
        _targeted,
        confirm=True,
    ),
    "disarm": Verb("disarm [TARGET]", "disarm the motors (a flying vehicle refuses)", _targeted),
    "mode": Verb(
        "mode NAME [TARGET]", "set a flight mode, e.g. `mode GUIDED`; or type the mode alone", _mode
    ),
    "takeoff": Verb(
        "takeoff ALT [TARGET]",
        "take off to ALT m above home (GUIDED and armed first)",
        _takeoff,
        confirm=True,
    ),
    "land": Verb("land [TARGET]", "LAND mode; `land` for all while the mission flies = abort", _targeted),
    "rtl": Verb("rtl [TARGET]", "RTL mode: return to launch and land", _targeted),
    "param": Verb(
        "param get|set|fetch NAME [VALUE] [TARGET]",
        "read or write a parameter; `param fetch` reads every vehicle's list (for completion)",
        _param,
    ),
    "status": Verb("status", "print every vehicle's state in detail", _no_args),
    "help": Verb("help [COMMAND]", "this list, or one command's usage", _help),
    "wait": Verb(
        "wait SECONDS | wait phase NAME [SECONDS]",
        "scripts: wait SECONDS of vehicle time, or until the mission enters phase NAME",
        _wait,
    ),
    "quit": Verb("quit", "leave the console (asks first while vehicles are airborne)", _no_args),
}
"""Every console command, in help order: adding one is one entry here (and its handler in
gcs_swarm.console.session)."""
COMMANDS = tuple(VERBS)
CONFIRM_VERBS = frozenset(name for name, verb in VERBS.items() if verb.confirm)


# ----------------------------------------------------------------------------- arguments


def _target(token: str | None, vocabulary: Vocabulary) -> tuple[tuple[int, ...], bool]:
    """Vehicle indices for a TARGET word (None or `all`: every vehicle)."""
    everyone = tuple(range(len(vocabulary.names)))
    if token is None or token.lower() == "all":
        return everyone, True
    if token in vocabulary.names:
        return (vocabulary.names.index(token),), False
    if token.isdigit() and int(token) in vocabulary.sysids:
        return (vocabulary.sysids.index(int(token)),), False
    known = ", ".join(
        f"{n} ({s})" if s is not None else n for n, s in zip(vocabulary.names, vocabulary.sysids, strict=True)
    )
    raise CommandError(f"no vehicle {token!r}: give all, a name or a sysid ({known})")


def _number(token: str, what: str) -> float:
    try:
        value = float(token)
    except ValueError:
        raise CommandError(f"{what} must be a number, not {token!r}") from None
    if not math.isfinite(value):
        raise CommandError(f"{what} must be a finite number, not {token!r}")
    return value


def _seconds(token: str) -> float:
    value = _number(token, "the time")
    if value < 0:
        raise CommandError(f"the time must be >= 0 s, not {token}")
    return value


def _param_name(token: str) -> str:
    name = token.upper()
    if not 1 <= len(name) <= 16 or not all(c.isascii() and (c.isalnum() or c == "_") for c in name):
        raise CommandError(f"parameter name {token!r} must be 1-16 letters, digits or _")
    return name


def _closest(word: str, choices: Sequence[str]) -> str:
    """' (did you mean X?)' for a choice close to `word`, or ''."""
    lowered = {c.lower(): c for c in choices}
    match = difflib.get_close_matches(word.lower(), list(lowered), n=1, cutoff=0.6)
    return f" (did you mean {lowered[match[0]]}?)" if match else ""
