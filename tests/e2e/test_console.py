"""`gcs-swarm console` end to end against the real simulator in lockstep on 127.0.0.1 free ports.

(1) Script mode: start, watch the formation form, hold, move the goal and resume, abort; the simulator's
truth log shows the vehicles did what was commanded, and bad commands leave the session running.
(2) The full-screen UI in a pseudo-terminal (pexpect): fleet table, status, help, a declined start, quit with
its landing question. The screen is read with a small VT100 interpreter (only what prompt_toolkit emits).
"""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pexpect
import yaml

from swarm_common.ports import free_udp_base
from tests.e2e.flights import MISSIONS, ROOT, numbers

SCRIPT = """\
# bad commands before the flight: each is refused and the session goes on
fly away
arm banana
takeoff -5
goal 1 2
hold
mode LAND lead
arm lead
help goal
param get MOT_THST_HOVER lead
start
wait phase formation 60
resume
formation hexagon
wait 4
hold
wait 4.5
status
goal 40 -30 10
resume
wait 6
abort
wait phase done 120
quit
"""
REFUSALS = (
    "error: unknown command 'fly'",
    "error: no vehicle 'banana'",
    "error: takeoff altitude -5 m is outside",
    "error: usage: goal X Y Z",
    "console: error: hold needs formation flight; the mission is in phase connect",
    "console: error: resume needs phase hold; the mission is in phase formation",
    "error: unknown formation shape 'hexagon'",
)


def _kill_group(proc_pid: int) -> None:
    """SIGKILL the console's process group (the console and its embedded simulator), if any is left."""
    try:
        os.killpg(proc_pid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):
        pass


def _truth(run_dir: Path) -> np.ndarray:
    return np.genfromtxt(run_dir / "truth.csv", names=True, delimiter=",")


def _event_time(output: str, text: str) -> float:
    """Vehicle time of the first output line `[    t] ...text...`."""
    for line in output.splitlines():
        m = re.match(r"^\[\s*([\d.]+)\] (.*)$", line)
        if m and text in m.group(2):
            return float(m.group(1))
    raise AssertionError(f"no line with {text!r} in the console output:\n{output[-3000:]}")


def test_script_flies_holds_moves_goal_and_aborts(tmp_path: Path) -> None:
    mission = MISSIONS / "quickstart.yaml"
    script = tmp_path / "ops.txt"
    script.write_text(SCRIPT)
    run_dir = tmp_path / "run"
    cmd = [sys.executable, "-m", "gcs_swarm", "console", str(mission), "--script", str(script), "--yes"]
    cmd += ["--base-port", str(free_udp_base(3)), "--out", str(run_dir)]
    proc = subprocess.Popen(
        cmd, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, start_new_session=True
    )
    try:
        output, _ = proc.communicate(timeout=180)
    finally:
        _kill_group(proc.pid)
    assert "Traceback" not in output, output[-3000:]
    assert proc.returncode == 1, output[-3000:]  # the refused commands
    for refusal in REFUSALS:
        assert refusal in output, refusal
    assert re.search(r"lead refused MAV_CMD_COMPONENT_ARM_DISARM: FAILED \((PreArm|Arm): .+\)", output)
    assert "goal X Y Z: move the leader's goal" in output
    assert re.search(r"lead: MOT_THST_HOVER = 0\.\d+", output)

    t_hold = _event_time(output, "console: holding: every vehicle brakes")
    t_goal = _event_time(output, "console: goal set to (40, -30, 10)")
    t_resume = _event_time(output, "console: resumed formation flight")
    t_abort = _event_time(output, "console: aborting: every vehicle lands now")
    assert _event_time(output, "mission: phase done") > t_abort
    assert t_hold + 4.0 <= t_goal <= t_resume < t_abort

    truth = _truth(run_dir)
    names = sorted(set(truth["vehicle"].astype(int)))
    assert len(names) == 3
    t = truth["t"]
    speed = np.linalg.norm(np.c_[truth["vx"], truth["vy"], truth["vz"]], axis=1)
    lead = truth["vehicle"] == 0

    # hold: flying fast when commanded, then every vehicle still and in place over the last second+
    at_hold = lead & (np.abs(t - t_hold) < 0.011)
    assert speed[at_hold].max() > 3.0
    window = (t >= t_hold + 3.0) & (t <= t_goal)
    for v in names:
        rows = window & (truth["vehicle"] == v)
        assert rows.sum() > 40
        assert speed[rows].max() < 0.6, f"vehicle {v} still moving in hold"
        p = np.c_[truth["x"][rows], truth["y"][rows], truth["z"][rows]]
        assert np.linalg.norm(p - p.mean(axis=0), axis=1).max() < 0.6, f"vehicle {v} drifted in hold"

    # goal + resume: the leader heads for the new goal
    goal = np.array([40.0, -30.0, 10.0])

    def leader_at(time_s: float) -> np.ndarray:
        k = np.flatnonzero(lead)[np.argmin(np.abs(t[lead] - time_s))]
        return np.array([truth["x"][k], truth["y"][k], truth["z"][k]])

    before, after = leader_at(t_resume), leader_at(t_abort)
    assert np.linalg.norm(after - goal) < np.linalg.norm(before - goal) - 10.0
    travelled = after - before
    cosine = travelled @ (goal - before) / (np.linalg.norm(travelled) * np.linalg.norm(goal - before))
    assert cosine > 0.8

    # abort: every vehicle down, disarmed, not crashed
    for v in names:
        last = np.flatnonzero(truth["vehicle"] == v)[-1]
        assert truth["armed"][last] == 0 and truth["crashed"][last] == 0
        assert abs(truth["z"][last]) < 0.3

    for name in ("record.csv", "telemetry.tlog", "flight.json", "report.json"):
        assert (run_dir / name).stat().st_size > 0, name


