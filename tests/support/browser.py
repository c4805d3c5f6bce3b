"""Headless chromium for the browser tests, driven by selenium.

Debian's `chromium` and `chromium-driver` (installed by `make test-py`,
$(CHROMIUM_STAMP)); no browser is downloaded. The tests that use it fail,
never skip, when the browser is missing: CI must really run them.

    from browser import Browser, chromium_fixture  # noqa: F401 (pytest finds it as `chromium`)

    def test_x(chromium: Browser) -> None:
        chromium.driver.get(url)
"""

from __future__ import annotations

import base64
import io
import os
import shutil
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from PIL import Image
from selenium import webdriver
from selenium.common.exceptions import TimeoutException
from selenium.webdriver.chrome.service import Service
from selenium.webdriver.remote.webdriver import WebDriver
from selenium.webdriver.support.ui import WebDriverWait

REPO = Path(__file__).resolve().parent.parent.parent
CHROMIUM = Path(os.environ.get("PORTAL_CHROMIUM", "/usr/bin/chromium"))
CHROMEDRIVER = Path(os.environ.get("PORTAL_CHROMEDRIVER", "/usr/bin/chromedriver"))
# Screenshots outlive the test session here (results/tmp/ is not tracked).
ARTEFACTS = Path(os.environ.get("PORTAL_TEST_ARTEFACTS", REPO / "results" / "tmp" / "browser"))
WINDOW = (1500, 1100)


@dataclass
class Browser:
    driver: WebDriver
    artefacts: Path  # where screenshots go (ARTEFACTS for the fixture)

    def wait_for(self, script: str, timeout_s: float = 20.0) -> Any:
        """Waits until `script` (a JS expression) is truthy; returns its value.
        On timeout the page's console is part of the failure."""
        try:
            return WebDriverWait(self.driver, timeout_s, poll_frequency=0.05).until(
                lambda d: d.execute_script(f"return {script};")
            )
        except TimeoutException:
            raise AssertionError(f"timed out waiting for {script!r}; console: {self.console()}") from None

    def console(self) -> list[str]:
        get_log = getattr(self.driver, "get_log", None)  # chromium's driver keeps one
        return [str(e.get("message")) for e in get_log("browser")] if get_log is not None else []

    def canvas_pixels(self, selector: str) -> np.ndarray:
        """The RGBA pixels of a canvas, (height, width, 4) uint8, read by the page itself."""
        data = self.driver.execute_script(
            """const c = document.querySelector(arguments[0]);
               const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
               let s = ''; const step = 0x8000;
               for (let i = 0; i < d.length; i += step) s += String.fromCharCode.apply(null, d.subarray(i, i + step));
               return [c.width, c.height, btoa(s)];""",
            selector,
        )
        width, height, text = data
        return np.frombuffer(base64.b64decode(text), dtype=np.uint8).reshape(height, width, 4)

    def viewer_state(self) -> dict[str, Any]:
        """The comparison viewer's state (Portal.viewer.state(): scale, pan, shown images...)."""
        state: dict[str, Any] = self.driver.execute_script("return Portal.viewer.state();")
        return state

    def viewer_keys(self, keys: str) -> None:
        """Types keys into the viewer and waits until each has redrawn it."""
        from selenium.webdriver.common.action_chains import ActionChains

        before = self.viewer_state()["draws"]
        ActionChains(self.driver).send_keys(keys).perform()
        self.wait_for(f"Portal.viewer.state().draws >= {before + len(keys)}")

    def viewer_image(self, shape: tuple[int, int], selector: str = "#images canvas") -> np.ndarray:
        """The image pixels as the viewer's first panel draws them: the screen
        pixel at the centre of each image pixel's block (all must be in view)."""
        s = self.viewer_state()
        scale, tx, ty = s["scale"], s["tx"], s["ty"]
        canvas = self.canvas_pixels(selector)
        h, w = shape
        ys = ty + np.arange(h) * scale + int(scale // 2)
        xs = tx + np.arange(w) * scale + int(scale // 2)
        assert ys[0] >= 0 and xs[0] >= 0 and ys[-1] < canvas.shape[0] and xs[-1] < canvas.shape[1], s
        shown: np.ndarray = canvas[np.ix_(ys, xs)][..., :3]
        return shown

    def screenshot(self, name: str) -> Path:
        """A PNG of the window, kept as a test artefact; its path is printed."""
        path = self.artefacts / f"{name}.png"
        png = self.driver.get_screenshot_as_png()
        Image.open(io.BytesIO(png)).save(path)
        print(f"screenshot: {path}")
        return path


def _check_installed() -> None:
    for path in (CHROMIUM, CHROMEDRIVER):
        if not (path.is_file() and os.access(path, os.X_OK)) and shutil.which(path.name) is None:
            pytest.fail(f"{path} is missing: `make test-py` installs Debian's chromium and chromium-driver")


def start(artefacts: Path) -> Browser:
    _check_installed()
    options = webdriver.ChromeOptions()
    options.binary_location = str(CHROMIUM)
    for arg in (
        "--headless=new",
        "--no-sandbox",  # root in a container has no user namespace for the sandbox
        "--disable-dev-shm-usage",
        "--disable-gpu",
        f"--window-size={WINDOW[0]},{WINDOW[1]}",
        "--force-device-scale-factor=1",
    ):
        options.add_argument(arg)
    options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    driver = webdriver.Chrome(service=Service(str(CHROMEDRIVER)), options=options)
    driver.set_page_load_timeout(30)
    artefacts.mkdir(parents=True, exist_ok=True)
    return Browser(driver, artefacts)


@pytest.fixture(scope="module", name="chromium")
def chromium_fixture() -> Iterator[Browser]:
    """One headless chromium per test module; screenshots in ARTEFACTS."""
    browser = start(ARTEFACTS)
    try:
        yield browser
    finally:
        browser.driver.quit()
