"""`gcs-swarm montecarlo MISSION.yaml --runs N --seed S`: N randomised worlds (seeds S..S+N-1,
gcs_swarm.evaluation.variants) flown for real, once per variant, on local processes (`--jobs`) or on a Dask
distributed cluster (`--scheduler ADDRESS`), into a resumable campaign folder
(gcs_swarm.evaluation.campaign_store).

Every variant of a seed flies the same world, so variants are compared run by run. Rerunning the same command
flies only the (seed, variant) pairs without a result. Run folders are kept under OUT/runs/<variant>/seed-<S>/
with their mission.yaml, flight.json and report.json/md; the bulky logs (truth, record, tlog) only with
--keep-runs.
"""

from __future__ import annotations

import concurrent.futures as cf
import hashlib
import json
import multiprocessing
import signal
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

from gcs_swarm.evaluation import campaign_store, figures, flights, variants
from gcs_swarm.evaluation.campaign_store import CampaignError, CampaignStore
from gcs_swarm.evaluation.error_log import log_exception, traceback_note
from gcs_swarm.flight.fly import EXIT_FAILED, EXIT_OK, EXIT_USER_ERROR
from gcs_swarm.mission import MissionError, load_mission

EXIT_INTERRUPTED = 130
BULKY_FILES = ("truth.csv", "truth.obstacles.csv", "record.csv", "telemetry.tlog")


@dataclass(frozen=True)
class RunTask:
    """One Monte Carlo flight, self-contained so that a remote worker needs no shared files."""

    seed: int
    variant: str
    mission_yaml: str  # the derived mission file's text
    vehicles: int
    run_dir: str
    collision_radius: float  # m
    keep_files: bool
    world: dict[str, float]  # what was drawn: obstacle count, wind speed m/s, link loss probability


def fly_task(task: RunTask) -> dict[str, Any]:
    """Fly one task (in a worker process or a Dask worker) and return its result line. Never raises: a failure
    outside the flight becomes a line with an `error` naming the run folder's errors.log, which holds its
    traceback; a resumed campaign flies the run again."""
    start = time.monotonic()
    run_dir = Path(task.run_dir)
    result: dict[str, Any] = {"seed": task.seed, "variant": task.variant, "world": task.world}
    in_main_thread = threading.current_thread() is threading.main_thread()
    previous = signal.signal(signal.SIGINT, signal.default_int_handler) if in_main_thread else None
    try:
        run_dir.mkdir(parents=True, exist_ok=True)
        mission_path = run_dir / "mission.yaml"
        mission_path.write_text(task.mission_yaml)
        status = flights.fly(mission_path, run_dir, task.vehicles, task.world["link_loss"])
        result |= flights.flight_figures(run_dir, status, task.collision_radius)
        if status == EXIT_USER_ERROR:
            result["error"] = "the flight could not start (simulator or link); see the run folder"
        elif any("interrupted" in e for e in result["events"]):
            result["error"] = "interrupted"
        if not task.keep_files:
            for name in BULKY_FILES:
                (run_dir / name).unlink(missing_ok=True)
    except KeyboardInterrupt:
        result["error"] = "interrupted"
    except Exception as exc:  # noqa: BLE001 - reported in the result line, the campaign goes on
        logged = log_exception(run_dir, f"Monte Carlo run seed {task.seed} variant {task.variant} failed")
        result["error"] = f"{type(exc).__name__}: {exc}{traceback_note(logged)}"
    finally:
        if previous is not None:
            signal.signal(signal.SIGINT, previous)
    result["wall_s"] = round(time.monotonic() - start, 3)
    result["run_dir"] = task.run_dir
    return result


def _init_local_worker() -> None:
    """Local worker initialiser: skip the report figures (the campaign draws its own histograms) and ignore
    Ctrl-C between runs (fly_task takes it during a run, so the flight stops cleanly)."""
    figures.ENABLED = False
    signal.signal(signal.SIGINT, signal.SIG_IGN)


