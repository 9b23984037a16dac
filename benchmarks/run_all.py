"""Run every benchmark of the project and rewrite BENCHMARKS.md (machine, date, command, figures).

Usage: python benchmarks/run_all.py [--only NAME ...] [--quick]

Each benchmark is a script in this folder that prints a Markdown section (median and spread of repeats,
measured in one run, since the machine is shared and noisy). This script only gathers them.
"""

from __future__ import annotations

import argparse
import os
import platform
import subprocess
import sys
import time
from datetime import UTC, datetime
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent

# (name, script, arguments for a full run, arguments for --quick)
BENCHMARKS: list[tuple[str, str, list[str], list[str]]] = [
    ("physics", "bench_physics.py", [], []),
    ("guidance", "bench_guidance.py", [], ["--quick"]),
    ("sitl", "bench_sitl.py", [], []),
    ("end_to_end", "bench_end_to_end.py", [], ["--quick"]),
    ("fleet_capacity", "bench_fleet_capacity.py", [], ["--quick"]),
    ("montecarlo", "bench_montecarlo.py", [], ["--quick"]),
    ("soak", "bench_soak.py", ["--leg", "6000"], ["--quick"]),
]


def machine_description() -> str:
    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    system = f"{platform.system()} {platform.release()}"
    return f"{cpu}, {os.cpu_count()} cores, Python {platform.python_version()}, {system}"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", nargs="*", help="run only these benchmarks (names: %(default)s)")
    parser.add_argument("--quick", action="store_true", help="fewer repeats / smaller cases")
    parser.add_argument("--output", default=str(ROOT / "BENCHMARKS.md"))
    args = parser.parse_args(argv)
    sections = []
    for name, script, full, quick in BENCHMARKS:
        if args.only and name not in args.only:
            continue
        path = HERE / script
        if not path.exists():
            print(f"skip {name}: {script} not present", file=sys.stderr)
            continue
        cmd = [sys.executable, str(path), *(quick if args.quick else full)]
        shown = "python benchmarks/" + " ".join([script, *(quick if args.quick else full)])
        print(f"running {shown}", file=sys.stderr, flush=True)
        start = time.monotonic()
        proc = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True)
        took = time.monotonic() - start
        body = (
            proc.stdout.strip()
            if proc.returncode == 0
            else f"FAILED (exit {proc.returncode}):\n\n```\n{proc.stderr[-2000:]}\n```"
        )
        sections.append(f"## {name}\n\nCommand: `{shown}` ({took:.0f} s wall)\n\n{body}\n")
    header = (
        "# Benchmarks\n\n"
        f"Rewritten by `python benchmarks/run_all.py` on {datetime.now(UTC):%Y-%m-%d %H:%M} UTC.\n\n"
        f"Machine: {machine_description()}. The machine is shared and noisy: figures are medians "
        "(with spread) of repeats measured in one run; compare ratios within a run rather than absolute "
        "numbers across runs.\n\n"
    )
    Path(args.output).write_text(header + "\n".join(sections))
    print(f"wrote {args.output}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
