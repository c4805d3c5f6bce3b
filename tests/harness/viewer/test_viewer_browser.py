"""The report's viewer in a real browser (headless chromium from Debian,
driven by selenium), opened from disk as a reader of a supplemental would:
the pixels shown are display.to_srgb8 of the runs' images, the number keys
flip between them, zoom reaches single pixels, exposure and the error map
change what is drawn, and the charts answer a hover with the summary's
values. A screenshot is kept as an artefact (its path is printed)."""

from __future__ import annotations

import base64
import re
import shutil
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from browser import Browser, chromium_fixture  # noqa: F401 (pytest finds it as `chromium`)
from selenium.webdriver.common.action_chains import ActionChains
from selenium.webdriver.common.actions.wheel_input import ScrollOrigin
from selenium.webdriver.common.by import By
from selenium.webdriver.support.ui import Select
from viewer_sweep import swept_once

from portal_harness.cli import main
from portal_harness.core import display
from portal_harness.viewer import bundle as vb

PANEL = "#images canvas"


@pytest.fixture(scope="module")
def report(tmp_path_factory: pytest.TempPathFactory, fake_renderer: Path) -> Path:
    swept = swept_once(tmp_path_factory, fake_renderer)
    out = tmp_path_factory.mktemp("report-parent") / "report"
    args = ["--results", str(swept.results), "--renderer", str(swept.renderer)]
    assert main(["report", str(swept.experiment), "--out", str(out), *args]) == 0
    return out


@pytest.fixture(scope="module")
def data(report: Path) -> dict[str, Any]:
    return vb.read_bundle(report / "data")


def _open(b: Browser, url: str) -> None:
    b.driver.get(url)
    assert b.wait_for("document.body.dataset.ready") == "1", b.driver.find_element(By.ID, "message").text


def _expected(report: Path, data: dict[str, Any], index: int, exposure: float) -> np.ndarray:
    entry = data["points"][0]["images"][index]
    return display.to_srgb8(vb.read_image(report / "data", entry["image"]).astype(np.float64), exposure)


def _assert_close(shown: np.ndarray, expected: np.ndarray) -> None:
    """Within one level everywhere; equal almost everywhere (measured: equal
    for all 5.9 million channel values of lampshade_ratio's 30 images)."""
    diff = np.abs(shown.astype(int) - expected.astype(int))
    assert diff.max() <= 1, f"max difference {diff.max()} levels at {np.unravel_index(diff.argmax(), diff.shape)}"
    assert np.mean(diff == 0) >= 0.99


def test_01_report_opens_from_disk_side_by_side(chromium: Browser, report: Path, data: dict[str, Any]) -> None:
    _open(chromium, (report / "viewer.html").as_uri())
    captions = [e.text for e in chromium.driver.find_elements(By.CSS_SELECTOR, "#images .caption")]
    assert [c.split()[1] for c in captions] == ["reference", "light", "portal"]
    s = chromium.viewer_state()
    assert s["layout"] == "grid" and s["shown"] == [e["image"] for e in data["points"][0]["images"]]
    assert s["exposure"] == pytest.approx(data["points"][0]["exposure"], rel=1e-12)
    # the region table has a row per region and a column per strategy
    rows = chromium.driver.find_elements(By.CSS_SELECTOR, "#metrics-table tr[data-region]")
    assert [r.get_attribute("data-region") for r in rows] == [r["name"] for r in data["points"][0]["regions"]]
    # ] and [ step through the sweep's points
    ActionChains(chromium.driver).send_keys("]").perform()
    chromium.wait_for("Portal.viewer.state().point === 1 && document.body.dataset.loading === '0'")
    chromium.wait_for(f"Portal.viewer.state().draws > {s['draws']}")
    assert chromium.viewer_state()["shown"] == [e["image"] for e in data["points"][1]["images"]]
    assert chromium.driver.find_element(By.ID, "point").get_attribute("value") == "1"
    ActionChains(chromium.driver).send_keys("[").perform()
    chromium.wait_for("Portal.viewer.state().point === 0")
    severe = [m for m in chromium.console() if "SEVERE" in m or "Error" in m]
    assert not severe, severe


def test_02_number_keys_flip_and_pixels_are_to_srgb8(chromium: Browser, report: Path, data: dict[str, Any]) -> None:
    _open(chromium, (report / "viewer.html").as_uri())
    chromium.viewer_keys("i")  # insets off: their frames would cover pixels
    exposure = data["points"][0]["exposure"]
    shown = []
    for k in range(3):
        chromium.viewer_keys(str(k + 1))
        s = chromium.viewer_state()
        assert s["layout"] == "single" and s["current"] == k
        assert s["shown"] == [data["points"][0]["images"][k]["image"]]
        image = chromium.viewer_image((16, 16))
        _assert_close(image, _expected(report, data, k, exposure))
        shown.append(image)
    assert not np.array_equal(shown[0], shown[1]) and not np.array_equal(shown[1], shown[2])


