"""RowLogProcess: the formatting process writes exactly `template % row` for every row, in order, across
template changes and raw chunks; flush makes the file complete; an owner killed mid-log leaves every row it
handed over in the file and no process behind; a child that cannot write is reported."""

from __future__ import annotations

import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from swarm_common.row_log_process import RowLogError, RowLogProcess

TEMPLATE = "%.3f,%d,row,%.6g,%.6g\r\n"
SPECIAL = [0.0, -0.0, math.nan, math.inf, -math.inf, 1e16, 1.5e-7, 2.5e-310, -1.7e308]


def test_rows_are_template_times_row_in_order(tmp_path: Path) -> None:
    rng = np.random.default_rng(3)
    log = RowLogProcess(tmp_path / "log.csv", "test log")
    expected = [b"t,i,name,a,b\r\n"]
    log.write(expected[0])
    for k, n in enumerate([1, 6, 250, 3, 0, 9]):  # 250 rows: a hand-over of their own; 0: an empty chunk
        template = TEMPLATE if k % 2 else TEMPLATE.replace("row", "other %% row")
        rows = np.column_stack([np.full(n, 0.02 * k), np.arange(n), rng.normal(0, 1e3, (n, 2))])
        if n:
            rows[0, 2:] = rng.choice(SPECIAL, 2)
        log.write_rows(template, rows)
        expected.append("".join(template % tuple(row) for row in rows.tolist()).encode())
        rows += 1.0  # the caller reuses its arrays: what was written stays
    log.write(b"# end\r\n")
    expected.append(b"# end\r\n")
    log.flush()
    assert (tmp_path / "log.csv").read_bytes() == b"".join(expected)  # complete before close
    log.close()
    log.close()  # idempotent
    with pytest.raises(ValueError, match="after close"):
        log.write_rows(TEMPLATE, np.zeros((1, 4)))


def test_a_table_that_is_not_2d_is_refused(tmp_path: Path) -> None:
    log = RowLogProcess(tmp_path / "log.csv", "test log")
    with pytest.raises(ValueError, match="2-D"):
        log.write_rows(TEMPLATE, np.zeros(4))
    log.close()


def test_a_child_that_cannot_write_is_reported(tmp_path: Path) -> None:
    log = RowLogProcess(tmp_path / "no such folder" / "log.csv", "test log")
    log.write_rows(TEMPLATE, np.zeros((3, 4)))
    with pytest.raises(RowLogError, match="test log: the formatting process .*No such file"):
        log.close()


OWNER = """
import os, signal, sys
import numpy as np
from swarm_common.row_log_process import RowLogProcess
log = RowLogProcess(sys.argv[1], "killed owner's log")
for k in range(40):
    log.write_rows("%d,%.6g\\r\\n", np.array([[k, 0.5 * k]]))
log.flush()  # 40 rows handed over and written
log.write_rows("%d,%.6g\\r\\n", np.array([[99, 0.0]]))  # pending: lost with the owner
print(log._child.pid, flush=True)
os.kill(os.getpid(), signal.SIGKILL)
"""


def test_a_killed_owner_leaves_its_rows_and_no_process(tmp_path: Path) -> None:
    path = tmp_path / "log.csv"
    owner = subprocess.run(
        [sys.executable, "-c", OWNER, str(path)], capture_output=True, text=True, timeout=60, check=False
    )
    assert owner.returncode == -signal.SIGKILL, owner.stderr
    child = int(owner.stdout.split()[0])
    deadline = time.monotonic() + 10.0
    while _running(child) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not _running(child), "the formatting process outlived its owner"
    assert path.read_bytes() == "".join(f"{k},{0.5 * k:.6g}\r\n" for k in range(40)).encode()


def _running(pid: int) -> bool:
    """Whether `pid` is a live process (not a zombie: an orphan is reaped by init)."""
    try:
        with open(f"/proc/{pid}/stat") as stat:
            return stat.read().split(")")[-1].split()[0] != "Z"
    except FileNotFoundError:
        return False
    except OSError:
        os.kill(pid, 0)
        return True


def test_the_child_runs_below_the_control_loops(tmp_path: Path) -> None:
    """Niced, and on Linux under SCHED_IDLE where the machine allows it: a waking formatter must not
    preempt the control loop it serves."""
    log = RowLogProcess(tmp_path / "log.csv", "test log")
    try:
        log.flush()  # answered by the child's main loop: its priority is set by then
        pid = log._child.pid
        assert os.getpriority(os.PRIO_PROCESS, pid) >= os.getpriority(os.PRIO_PROCESS, 0) + 10
        if hasattr(os, "SCHED_IDLE"):
            idle = "import os; os.sched_setscheduler(0, os.SCHED_IDLE, os.sched_param(0))"
            probe = subprocess.run([sys.executable, "-c", idle], timeout=30)  # the child's call, on its own
            if probe.returncode == 0:  # allowed on this machine: the formatter must use it
                assert os.sched_getscheduler(pid) == os.SCHED_IDLE
    finally:
        log.close()


@pytest.mark.skipif(not hasattr(os, "SCHED_IDLE"), reason="Linux scheduling policies")
def test_a_child_that_falls_behind_leaves_sched_idle(tmp_path: Path) -> None:
    """A formatter that gets no CPU (stopped here, as by other programs' load under SCHED_IDLE) is taken back
    to the normal policy once its pipe is half full, before the owner could block on it; nothing is lost."""
    log = RowLogProcess(tmp_path / "log.csv", "test log")
    pid = log._child.pid
    try:
        log.flush()  # the child has set its policy
        os.kill(pid, signal.SIGSTOP)
        fcntl = pytest.importorskip("fcntl")
        capacity = fcntl.fcntl(log._stdin.fileno(), getattr(fcntl, "F_GETPIPE_SZ", 1032))
        rows = np.arange(250 * 4, dtype=float).reshape(250, 4)  # 8 kB a chunk, a hand-over each
        written = 0
        while written * rows.nbytes <= 0.6 * capacity:  # past half the pipe, short of full
            assert not log.promoted or written * rows.nbytes > capacity // 2 - rows.nbytes
            log.write_rows(TEMPLATE, rows)
            written += 1
        assert log.promoted and os.sched_getscheduler(pid) == os.SCHED_OTHER
        assert os.getpriority(os.PRIO_PROCESS, pid) >= os.getpriority(os.PRIO_PROCESS, 0) + 10  # still niced
    finally:
        os.kill(pid, signal.SIGCONT)
        log.close()
    lines = (tmp_path / "log.csv").read_bytes().split(b"\r\n")
    assert len(lines) == written * len(rows) + 1  # every row, and the empty tail after the last \r\n
