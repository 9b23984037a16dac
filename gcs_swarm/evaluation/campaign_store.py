"""A Monte Carlo campaign folder: results.jsonl (one JSON line per finished run, appended and fsync'ed as each
run ends, so an interrupted campaign loses nothing), campaign.json (what the campaign is, checked on resume)
and summary.json / summary.md (success rate with its Wilson 95 % interval, collision rate and the
distributions of the run figures, over all runs and per variant).
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path
from typing import Any

import numpy as np
from scipy.stats import binomtest

from gcs_swarm.evaluation.metrics import rounded

RESULTS_FILE = "results.jsonl"
SUMMARY_FILE = "summary.json"
SUMMARY_MD = "summary.md"
CAMPAIGN_FILE = "campaign.json"

# Run figures summarised as distributions: key in a result line -> label (unit)
DISTRIBUTIONS = {
    "min_separation_m": "minimum separation (m)",
    "time_to_goal_s": "time to goal (s)",
    "formation_rms_m": "formation RMS error (m)",
    "min_obstacle_clearance_m": "minimum obstacle clearance (m)",
}


class CampaignError(Exception):
    """The output folder holds another campaign, or cannot be written (one sentence)."""


def wilson_interval(successes: int, n: int) -> tuple[float, float]:
    """Wilson score 95 % interval of a binomial proportion successes/n (scipy's binomtest); (0, 1) when
    n = 0."""
    if n <= 0:
        return (0.0, 1.0)
    interval = binomtest(successes, n).proportion_ci(confidence_level=0.95, method="wilson")
    return (float(interval.low), float(interval.high))


class CampaignStore:
    """The campaign folder `out_dir`; results are keyed by (seed, variant)."""

    def __init__(self, out_dir: Path) -> None:
        self.out_dir = out_dir
        self.results_path = out_dir / RESULTS_FILE

    def bind(self, description: dict[str, Any]) -> None:
        """Record what this campaign is (mission file hash, ranges, ...) or, on resume, check it is the same;
        CampaignError if the folder holds a different campaign."""
        self.out_dir.mkdir(parents=True, exist_ok=True)
        path = self.out_dir / CAMPAIGN_FILE
        if path.exists():
            try:
                recorded = json.loads(path.read_text())
            except (OSError, json.JSONDecodeError) as exc:
                raise CampaignError(f"{path}: unreadable campaign description ({exc})") from None
            changed = sorted(
                k for k in set(recorded) | set(description) if recorded.get(k) != description.get(k)
            )
            if changed:
                raise CampaignError(
                    f"{self.out_dir} holds a campaign with another {', '.join(changed)}: "
                    "choose another --out, or rerun the command that started it"
                )
            return
        path.write_text(json.dumps(description, indent=2) + "\n")

    def results(self) -> list[dict[str, Any]]:
        """The latest line per (seed, variant), in file order; a line cut short by a crash is skipped."""
        if not self.results_path.exists():
            return []
        latest: dict[tuple[int, str], dict[str, Any]] = {}
        for line in self.results_path.read_text().splitlines():
            try:
                row = json.loads(line)
                key = (int(row["seed"]), str(row["variant"]))
            except (json.JSONDecodeError, KeyError, TypeError, ValueError):
                continue
            latest.pop(key, None)
            latest[key] = row
        return list(latest.values())

    def finished(self) -> set[tuple[int, str]]:
        """(seed, variant) pairs with a flight outcome; runs that ended in an error are not finished."""
        return {(int(r["seed"]), str(r["variant"])) for r in self.results() if not r.get("error")}

    def append(self, result: dict[str, Any]) -> None:
        """Append one result line and force it to disk (flush + fsync) before returning."""
        self.out_dir.mkdir(parents=True, exist_ok=True)
        line = json.dumps(result, separators=(",", ":")) + "\n"
        with self.results_path.open("a", encoding="utf-8") as f:
            f.write(line)
            f.flush()
            os.fsync(f.fileno())


def _distribution(values: list[float | None]) -> dict[str, Any]:
    finite = np.array([v for v in values if v is not None and math.isfinite(v)], dtype=float)
    if finite.size == 0:
        return {"n": 0, "mean": None, "median": None, "p5": None, "p95": None, "min": None, "max": None}
    return {
        "n": int(finite.size),
        "mean": rounded(finite.mean()),
        "median": rounded(np.median(finite)),
        "p5": rounded(np.percentile(finite, 5)),
        "p95": rounded(np.percentile(finite, 95)),
        "min": rounded(finite.min()),
        "max": rounded(finite.max()),
    }


def summarise_group(results: list[dict[str, Any]]) -> dict[str, Any]:
    """Figures of a set of result lines (error lines are counted apart, not as runs); time to goal over the
    successful runs only."""
    flown = [r for r in results if not r.get("error")]
    n = len(flown)
    successes = sum(1 for r in flown if r.get("success"))
    collisions = sum(1 for r in flown if r.get("collision"))
    lo, hi = wilson_interval(successes, n)
    summary: dict[str, Any] = {
        "runs": n,
        "successes": successes,
        "success_rate": round(successes / n, 4) if n else None,
        "success_ci95": [round(lo, 4), round(hi, 4)],
        "collisions": collisions,
        "collision_rate": round(collisions / n, 4) if n else None,
        "errors": len(results) - n,
    }
    for key in DISTRIBUTIONS:
        pool = [r for r in flown if r.get("success")] if key == "time_to_goal_s" else flown
        summary[key] = _distribution([r.get(key) for r in pool])
    return summary


def summarise(results: list[dict[str, Any]], variants: list[str]) -> dict[str, Any]:
    """summary.json: the figures over all results plus the same per variant (in the order given)."""
    summary = summarise_group(results)
    summary["variants"] = {
        v: summarise_group([r for r in results if r.get("variant") == v]) for v in variants
    }
    return summary


def table_cell(x: Any) -> str:
    """A figure in a summary or comparison table: 3 significant digits, "-" for None."""
    return "-" if x is None else (f"{x:.3g}" if isinstance(x, float) else str(x))


def render_summary(summary: dict[str, Any], title: str) -> str:
    """summary.md: one column per variant (and all runs)."""
    groups = {**summary["variants"], "all": summary} if len(summary["variants"]) > 1 else {"all": summary}
    lines = [f"# Monte Carlo: {title}", "", "| figure | " + " | ".join(groups) + " |"]
    lines.append("|---|" + "---|" * len(groups))

    def row(label: str, cell: Any) -> None:
        lines.append(f"| {label} | " + " | ".join(cell(g) for g in groups.values()) + " |")

    row("runs", lambda g: str(g["runs"]))
    row("success rate", lambda g: table_cell(g["success_rate"]))
    row("success 95 % CI (Wilson)", lambda g: f"{g['success_ci95'][0]:.3f}-{g['success_ci95'][1]:.3f}")
    row("collision rate", lambda g: table_cell(g["collision_rate"]))
    row("runs with errors (not counted)", lambda g: str(g["errors"]))
    for key, label in DISTRIBUTIONS.items():
        row(
            f"{label}: median [p5, p95]",
            lambda g, key=key: (
                f"{table_cell(g[key]['median'])} [{table_cell(g[key]['p5'])}, {table_cell(g[key]['p95'])}]"
            ),
        )
    return "\n".join(lines) + "\n"
