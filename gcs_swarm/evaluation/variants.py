"""Mission files derived from a base mission: a variant (guidance method, controller, wind speed) for
`gcs-swarm compare`, or a randomised world (obstacles in the flight corridor, start states, wind) for one
Monte Carlo run. The simulator reads the world from the mission FILE, so every derivation is written as YAML
and checked with `load_mission`.

Ranges of the randomisation come from a small YAML file (`--ranges FILE`); every key is optional:

    obstacles:
      count: [2, 4]              # obstacles per run (integers, both ends included)
      radius: [2, 4]             # m
      along_track: [0.2, 0.8]    # where along the leader's route (start -> waypoints -> goal), fraction
      cross_track: [-10, 10]     # m, horizontal offset from the route, to its left (+) or right (-)
      altitude: [0, 0]           # m, vertical offset from the route
      speed: [0, 0]              # m/s, horizontal, random direction (0: static)
      keep_out: 4                # m beyond the radius kept free around starts, goal and final slots
      replace: true              # true: only the random obstacles; false: added to the mission's
    starts:
      position_jitter: 2         # m, each start moved by up to this in x and y
      velocity: 1                # m/s, per axis, airborne starts only (ground starts stay at rest)
    wind:
      speed: [0, 5]              # m/s
      direction_deg: [0, 360]    # compass, where it blows from
      turbulence: [0, 0.5]       # m/s
    link:
      loss: [0, 0]               # packet loss probability of every vehicle's link, both directions

The link loss is not part of the mission file: a run passes it to the embedded simulator (`--link-loss`).
"""

from __future__ import annotations

import copy
import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any

import numpy as np
import yaml
from pydantic import ValidationError

from gcs_swarm.guidance.formation import rotate_to_world
from gcs_swarm.guidance.params import PAPER_PLAIN
from gcs_swarm.mission import Mission, MissionError, load_mission
from gcs_swarm.mission.geometry import mission_offsets
from gcs_swarm.mission.schema import Range, Section, error_sentence, pair, settings_problem
from gcs_swarm.mission.yaml_tree import YamlLoader

FORMS = ("paper", "smooth")  # the spec's plain method (PAPER_PLAIN) or the mission's smoothing as written
MIN_START_GAP_M = 2.0  # m between jittered start positions
PLACEMENT_TRIES = 2000


class VariantError(Exception):
    """A variant or a ranges file that cannot be used (one sentence)."""


def read_yaml(path: Path) -> Any:
    """A YAML file as plain Python data; VariantError on unreadable files or syntax errors."""
    try:
        return yaml.load(Path(path).read_text(encoding="utf-8"), Loader=YamlLoader)  # noqa: S506 (safe loader)
    except OSError as exc:
        raise VariantError(f"{path}: cannot read ({exc.strerror or exc})") from None
    except yaml.YAMLError as exc:
        raise VariantError(f"{path}: not valid YAML ({str(exc).splitlines()[0]})") from None


def write_mission(data: dict[str, Any], path: Path) -> Mission:
    """Write mission data as YAML and load it back (MissionError if the derivation is not a valid mission)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return load_mission(path)


@dataclass(frozen=True)
class Variant:
    """What differs from the base mission; None keeps the mission's own setting."""

    method: str | None = None  # guidance.method: "apf" | "iaapf"
    controller: str | None = None  # control.controller: "smc" | "pid"
    wind_speed: float | None = None  # world.wind.speed, m/s
    # "paper": every [add] smoothing off (guidance.params.PAPER_PLAIN); "smooth": as is
    form: str | None = None

    @property
    def label(self) -> str:
        """Short name, e.g. "iaapf", "apf-pid-wind5", "iaapf-paper", "mission" when nothing differs."""
        parts = [p for p in (self.method, self.form, self.controller) if p is not None]
        if self.wind_speed is not None:
            parts.append(f"wind{self.wind_speed:g}")
        return "-".join(parts) or "mission"

    def settings(self) -> dict[str, object]:
        """The mission-file keys (dotted paths such as "guidance.method") this variant sets, with values."""
        out: dict[str, object] = {}
        if self.method is not None:
            out["guidance.method"] = self.method
        if self.controller is not None:
            out["control.controller"] = self.controller
        if self.wind_speed is not None:
            out["world.wind.speed"] = float(self.wind_speed)
        if self.form == "paper":
            for section, values in PAPER_PLAIN.items():
                out |= {f"{section}.{key}": value for key, value in values.items()}
        return out