class Screen:
    """A minimal VT100 screen: printable text, CR/LF/BS, cursor moves (CUU/CUD/CUF/CUB/CUP), erase (ED/EL);
    colours, modes and titles are skipped."""

    _CSI = re.compile(r"\x1b\[([?>=]?)([0-9;]*)[ -/]*([@-~])")
    _OSC = re.compile(r"\x1b\][^\x07\x1b]*(?:\x07|\x1b\\)")

    def __init__(self, rows: int, cols: int) -> None:
        self.rows, self.cols = rows, cols
        self.grid = [[" "] * cols for _ in range(rows)]
        self.y = self.x = 0

    def feed(self, data: str) -> None:
        i = 0
        while i < len(data):
            if data[i] == "\x1b":
                m = self._CSI.match(data, i) or self._OSC.match(data, i)
                if m is not None and m.re is self._CSI:
                    self._csi(m.group(1), m.group(2), m.group(3))
                i = m.end() if m is not None else i + 2
                continue
            self._char(data[i])
            i += 1

    def _char(self, ch: str) -> None:
        if ch == "\r":
            self.x = 0
        elif ch == "\n":
            self.y = min(self.y + 1, self.rows - 1)
        elif ch == "\b":
            self.x = max(self.x - 1, 0)
        elif ch >= " ":
            if self.x < self.cols:
                self.grid[self.y][self.x] = ch
            self.x = min(self.x + 1, self.cols)

    def _csi(self, private: str, params: str, final: str) -> None:
        if private:
            return
        nums = [int(p) if p else 0 for p in params.split(";")] if params else []
        n = nums[0] if nums and nums[0] else 1
        if final == "A":
            self.y = max(self.y - n, 0)
        elif final == "B":
            self.y = min(self.y + n, self.rows - 1)
        elif final == "C":
            self.x = min(self.x + n, self.cols - 1)
        elif final == "D":
            self.x = max(self.x - n, 0)
        elif final in "Hf":
            row = nums[0] if nums and nums[0] else 1
            col = nums[1] if len(nums) > 1 and nums[1] else 1
            self.y, self.x = min(row - 1, self.rows - 1), min(col - 1, self.cols - 1)
        elif final == "J":
            if nums and nums[0] in (2, 3):
                self.grid = [[" "] * self.cols for _ in range(self.rows)]
            else:
                self.grid[self.y][self.x :] = [" "] * (self.cols - self.x)
                for r in range(self.y + 1, self.rows):
                    self.grid[r] = [" "] * self.cols
        elif final == "K":
            self.grid[self.y][self.x :] = [" "] * (self.cols - self.x)

    def text(self) -> str:
        return "\n".join("".join(r).rstrip() for r in self.grid)


