"""Fly every bundled mission in lockstep into a folder, or compare two such folders: the check that a refactor
changed no flight (docs/architecture.md: lockstep flights are bit-for-bit reproducible).

    python benchmarks/bundled_reports.py fly OUT          # one run folder per mission under OUT
    python benchmarks/bundled_reports.py compare OLD NEW  # exit 1 when a flight differs

`compare` says, per mission, whether truth.csv, record.csv and every figure (PNG) are byte-identical, and
whether report.json holds the same values, ignoring `wall_duration_s` (the one wall-clock figure) and listing
keys only one side has (a new report key is not a changed flight, but it is shown).
"""

from __future__ import annotations

import argparse
import filecmp
import json
import subprocess
import sys
from pathlib import Path

from swarm_common.ports import free_udp_base

ROOT = Path(__file__).resolve().parents[1]
MISSIONS = (  # every bundled mission the embedded simulator flies (ardupilot_sitl_3, px4_sitl_3: real SITL)
    "quickstart",
    "quickstart_faulty",
    "paper_static_6",
    "paper_dynamic_6",
    "paper_dense_6",
    "paper_nine_9",
    "paper_table1_2d",
    "mixed_fleet",
)
WALL_CLOCK_KEYS = ("wall_duration_s",)


def fly(out: Path) -> int:
    """Fly each mission into out/<mission>; the number of runs that exited with an error (status 2)."""
    errors = 0
    for name in MISSIONS:
        cmd = [sys.executable, "-m", "gcs_swarm", "run", str(ROOT / "missions" / f"{name}.yaml")]
        cmd += [
            "--out",
            str(out / name),
            "--time-mode",
            "lockstep",
            "--quiet",
            "--base-port",
            str(free_udp_base(9)),
        ]
        status = subprocess.run(cmd, cwd=ROOT, check=False).returncode
        print(f"{name}: exit {status}", flush=True)
        errors += status == 2
    return errors


def compare(old: Path, new: Path) -> int:
    """Print the comparison of every mission folder of `old` with `new`; the number that differ."""
    differ = 0
    for folder in sorted(p for p in old.iterdir() if p.is_dir()):
        other = new / folder.name
        if not (other / "report.json").exists():
            print(f"{folder.name}: missing in {new}")
            differ += 1
            continue
        before, after = (json.loads((f / "report.json").read_text()) for f in (folder, other))
        for report in (before, after):
            for key in WALL_CLOCK_KEYS:
                report.pop(key, None)
        changed = sorted(k for k in before.keys() & after.keys() if before[k] != after[k])
        files = ["truth.csv", "record.csv", *sorted(p.name for p in folder.glob("*.png"))]
        unequal = [f for f in files if not filecmp.cmp(folder / f, other / f, shallow=False)]
        only_old, only_new = sorted(before.keys() - after.keys()), sorted(after.keys() - before.keys())
        same = not changed and not unequal and not only_old
        differ += not same
        print(
            f"{folder.name}: {'identical' if same else 'DIFFERENT'}"
            + (f"; report values changed: {changed}" if changed else "")
            + (f"; files differ: {unequal}" if unequal else "")
            + (f"; keys gone: {only_old}" if only_old else "")
            + (f"; new keys: {only_new}" if only_new else "")
        )
    return differ


def main() -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    sub = parser.add_subparsers(dest="command", required=True)
    sub.add_parser("fly").add_argument("out", type=Path)
    cmp_parser = sub.add_parser("compare")
    cmp_parser.add_argument("old", type=Path)
    cmp_parser.add_argument("new", type=Path)
    args = parser.parse_args()
    if args.command == "fly":
        return 1 if fly(args.out) else 0
    return 1 if compare(args.old, args.new) else 0


if __name__ == "__main__":
    sys.exit(main())
