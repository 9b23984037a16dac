"""Cost of one FleetController.tick (formation targets, obstacle + inter-UAV field, reference generator, SMC,
inversion) for the whole fleet, and of the command guard after it (ArduPilot thrust + guard_attitude_commands,
as gcs_swarm.flight.formation_tick runs them): small fleets N = 3, 6, 9 with K = 0 and 10 obstacles, and
N = 9, 100, 1000 with K = 10 and 100.

The fleet flies a grid formation with 9 m spacing (inside D_max = 10 m, so the inter-UAV term is active);
obstacles are spread over the fleet's area, so many vehicle-obstacle pairs are inside l0 = 20 m. The
controller is configured as the bundled missions fly it: an altitude floor, the dead-GCS speed scheduling
and the pace from the vehicles' drag (guidance.pace) on. Prints a Markdown table: median per tick over
repeats, with the spread (min..max of the repeat medians).

    python benchmarks/bench_guidance.py [--repeats 7] [--ticks 50] [--quick] [--max-n 1000]

With --baseline DIR: the tick of this tree against the tick of the gcs_swarm/guidance package of another tree
(DIR, e.g. an export of an older commit: `git archive <commit> gcs_swarm | tar -x -C DIR`), loaded side by
side in this process, interleaved repeat by repeat, N = --sizes with K = 10; `uptime` is printed alongside.

    python benchmarks/bench_guidance.py --baseline /tmp/old --sizes 3,6,9,50,100,200 --repeats 7
"""

from __future__ import annotations

import argparse
import importlib
import importlib.util
import math
import os
import statistics
import sys
import time
from pathlib import Path
from types import ModuleType

import numpy as np

import gcs_swarm
from gcs_swarm.guidance.fleet_controller import FleetController
from gcs_swarm.guidance.formation import formation_offsets
from gcs_swarm.guidance.params import CapabilityParams, DeadGcsParams, FieldParams, G
from gcs_swarm.link.attitude_commands import attitude_commands
from gcs_swarm.link.autopilots import ARDUPILOT
from gcs_swarm.link.command_limits import CommandLimits

SPACING = 9.0  # m
DT = 0.02  # s, 50 Hz


def scenario(n: int, k: int, seed: int = 0, guidance: dict[str, ModuleType] | None = None):
    """A controller, the fleet state and obstacles; deterministic. `guidance`: the modules fleet_controller
    and params to build it from (default this tree's)."""
    rng = np.random.default_rng(seed)
    offsets = np.zeros((n, 3))
    offsets[1:] = formation_offsets("grid", n - 1, SPACING)
    controller_class = FleetController if guidance is None else guidance["fleet_controller"].FleetController
    dead_gcs_class = DeadGcsParams if guidance is None else guidance["params"].DeadGcsParams
    pace_class = CapabilityParams if guidance is None else guidance["params"].CapabilityParams
    ctl = controller_class(
        n, 0, offsets, np.array([[5000.0, 0.0, 50.0]]), control_dt=DT, z_min=5.0,
        dead_gcs=dead_gcs_class(failsafe_timeout_s=3.0, brake_accel=2.5, brake_jerk=5.0), pace=pace_class(),
    )  # fmt: skip
    pos = offsets + np.array([0.0, 0.0, 50.0]) + rng.normal(0.0, 0.5, (n, 3))
    vel = np.tile([8.0, 0.0, 0.0], (n, 1)) + rng.normal(0.0, 0.3, (n, 3))
    att = np.zeros((n, 3))
    lo, hi = pos.min(axis=0) - 20.0, pos.max(axis=0) + 20.0
    centres = lo + rng.uniform(0.0, 1.0, (k, 3)) * (hi - lo)
    radii = rng.uniform(1.0, 4.0, k)
    centres[:, 0] += 15.0  # keep the vehicles themselves outside the spheres
    ctl.reset(pos, vel, att[:, 2])
    return ctl, pos, vel, att, centres, radii