class Progress:
    """A progress bar with ETA: redrawn in place on a terminal, one plain line per finished run otherwise."""

    def __init__(self, total: int, stream: IO[str] | None = None) -> None:
        self.total = total
        self.done = 0
        self.stream = stream or sys.stdout
        self.tty = self.stream.isatty()
        self.start = time.monotonic()

    def update(self, note: str) -> None:
        self.done += 1
        elapsed = time.monotonic() - self.start
        eta = elapsed / self.done * (self.total - self.done)
        eta_text = f"ETA {int(eta // 60)}m{int(eta % 60):02d}s"
        if self.tty:
            width = 30
            filled = int(width * self.done / max(1, self.total))
            bar = "#" * filled + "." * (width - filled)
            end = "\n" if self.done == self.total else ""
            self.stream.write(f"\r[{bar}] {self.done}/{self.total} {eta_text}  {note[:60]:<60}{end}")
        else:
            self.stream.write(f"run {self.done}/{self.total} {note} ({eta_text})\n")
        self.stream.flush()


@dataclass(frozen=True)
class CampaignOptions:
    """Command-line choices of `gcs-swarm montecarlo`."""

    runs: int
    seed: int = 0
    variants: tuple[str, ...] = ()  # guidance methods; () = the mission's own
    jobs: int = 2
    scheduler: str | None = None  # Dask scheduler address
    out_dir: Path | None = None
    ranges_path: Path | None = None
    keep_runs: bool = False


def plan_tasks(
    mission_path: Path, options: CampaignOptions, out_dir: Path, skip: set[tuple[int, str]]
) -> tuple[list[RunTask], list[str]]:
    """The tasks still to fly (derived and validated here) and the variant labels; VariantError/MissionError
    on bad input."""
    base = load_mission(mission_path)
    ranges = variants.load_ranges(options.ranges_path)
    grid = variants.variant_grid(list(options.variants) or [base.field.method], None, None)
    labels = [v.label for v in grid]
    tasks = []
    with tempfile.TemporaryDirectory(prefix="gcs-swarm-mc-") as scratch:
        for seed in range(options.seed, options.seed + options.runs):
            for variant in grid:
                if (seed, variant.label) in skip:
                    continue
                path = Path(scratch) / f"{variant.label}-seed-{seed}.yaml"
                mission = variants.derive_monte_carlo_run(mission_path, ranges, seed, variant, path)
                run_dir = out_dir / "runs" / variant.label / f"seed-{seed}"
                tasks.append(
                    RunTask(
                        seed=seed,
                        variant=variant.label,
                        mission_yaml=path.read_text(),
                        vehicles=len(mission.vehicles),
                        run_dir=str(run_dir.resolve()),
                        collision_radius=mission.safety.collision_radius,
                        keep_files=options.keep_runs,
                        world={
                            "obstacles": len(mission.obstacles),
                            "wind_speed_m_s": mission.wind.speed,
                            "link_loss": variants.link_loss(ranges, seed),
                        },
                    )
                )
    return tasks, labels


def _local_results(tasks: list[RunTask], jobs: int) -> Iterator[dict[str, Any]]:
    """Results as runs end, on `jobs` local processes. On Ctrl-C, runs not started are cancelled and the
    running ones end (they see the interrupt too) before the KeyboardInterrupt goes on."""
    context = multiprocessing.get_context("spawn")
    pool = cf.ProcessPoolExecutor(max_workers=jobs, mp_context=context, initializer=_init_local_worker)
    futures = {pool.submit(fly_task, t): t for t in tasks}
    seen: set[cf.Future[dict[str, Any]]] = set()

    def outcome(future: cf.Future[dict[str, Any]]) -> dict[str, Any]:
        seen.add(future)
        try:
            return future.result()
        except Exception as exc:  # noqa: BLE001 - a worker process died: report the run, go on
            task = futures[future]
            logged = log_exception(task.run_dir, f"worker of seed {task.seed} variant {task.variant} failed")
            error = f"worker failed: {exc!r}{traceback_note(logged)}"
            return {"seed": task.seed, "variant": task.variant, "error": error}

    try:
        for future in cf.as_completed(futures):
            yield outcome(future)
    except KeyboardInterrupt:
        pool.shutdown(wait=True, cancel_futures=True)
        for future in futures:
            if future not in seen and future.done() and not future.cancelled():
                yield outcome(future)
        raise
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


def _dask_results(tasks: list[RunTask], address: str) -> Iterator[dict[str, Any]]:
    """Results as runs end, on an existing Dask distributed cluster."""
    try:
        from dask.distributed import Client, as_completed
    except ImportError:
        raise CampaignError("--scheduler needs dask: pip install 'swarm-gcs[dask]'") from None
    try:
        client = Client(address, timeout="10s")
    except (OSError, TimeoutError) as exc:
        raise CampaignError(f"cannot reach the Dask scheduler at {address}: {exc}") from None
    futures = []
    try:
        futures = [client.submit(fly_task, t, pure=False) for t in tasks]
        for future in as_completed(futures):
            yield future.result()
    finally:
        client.cancel(futures)
        client.close()


