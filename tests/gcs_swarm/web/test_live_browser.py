"""The live page in a real browser (tests/gcs_swarm/web/browser.py) during a lockstep flight of
missions/quickstart.yaml in `gcs-swarm console --web 127.0.0.1:0 --web-token TOKEN`, whose script starts the
flight, holds it in formation and then waits for the page: the page sees every vehicle climb and fly, its
`land left` is refused without the token and with a wrong one, obeyed with it (the simulator's ground truth
shows left in LAND before the others), and its `land` (every vehicle) ends the flight. Marked e2e; skipped
only where Chromium is absent and CI is not set. Waits are bounded; no assertion is about time."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from swarm_common.ports import free_udp_base
from tests.e2e.flights import MISSIONS, ROOT
from tests.gcs_swarm.web.browser import WAIT_S, chromium, needs_chromium, page_state, wait_for
from tests.process_output import OutputLines

pytestmark = [pytest.mark.e2e, needs_chromium]

TOKEN = "swarm-test-token"
LAND = 9  # ArduCopter custom_mode of LAND (mode.h), as truth.csv writes the mode
# the script flies 8 s of formation flight, holds, and waits for the page to land the fleet
SCRIPT = """\
start
wait phase formation 120
wait 8
hold
wait phase land
wait phase done 120
quit
"""


def _act(driver: Any, verb: str, target: str, token: str) -> dict[str, Any]:
    """Send one action from the page's operator panel as a user does; the page's reply to it."""
    count = len(page_state(driver)["actions"])
    driver.execute_script(
        "document.getElementById('verb').value = arguments[0];"
        "document.getElementById('target').value = arguments[1];"
        "document.getElementById('token').value = arguments[2];"
        "document.getElementById('act').click();",
        verb,
        target,
        token,
    )
    return wait_for(driver, f"s.actions.length > {count} && s.actions[{count}]")


def test_the_live_page_shows_the_flight_and_acts_only_with_the_token(tmp_path: Path) -> None:
    script = tmp_path / "ops.txt"
    script.write_text(SCRIPT)
    run_dir = tmp_path / "run"
    cmd = [sys.executable, "-m", "gcs_swarm", "console", str(MISSIONS / "quickstart.yaml"), "--script"]
    cmd += [str(script), "--yes", "--base-port", str(free_udp_base(3)), "--out", str(run_dir)]
    cmd += ["--web", "127.0.0.1:0", "--web-token", TOKEN]
    proc = subprocess.Popen(
        cmd, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, start_new_session=True
    )
    output = OutputLines(proc)
    try:
        line = output.wait_for(lambda line: line.startswith("live page at http://"), WAIT_S, "the page's URL")
        url = line.split(" at ", 1)[1].split()[0]
        with chromium(tmp_path / "chromium-profile") as browser:
            browser.get(url)
            wait_for(browser, "s.scene !== null && s.frame !== null")
            assert page_state(browser)["scene"]["vehicles"] == ["lead", "right", "left"]
            assert page_state(browser)["scene"]["actions"] is True
            assert not browser.find_element("id", "actions").get_attribute("hidden")

            # every vehicle shown climbing, then flying in formation, then holding
            formation = wait_for(browser, "s.frame.phase === 'formation' && s.frame")
            held = wait_for(browser, "s.frame.phase === 'hold' && s.frame")
            for a, b in zip(formation["vehicles"], held["vehicles"], strict=True):
                assert a["z"] > 5.0 and b["z"] > 5.0  # up at the formation's 10 m (quickstart)
                assert (a["x"] - b["x"]) ** 2 + (a["y"] - b["y"]) ** 2 > 4.0  # 8 s at several m/s
            assert all(len(trail) > 10 for trail in page_state(browser)["trails"])
            assert held["leader"] == 0 and held["vehicles"][2]["mode"] == "GUIDED"
            rows = browser.find_elements("css selector", "#vehicles tbody tr")
            assert [r.find_elements("css selector", "td")[1].text for r in rows] == [
                "lead (leader)",
                "right",
                "left",
            ]

            # refused without the token and with a wrong one: the console never sees them
            refused = [_act(browser, "land", "left", ""), _act(browser, "land", "left", "not-it")]
            assert all(r["ok"] is False and "token" in r["text"] for r in refused)
            assert "refused" in browser.find_element("id", "reply").text
            t_refused = page_state(browser)["frame"]["t"]
            wait_for(browser, f"s.frame.t > {t_refused} + 1")
            assert page_state(browser)["frame"]["vehicles"][2]["mode"] == "GUIDED"

            # obeyed with it: the console's own reply, and the page shows left landing
            landed = _act(browser, "land", "left", TOKEN)
            assert landed["ok"] is True and "left: mode LAND" in landed["text"], landed
            wait_for(browser, "s.frame.vehicles[2].mode === 'LAND'")
            t_left = page_state(browser)["frame"]["t"]
            wait_for(browser, f"s.frame.t > {t_left} + 3")
            out = tmp_path / "live.png"
            assert browser.save_screenshot(str(out)) and out.stat().st_size > 0

            # `rejoin` with no vehicle named: the console's own usage refusal, through the page
            usage = _act(browser, "rejoin", "all", TOKEN)
            assert usage["ok"] is False and "usage: rejoin VEHICLE" in usage["text"]

            # land every vehicle: the console aborts the mission and the script goes on to the end
            every = _act(browser, "land", "all", TOKEN)
            assert every["ok"] is True and "landing every vehicle" in every["text"], every
        proc.wait(timeout=300)
        text = output.everything(30.0)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    assert "Traceback" not in text, text[-3000:]
    assert proc.returncode == 0, text[-3000:]

    # the ground truth: left entered LAND after the refusals and before the others did
    truth = np.genfromtxt(run_dir / "truth.csv", names=True, delimiter=",")

    def first_land(vehicle: int) -> float:
        rows = (truth["vehicle"] == vehicle) & (truth["mode"] == LAND)
        return float(truth["t"][rows].min())

    t_land = [first_land(v) for v in range(3)]
    assert t_refused < t_land[2] < min(t_land[0], t_land[1])
    flight = json.loads((run_dir / "flight.json").read_text())
    assert "aborted by the operator" in flight["events"]
