"""Debian's headless Chromium driven by Selenium through Debian's chromedriver (never selenium-manager, which
would go to the network), for the page's browser tests. Waits are bounded (WAIT_S) so that a broken page fails
instead of hanging; no assertion is about time."""

from __future__ import annotations

import os
import shutil
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pytest

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
CHROMEDRIVER = Path("/usr/bin/chromedriver")
WAIT_S = 120.0  # s: a hang guard only

needs_chromium = pytest.mark.skipif(
    (CHROMIUM is None or not CHROMEDRIVER.exists()) and not os.environ.get("CI"),
    reason="no Debian chromium/chromium-driver (apt-get install chromium chromium-driver); CI runs it",
)


@contextmanager
def chromium(profile: Path) -> Iterator[Any]:
    """A headless Chromium with its profile in `profile`, quit on the way out."""
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    if CHROMIUM:
        options.binary_location = CHROMIUM
    for flag in (
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--disable-background-networking",
        "--disable-component-update",
        "--disable-sync",
        "--no-first-run",
        f"--user-data-dir={profile}",
        "--window-size=1400,900",
    ):
        options.add_argument(flag)
    driver = webdriver.Chrome(service=Service(executable_path=str(CHROMEDRIVER)), options=options)
    driver.set_script_timeout(WAIT_S)
    try:
        yield driver
    finally:
        driver.quit()


def page_state(driver: Any) -> Any:
    return driver.execute_script("return window.swarmState;")


def wait_for(driver: Any, script: str) -> Any:
    """Wait until the JS expression `script` (over `s`, window.swarmState) is truthy; its value."""
    from selenium.webdriver.support.ui import WebDriverWait

    return WebDriverWait(driver, WAIT_S, poll_frequency=0.1).until(
        lambda d: d.execute_script(f"const s = window.swarmState; return ({script});")
    )