def description(mission_path: Path, options: CampaignOptions) -> dict[str, Any]:
    """What identifies a campaign (campaign.json): the mission and ranges files' contents and the seeds."""

    def digest(path: Path | None) -> str | None:
        return None if path is None else hashlib.sha256(path.read_bytes()).hexdigest()

    return {
        "mission_sha256": digest(mission_path),
        "ranges_sha256": digest(options.ranges_path),
        "first_seed": options.seed,
    }


def write_summary(store: CampaignStore, labels: list[str], title: str) -> dict[str, Any]:
    """summary.json, summary.md and (with matplotlib) histograms.png from the results so far."""
    results = [r for r in store.results() if r["variant"] in labels]
    summary = campaign_store.summarise(results, labels)
    out = store.out_dir
    (out / campaign_store.SUMMARY_FILE).write_text(json.dumps(summary, indent=2) + "\n")
    (out / campaign_store.SUMMARY_MD).write_text(campaign_store.render_summary(summary, title))
    raw = {
        key: {v: [r.get(key) for r in results if r["variant"] == v and not r.get("error")] for v in labels}
        for key in campaign_store.DISTRIBUTIONS
    }
    values = {k: {v: [x for x in xs if x is not None] for v, xs in by.items()} for k, by in raw.items()}
    figures.plot_histograms(values, campaign_store.DISTRIBUTIONS, out / "histograms.png")
    return summary


def _note(result: dict[str, Any]) -> str:
    if result.get("error"):
        return f"seed {result['seed']} {result['variant']}: error: {result['error']}"
    outcome = "ok" if result["success"] else ("collision" if result["collision"] else "failed")
    return f"seed {result['seed']} {result['variant']}: {outcome} in {result['wall_s']:.0f} s"


def montecarlo_command(mission_path: str, options: CampaignOptions, say: Callable[[str], None]) -> int:
    """The whole `montecarlo` command: 0 every run flown (whatever their outcomes), 1 some runs ended in an
    error, 2 user error, 130 interrupted (finished runs are kept; rerun to resume). `say` shows the user a
    line (the command line prints it)."""
    path = Path(mission_path)
    if options.runs < 1 or options.jobs < 1:
        say("error: --runs and --jobs must be at least 1")
        return EXIT_USER_ERROR
    try:
        base = load_mission(path)
        out_dir = options.out_dir or Path("runs") / f"montecarlo-{base.name}-seed{options.seed}"
        store = CampaignStore(out_dir)
        tasks, labels = plan_tasks(path, options, out_dir, store.finished())
        store.bind(description(path, options))
    except (MissionError, variants.VariantError, CampaignError) as exc:
        say(f"error: {exc}")
        return EXIT_USER_ERROR
    total = options.runs * len(labels)
    where = f"Dask at {options.scheduler}" if options.scheduler else f"{options.jobs} local process(es)"
    say(f"campaign {out_dir}: {total - len(tasks)} of {total} runs done, {len(tasks)} to fly on {where}")
    status = EXIT_OK
    if tasks:
        progress = Progress(len(tasks))
        if options.scheduler:
            results = _dask_results(tasks, options.scheduler)
        else:
            results = _local_results(tasks, min(options.jobs, len(tasks)))
        try:
            for result in results:
                if result.get("error") != "interrupted":
                    store.append(result)
                status = EXIT_FAILED if result.get("error") else status
                progress.update(_note(result))
        except KeyboardInterrupt:
            say(f"\ninterrupted: finished runs are in {store.results_path}; rerun the same command to resume")
            status = EXIT_INTERRUPTED
        except CampaignError as exc:
            say(f"error: {exc}")
            return EXIT_USER_ERROR
    summary = write_summary(
        store, labels, f"{base.name}, seeds {options.seed}..{options.seed + options.runs - 1}"
    )
    for label in labels:
        g = summary["variants"][label]
        lo, hi = g["success_ci95"]
        say(
            f"{label}: {g['runs']} runs, success {g['success_rate']} (95 % CI {lo:.2f}-{hi:.2f}), "
            f"collision rate {g['collision_rate']}"
        )
    say(f"summary: {out_dir / campaign_store.SUMMARY_MD}")
    return status