class Terminal:
    """The console in a pseudo-terminal, its screen kept up to date."""

    def __init__(self, args: list[str], rows: int = 40, cols: int = 130) -> None:
        env = {**os.environ, "TERM": "xterm", "COLUMNS": str(cols), "LINES": str(rows)}
        self.child = pexpect.spawn(
            sys.executable, args, cwd=str(ROOT), dimensions=(rows, cols), encoding="utf-8", env=env
        )
        self.screen = Screen(rows, cols)

    def read(self, seconds: float) -> None:
        end = time.monotonic() + seconds
        while time.monotonic() < end and self.child.isalive():
            try:
                self.screen.feed(self.child.read_nonblocking(65536, timeout=0.05))
            except pexpect.TIMEOUT:
                pass
            except pexpect.EOF:
                return

    def wait_for(self, text: str, timeout_s: float = 20.0) -> str:
        end = time.monotonic() + timeout_s
        while time.monotonic() < end:
            self.read(0.1)
            if text in self.screen.text():
                return self.screen.text()
        raise AssertionError(f"{text!r} did not appear on the screen:\n{self.screen.text()}")

    def type(self, line: str) -> None:
        self.child.send(line + "\r")

    def wait_exit(self, timeout_s: float) -> int:
        end = time.monotonic() + timeout_s
        while self.child.isalive() and time.monotonic() < end:
            self.read(0.2)
        assert not self.child.isalive(), f"the console did not exit:\n{self.screen.text()}"
        self.child.close()
        return int(self.child.exitstatus)


def test_interactive_console_in_a_pseudo_terminal(tmp_path: Path) -> None:
    """Airborne start 3 m up: the table shows the fleet at once, and quit offers to land it (~6 s)."""
    data = numbers(yaml.safe_load((MISSIONS / "quickstart.yaml").read_text()))
    data["mission"]["name"] = "console_pty"
    data["run"]["airborne_start"] = True
    for vehicle in data["vehicles"]:
        vehicle["start"]["position"][2] = 3.0
    mission = tmp_path / "console_pty.yaml"
    mission.write_text(yaml.safe_dump(data, sort_keys=False))
    run_dir = tmp_path / "run"
    args = [
        "-m",
        "gcs_swarm",
        "console",
        str(mission),
        "--base-port",
        str(free_udp_base(3)),
        "--out",
        str(run_dir),
    ]
    term = Terminal(args)
    try:
        screen = term.wait_for("phase ready", timeout_s=30)
        assert "name  sysid  age s" in screen
        for name in ("lead", "right", "left"):
            # name, sysid, age, loss, round-trip time (TIMESYNC), mode, armed, altitude
            pattern = rf"^{name}\s+\d\s+[\d.]+\s+\S+\s+[\d.]+\s+GUIDED\s+ARMED\s+3\.0"
            assert re.search(pattern, screen, re.M), screen

        term.child.send("stat\t")  # Tab completes the command name
        term.read(0.3)
        term.type("")
        term.wait_for("lead (sysid 1): GUIDED armed, airborne")
        term.type("help")
        term.wait_for("goal X Y Z")
        term.type("fly away")
        term.wait_for("error: unknown command 'fly'")
        term.type("start")
        term.wait_for("start: this arms or launches every vehicle. Go ahead? [y/N]")
        term.type("n")
        term.wait_for("cancelled")

        term.type("quit")
        term.wait_for("[l]and them first, [q]uit leaving them, [c]ancel?")
        term.type("c")
        term.read(0.5)
        term.type("quit")
        term.wait_for("[c]ancel? ")
        term.type("l")
        assert term.wait_exit(timeout_s=40) == 0
    finally:
        if term.child.isalive():
            term.child.terminate(force=True)
        _kill_group(term.child.pid)
    truth = _truth(run_dir)
    for v in range(3):
        last = np.flatnonzero(truth["vehicle"] == v)[-1]
        assert truth["armed"][last] == 0 and abs(truth["z"][last]) < 0.3
    history = (run_dir / "console_history.txt").read_text()
    assert "status" in history and "help" in history