def variant_grid(
    methods: list[str] | None, controllers: list[str] | None, winds: list[float] | None
) -> list[Variant]:
    """Every combination of the given methods, controllers and wind speeds (an absent list keeps the
    mission's value); `methods` may also name guidance forms (FORMS: `paper` flies the spec's plain
    method, `smooth` the mission as written), crossed with the methods given. VariantError on an unknown
    name or a bad wind speed: each value is checked by the mission schema, as the mission file would be."""
    forms = [v for v in methods or [] if v in FORMS]
    methods = [v for v in methods or [] if v not in FORMS] or None
    checked: list[tuple[str, object, Variant]] = [
        *(("unknown variant", v, Variant(method=v)) for v in methods or []),
        *(("unknown controller", v, Variant(controller=v)) for v in controllers or []),
        *(("wind speed", v, Variant(wind_speed=v)) for v in winds or []),
    ]
    for what, value, variant in checked:
        problem = settings_problem(variant.settings())
        if problem:
            hint = f" (forms: {', '.join(FORMS)})" if variant.method is not None else ""
            raise VariantError(f"{what} {value!r}: {problem}{hint}")
    # each axis: the values given, or None (the mission's own) alone
    method_axis: Sequence[str | None] = methods or [None]
    controller_axis: Sequence[str | None] = controllers or [None]
    wind_axis: Sequence[float | None] = winds or [None]
    form_axis: Sequence[str | None] = forms or [None]
    combos = itertools.product(method_axis, controller_axis, wind_axis, form_axis)
    grid = [Variant(m, c, w, f) for m, c, w, f in combos]
    if len({v.label for v in grid}) != len(grid):
        raise VariantError("the same variant is listed twice")
    return grid


def apply_variant(data: dict[str, Any], variant: Variant, name: str) -> dict[str, Any]:
    """A copy of mission data with the variant's settings and mission.name = name."""
    out = copy.deepcopy(data)
    out["mission"] = {**(out.get("mission") or {}), "name": name}
    for path, value in variant.settings().items():
        *sections, key = path.split(".")
        section = out
        for part in sections:
            section[part] = dict(section.get(part) or {})
            section = section[part]
        section[key] = value
    return out


# ----- Monte Carlo ranges -----


Pair = tuple[float, float]


class ObstacleRanges(Section):
    count: Annotated[tuple[int, int], pair(Range(ge=0))] = (2, 4)
    radius: Annotated[Pair, pair(Range(gt=0, unit="m"))] = (2.0, 4.0)
    along_track: Annotated[Pair, pair(Range(ge=0, le=1))] = (0.2, 0.8)
    cross_track: Annotated[Pair, pair()] = (-10.0, 10.0)
    altitude: Annotated[Pair, pair()] = (0.0, 0.0)
    speed: Annotated[Pair, pair(Range(ge=0, unit="m/s"))] = (0.0, 0.0)
    keep_out: Annotated[float, Range(ge=0, unit="m")] = 4.0
    replace: bool = True


class StartRanges(Section):
    position_jitter: Annotated[float, Range(ge=0, unit="m")] = 2.0
    velocity: Annotated[float, Range(ge=0, unit="m/s")] = 1.0


class WindRanges(Section):
    speed: Annotated[Pair, pair(Range(ge=0, unit="m/s"))] = (0.0, 5.0)
    direction_deg: Annotated[Pair, pair()] = (0.0, 360.0)
    turbulence: Annotated[Pair, pair(Range(ge=0, unit="m/s"))] = (0.0, 0.5)


class LinkRanges(Section):
    loss: Annotated[Pair, pair(Range(ge=0, lt=1))] = (0.0, 0.0)


class Ranges(Section):
    """Randomisation ranges of a Monte Carlo run (module docstring), as the ranges file is validated: pairs
    are (low, high), unknown keys refused with a "did you mean"."""

    obstacles: ObstacleRanges = ObstacleRanges()
    starts: StartRanges = StartRanges()
    wind: WindRanges = WindRanges()
    link: LinkRanges = LinkRanges()


def parse_ranges(data: Any, source: str) -> Ranges:
    """Ranges from parsed YAML (None or {} = the defaults); VariantError naming the key on any mistake."""
    try:
        return Ranges.model_validate(data)
    except ValidationError as exc:
        raise VariantError(f"{source}: {error_sentence(exc)}") from None


