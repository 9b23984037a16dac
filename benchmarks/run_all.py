"""Run every benchmark of the project and print a report for BENCHMARKS.md: machine, load, date, commit,
issue 16's table of required and aimed figures (benchmarks/aims.py), then each benchmark's own section.

Usage: python benchmarks/run_all.py [--only NAME ...] [--quick] [--args NAME "ARGS"] [--output FILE]

Each benchmark is a script in this folder that prints a Markdown section (median and spread of repeats,
measured in one run, since the machine is shared and noisy); this script gathers them. Those behind issue
16's figures (end_to_end, paper_static_6, fleet_capacity) also write their flights as JSON (`--json`), from
which the table is built, each figure with the command that measured it, its date (UTC) and the commit.
`--args NAME "ARGS"` replaces a benchmark's arguments (e.g. `--args fleet_capacity "--sizes 9,25 --leg 60"`
for a dry run).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import shlex
import subprocess
import sys
import tempfile
import time
from datetime import UTC, datetime
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))

from aims import Source, aims_table  # noqa: E402

# (name, script, arguments for a full run, arguments for --quick, whether it writes --json for the table)
BENCHMARKS: list[tuple[str, str, list[str], list[str], bool]] = [
    ("physics", "bench_physics.py", [], [], False),
    ("guidance", "bench_guidance.py", [], ["--quick"], False),
    ("sitl", "bench_sitl.py", [], [], False),
    ("telemetry_encoding", "bench_telemetry_encoding.py", [], ["--repeats", "3"], False),
    ("sim_intake", "bench_sim_intake.py", [], ["--repeats", "1", "--frames", "100"], False),
    ("link_intake", "bench_intake.py", [], ["--repeats", "1", "--frames", "100"], False),
    ("end_to_end", "bench_end_to_end.py", [], ["--quick"], True),
    (
        "paper_static_6",
        "bench_end_to_end.py",
        ["--mission", "missions/paper_static_6.yaml"],
        ["--mission", "missions/paper_static_6.yaml"],
        True,
    ),
    ("fleet_capacity", "bench_fleet_capacity.py", [], ["--sizes", "25,50,100", "--leg", "100"], True),
    ("montecarlo", "bench_montecarlo.py", [], ["--quick"], False),
    ("soak", "bench_soak.py", ["--leg", "6000"], ["--quick"], False),
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


def commit() -> str:
    """The checked-out commit, read from .git without running git (uncommitted changes are not seen)."""
    git = ROOT / ".git"
    try:
        head = (git / "HEAD").read_text().strip()
        if not head.startswith("ref: "):
            return head[:7]
        ref = head[5:]
        if (git / ref).exists():
            return (git / ref).read_text().strip()[:7]
        for line in (git / "packed-refs").read_text().splitlines():
            if line.endswith(" " + ref):
                return line.split()[0][:7]
    except OSError:
        pass
    return "unknown"


def load() -> str:
    one, five, _ = os.getloadavg()
    return f"load {one:.2f} (1 min), {five:.2f} (5 min)"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    names = [b[0] for b in BENCHMARKS]
    parser.add_argument("--only", nargs="*", choices=names, help="run only these benchmarks")
    parser.add_argument("--quick", action="store_true", help="fewer repeats / smaller cases")
    parser.add_argument(
        "--args", nargs=2, action="append", default=[], metavar=("NAME", "ARGS"), help="NAME's arguments"
    )
    parser.add_argument(
        "--output",
        default="-",
        help="file to write (default: standard output; BENCHMARKS.md keeps dated sections, so paste, do not "
        "overwrite)",
    )
    args = parser.parse_args(argv)
    override = {name: shlex.split(text) for name, text in args.args}
    code = commit()
    sections, sources = [], {}
    started = datetime.now(UTC)
    load_before = load()
    with tempfile.TemporaryDirectory() as tmp:
        for name, script, full, quick, writes_json in BENCHMARKS:
            if args.only and name not in args.only:
                continue
            chosen = override.get(name, quick if args.quick else full)
            shown = "python benchmarks/" + shlex.join([script, *chosen])
            cmd = [sys.executable, str(HERE / script), *chosen]
            json_path = Path(tmp) / f"{name}.json"
            if writes_json:
                cmd += ["--json", str(json_path)]
            print(f"running {shown}", file=sys.stderr, flush=True)
            start = time.monotonic()
            at = datetime.now(UTC)
            proc = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True)
            took = time.monotonic() - start
            body = (
                proc.stdout.strip()
                if proc.returncode == 0
                else f"FAILED (exit {proc.returncode}):\n\n```\n{proc.stderr[-2000:]}\n```"
            )
            sections.append(
                f"## {name}\n\nCommand: `{shown}` ({at:%Y-%m-%d %H:%M} UTC, {took:.0f} s wall, commit "
                f"{code}, {load()} after it)\n\n{body}\n"
            )
            if writes_json and json_path.exists():
                sources[name] = Source(shown, json.loads(json_path.read_text()), code)
    table = aims_table(sources)
    header = (
        "# Benchmarks\n\n"
        f"Rewritten by `python benchmarks/run_all.py` from {started:%Y-%m-%d %H:%M} UTC, commit {code}.\n\n"
        f"Machine: {machine_description()}; {load_before} before the first benchmark. Figures are medians "
        "(with spread) of repeats measured in one run; compare ratios within a run rather than absolute "
        "numbers across runs.\n\n"
    )
    if table:
        header += (
            "## Issue 16: required and aimed figures\n\n"
            "Each figure: median (min-max) over the flights and the worst flight; a bound is met only when "
            "the worst flight meets it.\n\n" + table + "\n"
        )
    report = header + "\n".join(sections)
    if args.output == "-":
        print(report)
    else:
        Path(args.output).write_text(report)
        print(f"wrote {args.output}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
