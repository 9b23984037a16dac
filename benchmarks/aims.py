"""Issue 16's table of required and aimed figures, filled from the benchmarks' JSON output (`--json FILE` of
bench_end_to_end.py and bench_fleet_capacity.py), for run_all.py.

A figure measured over several flights is given as its median, range and worst flight; it meets a bound only
when its worst flight does (issue 16: a claim stands with its spread and its worst run).

Each row names the command that measured it, the date (UTC) the command started and the commit of the code.
"""

from __future__ import annotations

import math
import statistics
from collections.abc import Callable
from dataclasses import dataclass
from datetime import UTC, datetime
from typing import Any


@dataclass(frozen=True)
class Source:
    """A benchmark invocation: its command line as shown, its JSON output, the commit it measured."""

    command: str
    result: dict[str, Any]
    commit: str

    @property
    def date(self) -> str:
        return f"{datetime.fromtimestamp(self.result['started_unix_s'], UTC):%Y-%m-%d %H:%M} UTC"


@dataclass(frozen=True)
class Bound:
    """A required or aimed value: `value` with `better` "higher" (>=) or "lower" (<)."""

    value: float
    better: str

    def met_by(self, x: float) -> bool:
        return math.isfinite(x) and (x >= self.value if self.better == "higher" else x < self.value)

    def text(self, unit: str) -> str:
        return f"{'>=' if self.better == 'higher' else '<'} {self.value:g}{unit}"


def verdict(bound: Bound, values: list[float]) -> str:
    """'met' when every flight's figure meets the bound (the worst one does); otherwise whether the median
    would have."""
    if not values:
        return "not measured"
    if all(bound.met_by(v) for v in values):
        return "met"
    return "not met (the median meets it)" if bound.met_by(statistics.median(values)) else "not met"


def spread_text(values: list[float], unit: str, fmt: str, worst: Callable[[list[float]], float]) -> str:
    finite = [v for v in values if math.isfinite(v)]
    if not finite:
        return "-"
    med, lo, hi = statistics.median(finite), min(finite), max(finite)
    text = f"{med:{fmt}}{unit} median ({lo:{fmt}}-{hi:{fmt}}), worst {worst(finite):{fmt}}{unit}"
    return text + ("" if len(finite) == len(values) else f" ({len(values) - len(finite)} flight(s) failed)")


def scenario(source: Source, prefix: str) -> list[dict[str, Any]]:
    """The flights of the bench_end_to_end scenario whose label starts with `prefix` ([] if none)."""
    for case in source.result["scenarios"]:
        if case["label"].startswith(prefix):
            return list(case["flights"])
    return []


def figure_row(
    figure: str,
    values: list[float],
    required: Bound,
    aim: Bound,
    unit: str,
    fmt: str,
    source: Source,
) -> str:
    worst = min if required.better == "higher" else max
    values = [math.nan if v is None else float(v) for v in values]
    return (
        f"| {figure} | {required.text(unit)} | {aim.text(unit)} | {spread_text(values, unit, fmt, worst)} "
        f"| {verdict(required, values)} | {verdict(aim, values)} | `{source.command}` | {source.date} "
        f"| {source.commit} |"
    )


def capacity_row(source: Source) -> str:
    """Largest fleet holding 50 Hz: met when it is at least the bound (every flight of that size held)."""
    res = source.result
    largest = res.get("largest_held") or 0
    by_size: dict[int, list[dict[str, Any]]] = {}
    for flight in res["flights"]:
        by_size.setdefault(flight["vehicles"], []).append(flight)
    failed = [n for n in by_size if n > largest]
    detail = f"{largest or 'none'} ({res['repeats']} flights of {res['leg_m']:g} m per size"
    if failed:
        first = min(failed)
        flights = by_size[first]
        missed = ", ".join("-" if f["frames_missed"] is None else str(f["frames_missed"]) for f in flights)
        exits = ",".join(str(f["status"]) for f in flights)
        detail += f"; at {first}: frames missed {missed}, exit {exits}"
    detail += ")"

    def met(bound: float) -> str:
        return "met" if largest >= bound else "not met"

    return (
        f"| largest fleet at 50 Hz in real time, 0 frames missed | >= 200 | >= 500 | {detail} | {met(200)} "
        f"| {met(500)} | `{source.command}` | {source.date} | {source.commit} |"
    )


def aims_table(sources: dict[str, Source]) -> str:
    """Issue 16's table from the invocations run: `paper_static_6` (bench_end_to_end.py --mission
    missions/paper_static_6.yaml), `end_to_end` (bench_end_to_end.py), `fleet_capacity`; rows whose
    benchmark did not run are left out."""
    rows = []
    if "paper_static_6" in sources:
        src = sources["paper_static_6"]
        rtf = [f["real_time_factor"] for f in src.result["scenarios"][0]["flights"]]
        rows.append(
            figure_row(
                "`gcs-swarm run missions/paper_static_6.yaml`, sim_duration / wall_duration",
                rtf,
                Bound(20, "higher"),
                Bound(50, "higher"),
                "x",
                ".1f",
                src,
            )
        )
    if "end_to_end" in sources:
        src = sources["end_to_end"]
        six = [f["real_time_factor"] for f in scenario(src, "paper_static_6")]
        nine = [f["latency_p99_ms"] for f in scenario(src, "paper_nine_9")]
        rows.append(
            figure_row(
                "bench_end_to_end 6-UAV (600, 600, 200), real-time factor",
                six,
                Bound(25, "higher"),
                Bound(60, "higher"),
                "x",
                ".1f",
                src,
            )
        )
        rows.append(
            figure_row(
                "GCS tick latency p99 (last telemetry in -> last command out), 9 vehicles",
                nine,
                Bound(2, "lower"),
                Bound(1, "lower"),
                " ms",
                ".2f",
                src,
            )
        )
    if "fleet_capacity" in sources:
        rows.append(capacity_row(sources["fleet_capacity"]))
    if not rows:
        return ""
    head = (
        "| figure | required | aim | measured | required met | aim met | command | date | commit |\n"
        "|---|---|---|---|---|---|---|---|---|\n"
    )
    return head + "\n".join(rows) + "\n"