def load_ranges(path: Path | None) -> Ranges:
    """The ranges file (None: the defaults)."""
    return Ranges() if path is None else parse_ranges(read_yaml(path), str(path))


def _route(mission: Mission) -> np.ndarray:
    """The leader's route (W, 3) m: its start, then its waypoints (the last is the goal); the start is taken
    at formation altitude for a ground start."""
    start = np.array(mission.vehicles[mission.leader_index].start.position, dtype=float)
    if not mission.run.airborne_start:
        start[2] = mission.formation.altitude
    return np.vstack([start, *[np.asarray(w, dtype=float) for w in mission.waypoints]])


def _point_on_route(route: np.ndarray, fraction: float) -> tuple[np.ndarray, np.ndarray]:
    """Point (3,) at `fraction` of the route's length and the unit horizontal direction (2,) of that leg."""
    legs = np.diff(route, axis=0)
    lengths = np.linalg.norm(legs, axis=1)
    total = float(lengths.sum())
    if total <= 0:
        raise VariantError("the leader starts at its goal: there is no route to place obstacles on")
    s = fraction * total
    k = min(int(np.searchsorted(np.cumsum(lengths), s)), len(legs) - 1)
    into = s - float(lengths[:k].sum())
    point = route[k] + legs[k] * (into / lengths[k] if lengths[k] > 0 else 0.0)
    horizontal = legs[k, :2]
    norm = float(np.linalg.norm(horizontal))
    return point, (horizontal / norm if norm > 0 else np.array([1.0, 0.0]))