def close_pairs(pos: np.ndarray, centres: np.ndarray, radii: np.ndarray, l0: float, d_max: float):
    """Vehicle-obstacle pairs within l0 of the surface and vehicle pairs within D_max (for context)."""
    obs = int((np.linalg.norm(pos[:, None] - centres[None], axis=2) - radii <= l0).sum())
    d = np.linalg.norm(pos[:, None] - pos[None], axis=2)
    return obs, int(((d < d_max).sum() - len(pos)) // 2)


def time_ticks(n: int, k: int, repeats: int, ticks: int) -> list[float]:
    """Per-tick seconds, one median per repeat."""
    ctl, pos, vel, att, centres, radii = scenario(n, k)
    active = np.ones(n, dtype=bool)
    t = 0.0
    for _ in range(5):  # warm-up
        ctl.tick(t, pos, vel, att, centres, radii, active)
        t += DT
    out = []
    for _ in range(repeats):
        samples = []
        for _ in range(ticks):
            start = time.perf_counter()
            ctl.tick(t, pos, vel, att, centres, radii, active)
            samples.append(time.perf_counter() - start)
            t += DT
        out.append(statistics.median(samples))
    return out


def time_ab(
    n: int, k: int, repeats: int, ticks: int, runs: dict[str, tuple], before_each: dict[str, object]
) -> dict[str, list[float]]:
    """Per-tick seconds of two or more controllers of the same scenario (`runs`: name -> scenario() tuple),
    one median per repeat each, run alternately (the order swapped every repeat); `before_each[name]()` is
    called before that name's ticks (to select a code path). The first round is a warm-up."""
    active = np.ones(n, dtype=bool)
    times: dict[str, list[float]] = {name: [] for name in runs}
    t = 0.0
    names = list(runs)
    for repeat in range(repeats + 1):
        for name in names if repeat % 2 else names[::-1]:
            ctl, pos, vel, att, centres, radii = runs[name]
            before_each[name]()  # type: ignore[operator]
            samples = []
            for tick in range(ticks):
                start = time.perf_counter()
                ctl.tick(t + tick * DT, pos, vel, att, centres, radii, active)
                samples.append(time.perf_counter() - start)
            if repeat:
                times[name].append(statistics.median(samples))
        t += ticks * DT
    return times


def print_ab(title: str, names: tuple[str, str], sizes: list[int], repeats: int, ticks: int, setup) -> None:
    """One A/B table: per N, each path's median ms per tick (min..max over repeats) and the ratio."""
    print(f"{title}, K = 10, median of {repeats} x {ticks} ticks per repeat, interleaved")
    print(f"uptime: {os.popen('uptime').read().strip()}")
    print()
    print(
        f"| N | {names[0]} ms / tick (min..max) | {names[1]} ms / tick (min..max) | {names[0]} / {names[1]} |"
    )
    print("|---|---|---|---|")
    for n in sizes:
        runs, before_each = setup(n)
        times = time_ab(n, 10, repeats, ticks, runs, before_each)
        (a_med, a_txt), (b_med, b_txt) = spread(times[names[0]]), spread(times[names[1]])
        print(f"| {n} | {a_txt} | {b_txt} | {a_med / b_med:.2f} |")
    print(f"uptime: {os.popen('uptime').read().strip()}")


def load_guidance(root: Path) -> dict[str, ModuleType]:
    """The modules fleet_controller and params of the gcs_swarm/guidance package under `root`, imported
    beside this tree's (sys.modules is restored afterwards, so both stay usable)."""
    for cached in (root / "gcs_swarm").rglob("*.nb[ic]"):
        cached.unlink()  # numba's cache of a package loaded this way names no importable module: not reusable
    ours = {
        name: mod for name, mod in sys.modules.items() if name.split(".")[:2] == ["gcs_swarm", "guidance"]
    }
    for name in ours:
        del sys.modules[name]
    package = root / "gcs_swarm" / "guidance"
    spec = importlib.util.spec_from_file_location(
        "gcs_swarm.guidance", package / "__init__.py", submodule_search_locations=[str(package)]
    )
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules["gcs_swarm.guidance"] = module
    try:
        spec.loader.exec_module(module)
        loaded = {
            name: importlib.import_module(f"gcs_swarm.guidance.{name}")
            for name in ("fleet_controller", "params")
        }
    finally:
        for name in [name for name in sys.modules if name.split(".")[:2] == ["gcs_swarm", "guidance"]]:
            del sys.modules[name]
        sys.modules.update(ours)
        gcs_swarm.guidance = ours["gcs_swarm.guidance"]  # type: ignore[attr-defined]
    return loaded


def baseline_ab(root: Path, sizes: list[int], repeats: int, ticks: int) -> None:
    """This tree's tick against the guidance package under `root`."""
    old = load_guidance(root)

    def setup(n: int):
        return {"baseline": scenario(n, 10, guidance=old), "this tree": scenario(n, 10)}, {
            "baseline": lambda: None,
            "this tree": lambda: None,
        }

    print_ab(
        f"FleetController.tick, {root} vs this tree", ("baseline", "this tree"), sizes, repeats, ticks, setup
    )


GUARD = CommandLimits(math.radians(35.0), 2.0, 5.0, 7000.0, 400.0)


def time_guard(n: int, k: int, repeats: int, ticks: int) -> list[float]:
    """Per-tick seconds of the send step for one tick's command (formation_tick's attitude_commands:
    ArduCopter's thrust, then the command guard), one median per repeat."""
    ctl, pos, vel, att, centres, radii = scenario(n, k)
    cmd = ctl.tick(0.0, pos, vel, att, centres, radii, np.ones(n, dtype=bool))
    hover, boost = np.full(n, 0.45), np.arange(n) % 2 == 0
    out = []
    for _ in range(repeats):
        samples = []
        for _ in range(ticks):
            start = time.perf_counter()
            attitude_commands(
                cmd.roll_d, cmd.pitch_d, cmd.yaw_d, cmd.thrust_acc, att, pos, vel, hover, boost, G, GUARD,
                [ARDUPILOT] * n,
            )  # fmt: skip
            samples.append(time.perf_counter() - start)
        out.append(statistics.median(samples))
    return out


def spread(seconds: list[float]) -> tuple[float, str]:
    """Median in ms and "median (min..max)" of per-repeat medians in seconds."""
    ms = [x * 1e3 for x in seconds]
    med = statistics.median(ms)
    return med, f"{med:.3f} ({min(ms):.3f}..{max(ms):.3f})"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=7, help="repeats per case (median and spread)")
    parser.add_argument("--ticks", type=int, default=50, help="ticks timed per repeat")
    parser.add_argument("--quick", action="store_true", help="3 repeats of 20 ticks")
    parser.add_argument("--max-n", type=int, default=1000, help="skip fleets larger than this")
    parser.add_argument("--baseline", type=Path, help="A/B against the guidance package of this tree root")
    parser.add_argument("--sizes", default="3,6,9,50,100,200", help="fleet sizes of the A/B tables")
    args = parser.parse_args()
    repeats, ticks = (3, 20) if args.quick else (args.repeats, args.ticks)
    sizes = [int(x) for x in args.sizes.split(",")]
    if args.baseline is not None:
        baseline_ab(args.baseline, sizes, repeats, ticks)
        return
    fp = FieldParams()
    print(
        f"FleetController.tick, SMC + IAAPF, grid spacing {SPACING:g} m, median of {repeats} x {ticks} ticks"
    )
    print()
    columns = ("N", "K", "obstacle pairs < l0", "UAV pairs < D_max", "ms / tick (min..max)", "us / vehicle")
    print("| " + " | ".join(columns) + " | 50 Hz load | guard ms / tick (min..max) |")
    print("|---|---|---|---|---|---|---|---|")
    small = [(n, k) for n in (3, 6, 9) for k in (0, 10)]
    large = [(n, k) for n in (9, 100, 1000) for k in (10, 100) if (n, k) not in small]
    for n, k in [case for case in small + large if case[0] <= args.max_n]:
        ctl, pos, _, _, centres, radii = scenario(n, k)
        n_obs, n_uav = close_pairs(pos, centres, radii, fp.l0, ctl.d_max)
        med, cost = spread(time_ticks(n, k, repeats, ticks))
        _, guard = spread(time_guard(n, k, repeats, ticks))
        load = med / (DT * 1e3) * 100
        print(f"| {n} | {k} | {n_obs} | {n_uav} | {cost} | {med / n * 1e3:.1f} | {load:.1f} % | {guard} |")


if __name__ == "__main__":
    main()
