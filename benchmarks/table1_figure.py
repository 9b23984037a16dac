"""Reproduce the paper's Figure 9/10 comparison (Table 1 scenario, spec 9.1 reproduction default, 11.3):
APF vs IAAPF paths around the four circles, for both planner step rules, as a PNG and a table.

    python benchmarks/table1_figure.py [PATH.png]     (default docs/figures/table1.png)
"""

from __future__ import annotations

import argparse
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from gcs_swarm.evaluation.planner import PlannerSettings, PlanResult, plan_path
from gcs_swarm.evaluation.planning import draw_plan
from gcs_swarm.guidance.params import FieldParams

ROOT = Path(__file__).resolve().parents[1]
CENTRES = np.array([[25.0, 75.0], [81.0, 30.0], [70.0, 70.0], [32.0, 27.0]])  # Table 1
RADII = np.array([9.0, 8.0, 18.0, 14.0])
START, GOAL = np.array([5.0, 5.0]), np.array([95.0, 70.0])
STEPS = ("proportional", "constant")


def run(method: str, step: str) -> PlanResult:
    fp = FieldParams(method=method, k_att=100.0, k_rep=1e5, l0=20.0, n=0.8, d_g=15.0)
    return plan_path(START, GOAL, CENTRES, RADII, None, fp, 15.0, PlannerSettings(step=step))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("path", nargs="?", default=str(ROOT / "docs" / "figures" / "table1.png"))
    args = parser.parse_args()
    results = {step: {m: run(m, step) for m in ("apf", "iaapf")} for step in STEPS}
    print("Table 1 scenario: start (5, 5), goal (95, 70), k_att 100, k_rep 1e5, l0 20 m, n 0.8, d_g 15 m,")
    print("15 m/s, dt 0.01 s, 60 s, goal radius 0.5 m held 2 s; figures over the approach (spec 10).\n")
    print("| step | method | reached | time s | path m | min clearance m | T_osc s | reversals | end gap m |")
    print("|---|---|---|---|---|---|---|---|---|")
    for step, by_method in results.items():
        for method, r in by_method.items():
            time_s = f"{r.time_s:.2f}" if r.time_s is not None else "-"
            reached = "yes" if r.reached else "no"
            print(
                f"| {step} | {method.upper()} | {reached} | {time_s} | {r.path_length_m:.1f} "
                f"| {r.min_clearance_m:.2f} | {r.oscillation_time_s:.2f} | {r.heading_reversals} "
                f"| {r.final_distance_m:.2f} |"
            )
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    circles = [SimpleNamespace(center=c, radius=r) for c, r in zip(CENTRES, RADII, strict=True)]
    fig, axes = plt.subplots(1, 2, figsize=(13, 6))
    for ax, step in zip(axes, STEPS, strict=True):
        draw_plan(ax, results[step], circles, f"{step} step (spec 11.3)")
        zoom = ax.inset_axes((0.03, 0.55, 0.3, 0.3))  # the goal region: APF's equilibrium 1 m east of it
        for r in results[step].values():
            zoom.plot(r.path[:, 0], r.path[:, 1], lw=1.0)
        zoom.plot(*GOAL, "r*", ms=10)
        zoom.set_xlim(GOAL[0] - 2.5, GOAL[0] + 2.5)
        zoom.set_ylim(GOAL[1] - 2.5, GOAL[1] + 2.5)
        zoom.set_aspect("equal")
        zoom.tick_params(labelsize=7)
    fig.tight_layout()
    out = Path(args.path)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=120)
    print(f"\nfigure: {out}")


if __name__ == "__main__":
    main()