def _protected_points(mission: Mission, starts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Points (P, 3) that obstacles keep clear of and whether each is a column (ground start: the vehicle
    climbs vertically there, so only horizontal distance counts): starts, waypoints, goal, final slots,
    targets."""
    route = _route(mission)
    last = route[-1] - route[-2]
    psi_final = math.atan2(last[1], last[0]) if np.linalg.norm(last[:2]) > 0 else 0.0
    slots = np.asarray(mission.goal, dtype=float) + rotate_to_world(mission_offsets(mission), psi_final)
    targets = [np.asarray(v.target, dtype=float) for v in mission.vehicles if v.target is not None]
    points = np.vstack([starts, *mission.waypoints, slots, *targets])
    column = np.zeros(len(points), dtype=bool)
    column[: len(starts)] = not mission.run.airborne_start
    return points, column


def _clear(centre: np.ndarray, radius: float, points: np.ndarray, column: np.ndarray, gap: float) -> bool:
    d = np.linalg.norm(points - centre, axis=1)
    d_h = np.linalg.norm(points[:, :2] - centre[:2], axis=1)
    return bool(np.all(np.where(column, d_h, d) > radius + gap))


def _random_starts(mission: Mission, ranges: Ranges, rng: np.random.Generator) -> list[dict[str, Any]]:
    """Jittered start states in vehicle order (positions apart by MIN_START_GAP_M)."""
    base = np.array([v.start.position for v in mission.vehicles], dtype=float)
    for _ in range(PLACEMENT_TRIES):
        pos = base.copy()
        pos[:, :2] += rng.uniform(
            -ranges.starts.position_jitter, ranges.starts.position_jitter, size=(len(base), 2)
        )
        gaps = np.linalg.norm(pos[:, None] - pos[None], axis=-1) + np.eye(len(pos)) * 1e9
        if gaps.min() >= MIN_START_GAP_M:
            break
    else:
        raise VariantError("cannot place the jittered starts 2 m apart: lower starts.position_jitter")
    starts = []
    for v, p in zip(mission.vehicles, pos, strict=True):
        vel = np.zeros(3)
        if mission.run.airborne_start:
            vel = np.asarray(v.start.velocity, dtype=float) + rng.uniform(
                -ranges.starts.velocity, ranges.starts.velocity, size=3
            )
        starts.append(
            {"position": [round(float(x), 3) for x in p], "velocity": [round(float(x), 3) for x in vel]}
            | {"yaw_deg": float(v.start.yaw_deg)}
        )
    return starts


def _random_obstacles(
    mission: Mission, ranges: Ranges, starts: np.ndarray, rng: np.random.Generator
) -> list[dict[str, Any]]:
    """Obstacles in the flight corridor, each clear of the protected points by keep_out beyond its radius."""
    route = _route(mission)
    points, column = _protected_points(mission, starts)
    lo, hi = int(ranges.obstacles.count[0]), int(ranges.obstacles.count[1])
    count = int(rng.integers(lo, hi + 1))
    gap = ranges.obstacles.keep_out + mission.safety.collision_radius
    obstacles = []
    for k in range(count):
        for _ in range(PLACEMENT_TRIES):
            point, direction = _point_on_route(route, rng.uniform(*ranges.obstacles.along_track))
            left = np.array([-direction[1], direction[0], 0.0])
            centre = point + left * rng.uniform(*ranges.obstacles.cross_track)
            centre[2] += rng.uniform(*ranges.obstacles.altitude)
            radius = rng.uniform(*ranges.obstacles.radius)
            if _clear(centre, radius, points, column, gap):
                break
        else:
            raise VariantError(
                f"cannot place obstacle {k + 1} clear of the starts, goal and slots: widen "
                "obstacles.along_track / cross_track or lower obstacles.radius / keep_out"
            )
        heading = rng.uniform(0.0, 2.0 * math.pi)
        speed = rng.uniform(*ranges.obstacles.speed)
        obstacles.append(
            {
                "center": [round(float(x), 3) for x in centre],
                "radius": round(float(radius), 3),
                "velocity": [round(speed * math.cos(heading), 3), round(speed * math.sin(heading), 3), 0.0],
            }
        )
    return obstacles


def randomise(data: dict[str, Any], mission: Mission, ranges: Ranges, seed: int) -> dict[str, Any]:
    """A copy of mission data (`mission` = its loaded form) with a random world drawn from `ranges` by
    numpy's default_rng(seed): the same seed gives the same world. Also sets run.simulator.seed = seed."""
    rng = np.random.default_rng(seed)
    out = copy.deepcopy(data)
    starts = _random_starts(mission, ranges, rng)
    for vehicle, start in zip(out["vehicles"], starts, strict=True):
        vehicle["start"] = start
    obstacles = _random_obstacles(mission, ranges, np.array([s["position"] for s in starts]), rng)
    world = dict(out.get("world") or {})
    kept = [] if ranges.obstacles.replace else list(world.get("obstacles") or [])
    world["obstacles"] = kept + obstacles
    world["wind"] = {
        "speed": round(float(rng.uniform(*ranges.wind.speed)), 3),
        "direction_deg": round(float(rng.uniform(*ranges.wind.direction_deg)) % 360.0, 3),
        "turbulence": round(float(rng.uniform(*ranges.wind.turbulence)), 3),
    }
    out["world"] = world
    run = dict(out.get("run") or {})
    run["simulator"] = {**(run.get("simulator") or {}), "seed": int(seed)}
    out["run"] = run
    return out


def link_loss(ranges: Ranges, seed: int) -> float:
    """The link loss probability of run `seed`, drawn from its own stream (so adding it leaves the worlds of
    `randomise` unchanged)."""
    lo, hi = ranges.link.loss
    return 0.0 if hi <= 0.0 else round(float(np.random.default_rng([seed, 1]).uniform(lo, hi)), 4)


def derive_monte_carlo_run(
    base_path: Path, ranges: Ranges, seed: int, variant: Variant, out_path: Path
) -> Mission:
    """Write the mission of Monte Carlo run (seed, variant) to out_path: the base mission with the world of
    `seed` (identical for every variant of that seed) and the variant's settings; returns it loaded. The run's
    link loss is `link_loss(ranges, seed)`."""
    base = load_mission(base_path)
    data = read_yaml(base_path)
    name = f"{base.name[:40]}-s{seed}-{variant.label}"[:64]
    try:
        return write_mission(apply_variant(randomise(data, base, ranges, seed), variant, name), out_path)
    except MissionError as exc:
        raise VariantError(f"seed {seed}: the randomised mission is not valid: {exc}") from None


def derive_variant(base_path: Path, variant: Variant, out_path: Path) -> Mission:
    """Write the base mission with the variant's settings to out_path; returns it loaded."""
    base = load_mission(base_path)
    name = f"{base.name[:40]}-{variant.label}"[:64]
    return write_mission(apply_variant(read_yaml(base_path), variant, name), out_path)
