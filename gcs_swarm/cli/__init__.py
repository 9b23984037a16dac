"""`gcs-swarm` command line: run, console, check, plan, report, replay, compare, montecarlo, import."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

from gcs_swarm.guidance.params import FieldMethod

if TYPE_CHECKING:
    from gcs_swarm.mission import Mission

EXIT_USER_ERROR = 2


VARIANTS_HELP = "guidance methods and forms, e.g. apf,iaapf or paper,smooth (the plain method, the smoothing)"


def _flight_options(args: argparse.Namespace) -> dict[str, Any]:
    """The options `run` and `console` share (`_add_flight_flags`), as keyword arguments."""
    return {
        "out_dir": Path(args.out) if args.out else None,
        "connect_only": args.connect_only,
        "base_port": args.base_port,
        "keep_params": args.keep_params,
        "forward": tuple(args.forward),
        "forward_rw": args.forward_rw,
    }


def _cmd_run(args: argparse.Namespace) -> int:
    from gcs_swarm.cli.run import run_command
    from gcs_swarm.flight.fly import RunOptions

    page = None
    if args.web is not None:
        from gcs_swarm.web.live import start_live_page

        page = start_live_page(args.web, None)
        if page is None:
            return EXIT_USER_ERROR
    options = RunOptions(
        **_flight_options(args),
        time_mode=args.time_mode,
        seed=args.seed,
        quiet=args.quiet,
        sim_args=tuple(args.sim_arg),
        crash_at=args.crash_at,
        airborne=args.airborne,
        watch=None if page is None else page.watch,
    )
    try:
        return run_command(args.mission, options)
    finally:
        if page is not None:
            page.stop()


def _cmd_console(args: argparse.Namespace) -> int:
    from gcs_swarm.console.main import ConsoleOptions, console_command

    script = Path(args.script) if args.script else None
    if args.web_token is not None and args.web is None:
        print("error: --web-token needs --web (the page it allows actions on)")
        return EXIT_USER_ERROR
    options = ConsoleOptions(
        **_flight_options(args), script=script, yes=args.yes, web=args.web, web_token=args.web_token
    )
    return console_command(args.mission, options)


def _add_flight_flags(parser: argparse.ArgumentParser, verb: str) -> None:
    """The flags `run` and `console` share: the mission, the run folder, the embedded simulator or running
    vehicles (`verb` says what is done to them), the flight parameters, the forwards
    (docs/watching-with-qgc.md)."""
    parser.add_argument("mission", help="mission file (YAML)")
    parser.add_argument("--out", help="run folder (default runs/<time>-<mission>/)")
    parser.add_argument(
        "--connect-only",
        action="store_true",
        help=f"{verb} vehicles that are already running (no embedded simulator)",
    )
    parser.add_argument(
        "--base-port", type=int, help="embedded simulator: first UDP port (vehicle i on port+i)"
    )
    parser.add_argument(
        "--keep-params",
        action="store_true",
        help="leave the parameters the run sets (GUID_OPTIONS, FS_GCS_*, GUID_TIMEOUT) as flown instead of "
        "restoring them on the ground (also run.keep_params)",
    )
    parser.add_argument(
        "--forward",
        action="append",
        default=[],
        metavar="ENDPOINT",
        help="send every vehicle frame, unchanged, to another ground station at ENDPOINT (a pymavlink "
        "connection string, e.g. udpout:127.0.0.1:14550 for QGroundControl; repeatable; added to "
        "run.forward); read-only: it may watch and read parameters",
    )
    parser.add_argument(
        "--forward-rw",
        action="store_true",
        help="let the forwards' commands through to the vehicle their target system names (modes, arming, "
        "parameters...); on a signed fleet only if they carry a valid signature (also run.forward_rw)",
    )
    parser.add_argument(
        "--web",
        nargs="?",
        const="127.0.0.1:8765",
        metavar="HOST:PORT",
        help="serve the live page (docs/replay.md) on HOST:PORT (default 127.0.0.1:8765; port 0: any free "
        "one); another host than loopback lets other machines watch",
    )


def _load(path: str, *, to_fly: bool = True) -> Mission | None:
    """The mission file loaded, or None after printing its mistake (`to_fly`: as load_mission)."""
    from gcs_swarm.mission import MissionError, load_mission

    try:
        return load_mission(path, to_fly=to_fly)
    except MissionError as exc:
        print(f"error: {exc}")
        return None


def _cmd_check(args: argparse.Namespace) -> int:
    from gcs_swarm.mission import MissionError, load_mission

    mission = _load(args.mission, to_fly=False)
    if mission is None:
        return EXIT_USER_ERROR
    leader = mission.vehicles[mission.leader_index].name
    site = [(len(mission.prisms), "buildings"), (len(mission.cylinders), "trees or masts")]
    site += [(len(mission.fence.exclusions), "exclusion zones"), (len(mission.legs), "legs")]
    fence = ", a fence polygon" if mission.fence.polygon is not None else ""
    print(
        f"{args.mission}: ok: mission '{mission.name}', {len(mission.vehicles)} vehicles (leader {leader}), "
        f"{len(mission.obstacles)} obstacles{''.join(f', {n} {what}' for n, what in site if n)}{fence}, "
        f"goal {[round(float(x), 2) + 0.0 for x in mission.goal]}"  # + 0.0: no -0.0
    )
    try:
        load_mission(args.mission)
    except MissionError as exc:  # the flight refuses it (checks.flight_refusal: legs too near the site fence)
        print(f"note: valid, but it cannot be flown yet: {exc}")
    return 0


def _cmd_import(args: argparse.Namespace) -> int:
    from gcs_swarm.cli.site_import import import_command

    if args.vehicles < 1:
        print("error: --vehicles must be at least 1")
        return EXIT_USER_ERROR
    if not args.spacing > 0:
        print("error: --spacing must be > 0 m")
        return EXIT_USER_ERROR
    return import_command(args.files, args.out, args.vehicles, args.spacing)


def _cmd_plan(args: argparse.Namespace) -> int:
    from gcs_swarm.evaluation.planning import plan_json, plan_mission, plot_plan

    mission = _load(args.mission)
    if mission is None:
        return EXIT_USER_ERROR
    result = plan_mission(mission, args.method)
    figures = plan_json(result)
    if args.json:
        print(json.dumps(figures))
    else:
        for key, value in figures.items():
            print(f"{key:>20}: {value}")
    if args.plot:
        if not plot_plan({args.method: result}, mission.obstacles, Path(args.plot)):
            print("note: matplotlib is not installed (pip install 'swarm-gcs[plot]'); no plot written")
    return 0


def _cmd_report(args: argparse.Namespace) -> int:
    from gcs_swarm.evaluation.report import write_report

    run_dir = Path(args.run_dir)
    flight_path = run_dir / "flight.json"
    if not flight_path.exists():
        print(f"error: {run_dir} is not a run folder (no flight.json)")
        return EXIT_USER_ERROR
    mission = _load(args.mission or json.loads(flight_path.read_text()).get("mission_path"))
    if mission is None:
        return EXIT_USER_ERROR
    report = write_report(run_dir, mission)
    print((run_dir / "report.md").read_text())
    return 0 if report["reached"] and report["collisions"] == 0 else 1


def _cmd_replay(args: argparse.Namespace) -> int:
    from gcs_swarm.cli.replay import replay_command

    return replay_command(
        Path(args.run_dir),
        Path(args.mission) if args.mission else None,
        args.host,
        args.port,
        args.speed,
        Path(args.export) if args.export else None,
    )


def _csv_list(kind: type, text: str) -> list:
    try:
        return [kind(x.strip()) for x in text.split(",") if x.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a comma-separated list, got {text!r}") from None


def _cmd_compare(args: argparse.Namespace) -> int:
    from gcs_swarm.evaluation.compare import CompareOptions, compare_command

    options = CompareOptions(
        methods=args.variants,
        controllers=args.controllers,
        winds=args.wind,
        out_dir=Path(args.out) if args.out else None,
    )
    return compare_command(args.mission, options, print)


def _cmd_montecarlo(args: argparse.Namespace) -> int:
    from gcs_swarm.evaluation.montecarlo import CampaignOptions, montecarlo_command

    options = CampaignOptions(
        runs=args.runs,
        seed=args.seed,
        variants=tuple(args.variants or ()),
        jobs=args.jobs,
        scheduler=args.scheduler,
        out_dir=Path(args.out) if args.out else None,
        ranges_path=Path(args.ranges) if args.ranges else None,
        keep_runs=args.keep_runs,
    )
    return montecarlo_command(args.mission, options, print)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="gcs-swarm",
        description="Ground station for quadrotor swarms: IAAPF-SMC formation flight over MAVLink.",
    )
    sub = parser.add_subparsers(dest="command", required=True)

    run = sub.add_parser("run", help="fly a mission and write a run folder with its report")
    _add_flight_flags(run, "fly")
    run.add_argument(
        "--time-mode",
        choices=("lockstep", "realtime", "speedup"),
        help="embedded simulator time mode override",
    )
    run.add_argument("--seed", type=int, help="embedded simulator seed override")
    run.add_argument("--quiet", action="store_true", help="no progress output")
    run.add_argument(
        "--sim-arg",
        action="append",
        default=[],
        metavar="ARG",
        help="pass ARG verbatim to the embedded simulator, e.g. --sim-arg=--link-loss=0.1 (repeatable)",
    )
    run.add_argument(
        "--airborne",
        choices=("finish", "land"),
        help="with --connect-only, vehicles found already flying (a crashed ground station left them holding "
        "in BRAKE): finish the mission from where they are, or land them where they are; without it such a "
        "run stops and says what it found",
    )
    run.add_argument(
        "--crash-at",
        type=float,
        metavar="T",
        help="rehearse a ground-station crash: SIGKILL this process at vehicle time T s (time since the "
        "vehicles booted), as an out-of-memory kill would; the vehicles' failsafes take over",
    )
    run.set_defaults(func=_cmd_run)

    console = sub.add_parser("console", help="operator console: watch and command the swarm live")
    _add_flight_flags(console, "command")
    console.add_argument("--yes", action="store_true", help="do not ask before commands that arm or launch")
    console.add_argument(
        "--script", metavar="FILE", help="run the commands in FILE (plain output, no full-screen UI)"
    )
    console.add_argument(
        "--web-token",
        metavar="TOKEN",
        help="with --web: the page may land, rtl, hold, rejoin and lead (the console's verbs) when it gives "
        "TOKEN; without it the page is read-only",
    )
    console.set_defaults(func=_cmd_console)

    check = sub.add_parser("check", help="validate a mission file without flying")
    check.add_argument("mission")
    check.set_defaults(func=_cmd_check)

    site = sub.add_parser(
        "import", help="write a mission from site files: QGroundControl .plan, GeoJSON, KML (docs/site.md)"
    )
    site.add_argument("files", nargs="+", metavar="FILE", help="site files (.plan, .geojson/.json, .kml)")
    site.add_argument("--out", required=True, metavar="MISSION.yaml", help="the mission file to write")
    site.add_argument("--vehicles", type=int, default=3, help="vehicles in the fleet (default 3)")
    site.add_argument("--spacing", type=float, default=3.0, help="m between start positions (default 3)")
    site.set_defaults(func=_cmd_import)

    plan = sub.add_parser("plan", help="kinematic APF/IAAPF path of the leader (preview, Table 1 experiment)")
    plan.add_argument("mission")
    plan.add_argument("--method", choices=[law.value for law in FieldMethod], default="iaapf")
    plan.add_argument("--json", action="store_true", help="print the figures as one JSON object")
    plan.add_argument("--plot", metavar="FILE.png", help="write the path plot (needs matplotlib)")
    plan.set_defaults(func=_cmd_plan)

    report = sub.add_parser("report", help="(re)build a run folder's report")
    report.add_argument("run_dir")
    report.add_argument("--mission", help="mission file (default: the one recorded in the run folder)")
    report.set_defaults(func=_cmd_report)

    replay = sub.add_parser(
        "replay", help="watch a run folder in the browser, or --export its top view (docs/replay.md)"
    )
    replay.add_argument("run_dir", metavar="RUN_DIR")
    replay.add_argument("--mission", help="mission file (default: the one recorded in the run folder)")
    replay.add_argument("--host", default="127.0.0.1", help="address to serve on (default 127.0.0.1)")
    replay.add_argument("--port", type=int, default=8765, help="TCP port (default 8765; 0: any free one)")
    replay.add_argument(
        "--speed", type=float, help="replay s per s: on the page at the start (default 1), in the export (4)"
    )
    replay.add_argument(
        "--export",
        metavar="OUT.gif|OUT.mp4",
        help="write an animation of the top view instead (.mp4: ffmpeg)",
    )
    replay.set_defaults(func=_cmd_replay)

    compare = sub.add_parser("compare", help="fly a mission under several variants and compare them")
    compare.add_argument("mission")
    compare.add_argument(
        "--variants",
        type=lambda s: _csv_list(str, s),
        help=VARIANTS_HELP,
    )
    compare.add_argument("--controllers", type=lambda s: _csv_list(str, s), help="e.g. smc,pid")
    compare.add_argument("--wind", type=lambda s: _csv_list(float, s), help="wind speeds m/s, e.g. 0,5,10")
    compare.add_argument("--out", help="output folder (default runs/compare-<mission>-<time>/)")
    compare.set_defaults(func=_cmd_compare)

    mc = sub.add_parser("montecarlo", help="resumable Monte Carlo campaign of randomised flights")
    mc.add_argument("mission")
    mc.add_argument("--runs", type=int, required=True, help="number of random worlds (seeds)")
    mc.add_argument("--seed", type=int, default=0, help="first seed; run k uses seed+k (default 0)")
    mc.add_argument(
        "--variants",
        type=lambda s: _csv_list(str, s),
        help=VARIANTS_HELP,
    )
    mc.add_argument("--jobs", type=int, default=2, help="local worker processes (default 2)")
    mc.add_argument("--scheduler", metavar="ADDRESS", help="run on this Dask distributed scheduler")
    mc.add_argument("--ranges", metavar="FILE", help="YAML of randomisation ranges (docs/paper-results.md)")
    mc.add_argument("--out", help="campaign folder (default runs/montecarlo-<mission>-seed<S>/)")
    mc.add_argument("--keep-runs", action="store_true", help="keep truth, record and tlog of every run")
    mc.set_defaults(func=_cmd_montecarlo)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return int(args.func(args))
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":
    sys.exit(main())
