"""The replay page in a real browser: Debian's headless Chromium driven by Selenium through Debian's
chromedriver (never selenium-manager, which would go to the network), over the run folder of a real lockstep
flight of missions/quickstart.yaml. Marked e2e; skipped only where Chromium is absent and CI is not set (in
CI a missing browser fails). Waits are bounded (WAIT_S) so that a broken page fails instead of hanging; no
assertion is about time."""

from __future__ import annotations

import json
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from tests.e2e.flights import MISSIONS, ROOT, fly
from tests.gcs_swarm.web.browser import WAIT_S, chromium, needs_chromium
from tests.gcs_swarm.web.browser import page_state as _state
from tests.gcs_swarm.web.browser import wait_for as _wait
from tests.process_output import OutputLines

pytestmark = [pytest.mark.e2e, needs_chromium]


@pytest.fixture(scope="module")
def flown(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A run folder of quickstart flown in lockstep, once for the module."""
    run_dir = tmp_path_factory.mktemp("browser") / "quickstart"
    outcome = fly(MISSIONS / "quickstart.yaml", run_dir, 600.0, ["--time-mode", "lockstep", "--quiet"])
    assert outcome.status == 0, outcome.output
    return run_dir


@pytest.fixture(scope="module")
def page_url(flown: Path) -> Iterator[str]:
    """`gcs-swarm replay` serving the run on a free port (0: the system picks); the URL it prints."""
    proc = subprocess.Popen(
        [sys.executable, "-m", "gcs_swarm", "replay", str(flown), "--port", "0", "--speed", "2"],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    output = OutputLines(proc)
    try:
        line = output.wait_for(lambda line: " at http://" in line, WAIT_S, "the replay's URL")
        url = line.split(" at ", 1)[1].split()[0]
        yield url
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=30)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


@pytest.fixture
def browser(tmp_path: Path) -> Iterator[Any]:
    with chromium(tmp_path / "chromium-profile") as driver:
        yield driver


def _seek(driver: Any, t: float) -> None:
    """Move the time slider to t s as a user does (the input event the page listens to)."""
    driver.execute_script(
        "const e = document.getElementById('slider'); e.value = arguments[0];"
        "e.dispatchEvent(new Event('input')); e.dispatchEvent(new Event('change'));",
        t,
    )


def test_the_replay_page_shows_every_vehicle_moving_and_seeks(
    browser: Any, page_url: str, flown: Path, tmp_path: Path
) -> None:
    flight = json.loads((flown / "flight.json").read_text())
    t_formation = float(flight["t_formation_start"])
    browser.get(page_url)
    _wait(browser, "s.scene !== null && s.frame !== null")
    state = _state(browser)
    assert state["scene"]["vehicles"] == ["lead", "right", "left"]
    assert all(v["x"] is not None and v["y"] is not None for v in state["frame"]["vehicles"])
    rows = browser.find_elements("css selector", "#vehicles tbody tr")
    assert [r.find_elements("css selector", "td")[1].text.split(" ")[0] for r in rows] == [
        "lead",
        "right",
        "left",
    ]

    # the slider: to the start of formation flight, while playing
    _seek(browser, t_formation)
    start = _wait(browser, f"s.frame.t >= {t_formation} - 0.05 && s.frame")
    assert start["phase"] == "formation" and start["leader"] == 0
    # playing: later frames, every vehicle somewhere else (formation flight at several m/s)
    later = _wait(browser, f"s.frame.t > {start['t']} + 3 && s.frame")
    for a, b in zip(start["vehicles"], later["vehicles"], strict=True):
        assert (a["x"] - b["x"]) ** 2 + (a["y"] - b["y"]) ** 2 > 1.0
    assert _state(browser)["trails"][0]  # the lead's trail is drawn

    browser.find_element("id", "play").click()  # pause
    _wait(browser, "s.status && s.status.playing === false")
    # back to 10 s while paused: the vehicles on the ground where the mission starts them (lead at (0, 0),
    # right at (-1.5, -10), left at (-10, 1.5) m: missions/quickstart.yaml)
    _seek(browser, 10.0)
    ground = _wait(browser, "s.frame.t <= 10 && s.frame")
    assert 9.9 <= ground["t"] <= 10.0
    for v, (x, y) in zip(ground["vehicles"], [(0.0, 0.0), (-1.5, -10.0), (-10.0, 1.5)], strict=True):
        assert abs(v["x"] - x) < 0.5 and abs(v["y"] - y) < 0.5 and abs(v["z"]) < 0.5
    assert _state(browser)["status"]["playing"] is False

    # a screenshot in formation as the obstacles narrow it, with trails (docs/replay.png is one of these)
    _seek(browser, t_formation + 4.0)
    browser.find_element("id", "play").click()
    _wait(browser, f"s.frame.t >= {t_formation} + 12 && s.status.playing")
    browser.find_element("id", "play").click()
    _wait(browser, "s.status.playing === false")
    out = tmp_path / "replay.png"
    assert browser.save_screenshot(str(out)) and out.stat().st_size > 0
