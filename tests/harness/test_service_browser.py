"""The experiments page in a real browser (Debian's headless chromium,
driven by Selenium): load it, submit a tiny experiment with the form,
watch its progress bars reach 100%, see the runs' images. The page's
screenshot is kept in results/tmp/test-artifacts/ (an artefact to look
at, not compared)."""

from __future__ import annotations

import shutil
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
import yaml
from test_service_server import REPO, TOKEN, Service, free_port

ARTIFACTS = REPO / "results" / "tmp" / "test-artifacts"
CHROMIUM = shutil.which("chromium")
CHROMEDRIVER = shutil.which("chromedriver")

pytestmark = pytest.mark.skipif(
    CHROMIUM is None or CHROMEDRIVER is None, reason="chromium and chromium-driver are not installed (make test does)"
)


@pytest.fixture
def browser() -> Iterator[object]:
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service as DriverService

    options = webdriver.ChromeOptions()
    options.binary_location = str(CHROMIUM)
    for arg in (
        "--headless=new",
        "--no-sandbox",
        "--disable-gpu",
        "--disable-dev-shm-usage",
        "--window-size=1200,1600",
    ):
        options.add_argument(arg)
    driver = webdriver.Chrome(service=DriverService(executable_path=str(CHROMEDRIVER)), options=options)
    try:
        yield driver
    finally:
        driver.quit()


def _experiment() -> str:
    return yaml.safe_dump(
        {
            "name": "browser_tiny",
            "scene": "lampshade.yaml",
            "integrator": "direct",
            "strategies": ["light", "antishadow"],
            "sweep": {"params.s_L": [0.6]},
            "fixed": {"params.s_P": 0.3, "film.width": 16, "film.height": 16},
            "budget": {"time_s": 1.0, "threads": 1, "seed": 1, "snapshots": {"every": 0.1}},
            "reference": {"strategy": "light", "spp": 64, "seed": 7},
        }
    )


@pytest.mark.real
def test_01_submit_from_the_page_and_watch_progress_reach_100(
    real_renderer: Path, tmp_path: Path, browser: object
) -> None:
    from selenium.webdriver.common.by import By
    from selenium.webdriver.remote.webdriver import WebDriver

    assert isinstance(browser, WebDriver)
    root = tmp_path / "root"
    root.mkdir()
    (root / "lampshade.yaml").write_bytes((REPO / "configs" / "scenes" / "lampshade.yaml").read_bytes())
    service = Service(tmp_path / "results", root, real_renderer, free_port())
    service.start()
    try:
        browser.get(f"http://127.0.0.1:{service.port}/")
        assert browser.title.startswith("portal-harness")
        textarea = browser.find_element(By.ID, "yaml")
        textarea.clear()
        browser.execute_script("arguments[0].value = arguments[1];", textarea, _experiment())
        # Without the token the form shows the refusal.
        browser.find_element(By.ID, "submit").click()
        result = browser.find_element(By.ID, "submit-result")
        _wait(lambda: result.text.startswith("401"), "the refusal without a token")
        browser.find_element(By.ID, "token").send_keys(TOKEN)
        browser.find_element(By.ID, "submit").click()
        _wait(lambda: result.text.startswith("queued:"), "the submission to be queued")
        bar = browser.find_element(By.CSS_SELECTOR, "#detail-bar")
        seen: list[int] = []
        status = browser.find_element(By.ID, "detail-status")
        deadline = time.monotonic() + 90
        while time.monotonic() < deadline:
            value = bar.find_element(By.XPATH, "..").get_attribute("aria-valuenow")
            seen.append(int(value or 0))
            if status.text == "status: done" and seen[-1] == 100:
                break
            time.sleep(0.05)
        else:
            raise AssertionError(f"progress never reached 100% (seen {sorted(set(seen))}, {status.text})")
        assert seen == sorted(seen), "the experiment's progress went backwards"
        assert any(0 < v < 100 for v in seen), "no progress seen between 0 and 100%"
        rows = browser.find_elements(By.CSS_SELECTOR, "#runs tbody tr")
        runs = [r for r in rows if r.find_element(By.CSS_SELECTOR, "td").text == "run"]
        assert len(runs) == 2
        for row in runs:
            assert row.find_element(By.CSS_SELECTOR, "[role=progressbar]").get_attribute("aria-valuenow") == "100"
            image = row.find_element(By.CSS_SELECTOR, "img.thumb")
            _wait(lambda image=image: browser.execute_script("return arguments[0].naturalWidth", image) == 16, "a PNG")
        # The list is redrawn every 3 s: look the cell up afresh each time.
        _wait(
            lambda: browser.find_element(By.CSS_SELECTOR, "#experiments tbody tr .status").text == "done",
            "the list to show done",
        )
        ARTIFACTS.mkdir(parents=True, exist_ok=True)
        assert browser.save_screenshot(str(ARTIFACTS / "service_page.png"))
    finally:
        service.stop()


def _wait(condition: object, what: str, timeout_s: float = 30) -> None:
    assert callable(condition)
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        try:
            if condition():
                return
        except Exception:  # a node replaced by the page's refresh: look again
            pass
        time.sleep(0.05)
    raise AssertionError(f"timed out waiting for {what}")


def test_02_the_api_documentation_renders_offline(tmp_path: Path, real_renderer: Path, browser: object) -> None:
    from selenium.webdriver.common.by import By
    from selenium.webdriver.remote.webdriver import WebDriver

    assert isinstance(browser, WebDriver)
    root = tmp_path / "root"
    root.mkdir()
    service = Service(tmp_path / "results", root, real_renderer, free_port())
    service.start()
    try:
        browser.get(f"http://127.0.0.1:{service.port}/docs")
        # Swagger UI (served from the wheel) reads the OpenAPI 3.1 schema and lists the operations.
        _wait(lambda: len(browser.find_elements(By.CSS_SELECTOR, ".opblock")) >= 5, "the documented operations")
        text = browser.find_element(By.TAG_NAME, "body").text
        assert "/api/experiments/{experiment_id}/events" in text and "Unable to render" not in text
        resources = browser.execute_script("return performance.getEntriesByType('resource').map(e => e.name)")
        assert resources and all(str(r).startswith(f"http://127.0.0.1:{service.port}/") for r in resources)
    finally:
        service.stop()