def test_03_zoom_shows_single_pixels_and_their_values(chromium: Browser, report: Path, data: dict[str, Any]) -> None:
    _open(chromium, (report / "viewer.html").as_uri())
    chromium.viewer_keys("i1")
    canvas = chromium.driver.find_element(By.CSS_SELECTOR, PANEL)
    before = chromium.viewer_state()["scale"]
    for _ in range(3):
        ActionChains(chromium.driver).scroll_from_origin(ScrollOrigin.from_element(canvas, 30, 20), 0, -120).perform()
    chromium.wait_for(f"Portal.viewer.state().scale > {before}")
    s = chromium.viewer_state()
    scale, tx, ty = s["scale"], s["tx"], s["ty"]
    assert scale == int(scale) and scale > before
    pixels = chromium.canvas_pixels(PANEL)[..., :3]
    expected = _expected(report, data, 0, data["points"][0]["exposure"])
    # every screen pixel shows the image pixel its block belongs to: blocks of scale x scale
    hh, ww = pixels.shape[:2]
    ix = (np.arange(ww) - tx) // scale
    iy = (np.arange(hh) - ty) // scale
    inside_x = (ix >= 0) & (ix < 16)
    inside_y = (iy >= 0) & (iy < 16)
    assert inside_x.sum() >= scale * 3 and inside_y.sum() >= scale * 3
    want = expected[np.ix_(iy[inside_y], ix[inside_x])]
    _assert_close(pixels[np.ix_(inside_y, inside_x)], want)
    block = pixels[np.ix_(inside_y, inside_x)]
    assert len(np.unique(block.reshape(-1, 3), axis=0)) == len(np.unique(want.reshape(-1, 3), axis=0))
    # the value under the cursor: the pixel at the canvas centre
    ActionChains(chromium.driver).move_to_element_with_offset(canvas, 0, 0).perform()
    info = chromium.driver.find_element(By.ID, "pixel-info")
    x, y = int(info.get_attribute("data-x") or -1), int(info.get_attribute("data-y") or -1)
    rect = canvas.rect
    assert (x, y) == ((int(rect["width"] / 2) - tx) // scale, (int(rect["height"] / 2) - ty) // scale)
    ref = vb.read_image(report / "data", data["points"][0]["images"][0]["image"])
    red = float(re.search(r"1 reference: (\S+)", info.text).group(1))  # type: ignore[union-attr]
    assert red == pytest.approx(float(ref[y, x, 0]), rel=1e-3)


def test_04_exposure_keys_and_slider(chromium: Browser, report: Path, data: dict[str, Any]) -> None:
    _open(chromium, (report / "viewer.html").as_uri())
    chromium.viewer_keys("i2++")
    s = chromium.viewer_state()
    base = data["points"][0]["exposure"]
    assert s["stops"] == 1 and s["exposure"] == pytest.approx(2 * base, rel=1e-12)
    _assert_close(chromium.viewer_image((16, 16)), _expected(report, data, 1, 2 * base))
    chromium.viewer_keys("-")
    assert chromium.driver.find_element(By.ID, "exposure").get_attribute("value") == "0.5"
    chromium.viewer_keys("0")
    _assert_close(chromium.viewer_image((16, 16)), _expected(report, data, 1, base))


def test_05_error_maps_are_the_relative_error_and_flip_in_false_colour(
    chromium: Browser,
    report: Path,
    data: dict[str, Any],
) -> None:
    _open(chromium, (report / "viewer.html").as_uri())
    chromium.viewer_keys("i2e")
    assert chromium.viewer_state()["errorKind"] == "relative"
    assert chromium.driver.find_element(By.ID, "colourbar").is_displayed()
    images = data["points"][0]["images"]
    x = vb.read_image(report / "data", images[1]["image"]).astype(np.float64)
    r = vb.read_image(report / "data", images[0]["image"]).astype(np.float64)
    relative = display.luminance(np.abs(x - r)) / (np.maximum(display.luminance(r), 0) + 0.01)
    flip = vb.read_image(report / "data", images[1]["flip_image"]).astype(np.float64)
    colours = np.array(data["error_colormap"]["colours"])
    for error, kind in ((relative, "relative"), (flip, "flip")):
        # both on a linear scale from 0 to 1 (the default maximum of the relative error)
        index = np.rint(np.clip(error, 0, 1) * (len(colours) - 1)).astype(int)
        shown = chromium.viewer_image((16, 16)).astype(int)
        found = np.abs(shown[:, :, None, :] - colours[None, None, :, :]).sum(-1).argmin(-1)
        assert np.abs(found - index).max() <= 1, kind  # the same colour (a neighbour where rounding differs)
        assert np.mean(found == index) > 0.95, kind
        chromium.viewer_keys("e")
    assert chromium.viewer_state()["errorKind"] == ""
    assert "FLIP: " in chromium.driver.find_element(By.ID, "metrics-table").text


def test_06_charts_show_values_on_hover_and_a_screenshot(
    chromium: Browser,
    report: Path,
    data: dict[str, Any],
) -> None:
    _open(chromium, (report / "viewer.html").as_uri())
    driver = chromium.driver
    markers = driver.find_elements(By.CSS_SELECTOR, "#chart-efficiency .marker[data-strategy=portal]")
    assert len(markers) == len(data["points"])
    marker = markers[-1]
    driver.execute_script("arguments[0].scrollIntoView({block: 'center'});", marker)
    ActionChains(driver).move_to_element(marker).perform()
    tip = driver.find_element(By.ID, "chart-tooltip")
    chromium.wait_for("document.getElementById('chart-tooltip').style.display === 'block'")
    row = next(
        r
        for r in data["summary"]
        if r["point"] == marker.get_attribute("data-point") and r["strategy"] == "portal" and r["region"] == "lit"
    )
    value = float(re.search(r"efficiency relative to light = (\S+)", tip.text).group(1))  # type: ignore[union-attr]
    assert value == pytest.approx(row["efficiency_vs_light"], rel=5e-3) and "portal" in tip.text
    curve = driver.find_elements(By.CSS_SELECTOR, "#chart-error .marker[data-strategy=light]")
    ActionChains(driver).move_to_element(curve[0]).perform()
    chromium.wait_for("document.getElementById('chart-tooltip').textContent.indexOf('relMSE = ') > 0")
    lit = data["curves"][data["points"][0]["id"]]["lit"]["strategies"]["light"]
    shown = float(re.search(r"relMSE = (\S+)", tip.text).group(1))  # type: ignore[union-attr]
    assert shown == pytest.approx(lit["v"][0], rel=5e-3)
    assert chromium.screenshot("viewer_charts").stat().st_size > 10000  # the tooltip shown
    driver.execute_script("window.scrollTo(0, 0);")
    path = chromium.screenshot("viewer")
    assert path.stat().st_size > 10000


def test_07_bundle_from_the_query_string_and_refusals(chromium: Browser, report: Path) -> None:
    elsewhere = report.parent / "elsewhere"
    shutil.copytree(report / "data", elsewhere / "data")
    _open(chromium, (report / "viewer.html").as_uri() + "?bundle=../elsewhere/data")
    assert chromium.viewer_state()["shown"]
    for bad in ("https://example.com/data/", "//example.com/data/", "javascript:alert(1)"):
        chromium.driver.get((report / "viewer.html").as_uri() + "?bundle=" + bad)
        message = chromium.wait_for("document.getElementById('message').textContent")
        assert "must be a path on this site" in message


def test_08_a_region_is_highlighted_and_classes_are_tinted(
    chromium: Browser,
    report: Path,
    data: dict[str, Any],
) -> None:
    _open(chromium, (report / "viewer.html").as_uri())
    chromium.viewer_keys("i1")
    point = data["points"][0]
    expected = _expected(report, data, 0, point["exposure"]).astype(float)
    region = next(r for r in point["regions"] if r["name"] == "lit")
    mask = np.unpackbits(np.frombuffer(base64.b64decode(region["mask"]), dtype=np.uint8))[:256].reshape(16, 16)
    before = chromium.viewer_state()["draws"]
    Select(chromium.driver.find_element(By.ID, "region")).select_by_value("lit")
    chromium.wait_for(f"Portal.viewer.state().draws > {before}")
    shown = chromium.viewer_image((16, 16)).astype(float)
    # outside the region at 30% (viewer DIM), inside untouched
    want = np.where(mask[..., None] == 1, expected, np.rint(expected * 0.3))
    assert np.abs(shown - want).max() <= 1 and (mask == 0).any() and (mask == 1).any()
    assert (
        chromium.driver.find_element(By.CSS_SELECTOR, "#metrics-table tr.highlighted").get_attribute("data-region")
        == "lit"
    )
    before = chromium.viewer_state()["draws"]
    Select(chromium.driver.find_element(By.ID, "region")).select_by_value("*classes")
    chromium.wait_for(f"Portal.viewer.state().draws > {before}")
    tinted = chromium.viewer_image((16, 16)).astype(float)
    classes = [r for r in point["regions"] if r["kind"] == "class"]
    assert classes and "anti-umbra" in chromium.driver.find_element(By.ID, "class-legend").text
    for r in classes:
        m = np.unpackbits(np.frombuffer(base64.b64decode(r["mask"]), dtype=np.uint8))[:256].reshape(16, 16) == 1
        colour = np.array([int(data["class_colours"][r["name"]][i : i + 2], 16) for i in (1, 3, 5)], dtype=float)
        # blended towards the class colour with alpha 150/255
        blend = expected[m] * (1 - 150 / 255) + colour * 150 / 255
        assert np.abs(tinted[m] - blend).max() <= 1.5, r["name"]
