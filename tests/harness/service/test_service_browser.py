"""The experiments page in a real browser (Debian's headless chromium,
driven by Selenium): load it, submit a tiny experiment with the form,
watch its progress bars reach 100%, see the runs' images, open the
comparison viewer from the page, flip between strategies and check the
pixels shown are the service's PNG of each run, zoom. Screenshots are kept
in results/tmp/test-artifacts/ (artefacts to look at, not compared)."""

from __future__ import annotations

import io
import time
import urllib.request
from pathlib import Path

import numpy as np
import pytest
import yaml
from browser import Browser, chromium_fixture  # noqa: F401 (pytest finds it as `chromium`)
from conftest import REPO
from PIL import Image
from served import TOKEN, Service, free_port

ARTIFACTS = REPO / "results" / "tmp" / "test-artifacts"


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
def test_01_submit_watch_progress_reach_100_then_compare_in_the_viewer(
    real_renderer: Path, tmp_path: Path, chromium: Browser
) -> None:
    from selenium.webdriver.common.action_chains import ActionChains
    from selenium.webdriver.common.actions.wheel_input import ScrollOrigin
    from selenium.webdriver.common.by import By

    browser = chromium.driver
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

        # The comparison viewer, opened from the page's link: 1 = reference, 2.. = strategies.
        link = browser.find_element(By.CSS_SELECTOR, "a[href*='viewer.html']")
        browser.get(str(link.get_attribute("href")))
        assert chromium.wait_for("document.body.dataset.ready", timeout_s=60) == "1"
        bundle = browser.execute_script("return window.PORTAL_BUNDLE;")
        entries = bundle["points"][0]["images"]
        assert [e["name"] for e in entries] == ["reference", "light", "antishadow"]
        chromium.viewer_keys("i")  # insets off: their frames would cover pixels
        shown = []
        for k in (1, 2):
            chromium.viewer_keys(str(k + 1))
            assert chromium.viewer_state()["current"] == k
            pixels = chromium.viewer_image((16, 16))
            # The viewer shows each run's image at the point's equal time; the service's PNG
            # of that image is tone-mapped with the same reference exposure.
            png = _get(service.port, f"/api/runs/{entries[k]['run']}/image.png?image={entries[k]['file']}")
            expected = np.asarray(Image.open(io.BytesIO(png)).convert("RGB"))
            diff = np.abs(pixels.astype(int) - expected.astype(int))
            assert diff.max() <= 1 and np.mean(diff == 0) >= 0.99, f"max difference {diff.max()} levels"
            shown.append(pixels)
        assert not np.array_equal(shown[0], shown[1]), "flipping did not change the pixels"
        # Zoom: the wheel over the image makes image pixels larger square blocks.
        before = chromium.viewer_state()["scale"]
        canvas = browser.find_element(By.CSS_SELECTOR, "#images canvas")
        ActionChains(browser).scroll_from_origin(ScrollOrigin.from_element(canvas, 10, 10), 0, -120).perform()
        chromium.wait_for(f"Portal.viewer.state().scale > {before}")
        chromium.screenshot("service_viewer")
    finally:
        service.stop()


def _get(port: int, path: str) -> bytes:
    with urllib.request.urlopen(f"http://127.0.0.1:{port}{path}", timeout=30) as r:
        data: bytes = r.read()
        return data


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


def test_02_the_api_documentation_renders_offline(tmp_path: Path, real_renderer: Path, chromium: Browser) -> None:
    from selenium.webdriver.common.by import By

    browser = chromium.driver
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
