"""The figures' layout (figures/layout.py, figures/*.py): headers that fit
their columns, facets in a grid of sensible size, a reference drawn once for
the points that share it, efficiency figures at a page's width, titles and
legends clear of the panels. Measured with matplotlib's own renderer on
figures built from fake sweeps."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import pytest
from matplotlib.figure import Figure
from matplotlib.text import Text

from portal_harness.core.paths import ResultsLayout
from portal_harness.execution import index
from portal_harness.experiment.loader import load_experiment
from portal_harness.figures import data as figure_data
from portal_harness.figures import layout as figure_layout
from portal_harness.figures import style as figure_style
from portal_harness.figures.efficiency import build_efficiency
from portal_harness.figures.error_curves import build_error_curves
from portal_harness.figures.insets import build_insets

CliRunner = Callable[..., tuple[int, str, str]]
STRATEGIES = ["light", "portal", "projection", "antishadow", "antishadow_exact"]


def _box(artist: Any, renderer: Any) -> tuple[float, float, float, float]:
    b = artist.get_window_extent(renderer)
    return (b.x0, b.y0, b.x1, b.y1)


def _texts(fig: Figure) -> list[Text]:
    """The figure-level texts that have something to say (headers, labels, the title)."""
    return [t for t in fig.texts if t.get_text().strip()]


def _title(fig: Figure) -> Text:
    return next(t for t in fig.texts if t.get_text() == fig.get_suptitle())


@contextmanager
def _built(results: Path, exp: Path, build: Callable[..., Figure], *with_conn: bool) -> Iterator[Figure]:
    layout = ResultsLayout(results)
    from conftest import REAL_RENDERER

    experiment = load_experiment(exp, str(REAL_RENDERER))
    conn = index.connect(layout.index_path)
    try:
        data = figure_data.load(experiment, conn, layout)
        fig = build(experiment, data, conn) if with_conn else build(experiment, data)
        fig.canvas.draw()
        yield fig
    finally:
        conn.close()
        plt.close("all")


def test_01_headers_fit_any_number_of_columns() -> None:
    for name in ("antishadow (exact)", "a strategy with a much longer name than any today", "light"):
        for width in (40.0, 60.0, 90.0):
            text, size = figure_layout.fit_text(name, width, 8)
            assert figure_layout.text_width_pt(text, size) <= width or size == figure_layout.SMALLEST_FONT_PT
            assert text.replace("\n", " ") == name
    assert figure_layout.fit_text("antishadow (exact)", 60, 8) == ("antishadow\n(exact)", 8)
    assert figure_layout.overlapping([(0, 0, 1, 1), (1, 0, 2, 1), (0.5, 0.5, 1.5, 1.5)]) == [(0, 2), (1, 2)]


def test_02_grids_wrap_at_the_page_width() -> None:
    g = figure_layout.wrapped(9, 5)
    assert (g.rows, g.columns) == (2, 5) and g.cells[5] == (1, 0)
    b = figure_layout.blocks(2, 9, 5)
    assert (b.rows, b.columns) == (4, 5) and b.cells[9] == (2, 0)


@pytest.fixture
def weights_sweep(cli: CliRunner, write_experiment: Callable[..., Path]) -> Path:
    """Facets only (no axis), six points sharing one reference, five strategies."""
    exp = write_experiment(
        sweep={"render.portal_weight": ["area", "distance", "irradiance"], "render.defensive": [0, 0.1]},
        strategies=STRATEGIES,
        axis="none",
    )
    status, out, err = cli("sweep", str(exp), "--no-progress")
    assert status == 0, out + err
    return exp


def test_03_insets_headers_do_not_overlap_and_the_shared_reference_is_drawn_once(
    weights_sweep: Path, results: Path
) -> None:
    with _built(results, weights_sweep, build_insets, True) as fig:
        renderer = fig.canvas.get_renderer()  # type: ignore[attr-defined]
        texts = _texts(fig)
        headers = [
            t for t in texts if t.get_text().replace("\n", " ") in {figure_style.strategy_label(s) for s in STRATEGIES}
        ]
        assert len(headers) == len(STRATEGIES)
        pairs = figure_layout.overlapping([_box(t, renderer) for t in texts])
        assert pairs == [], [(texts[i].get_text(), texts[j].get_text()) for i, j in pairs]
        images = [ax for ax in fig.axes if ax.images and ax.get_title() == "reference"]
        assert len(images) == 1  # one reference image for the six points
        # the reference's inset column appears once too (2 insets), the strategies' for every point
        insets = [ax for ax in fig.axes if ax.images and ax.get_xlabel().endswith("spp")]
        assert len(insets) == 2


def test_04_error_curves_of_facets_without_an_axis_are_a_grid(weights_sweep: Path, results: Path) -> None:
    with _built(results, weights_sweep, build_error_curves, True) as fig:
        visible = [ax for ax in fig.axes if ax.get_visible()]
        # regions lit, left, right, image as columns; six facet combinations as rows
        assert len(visible) == 6 * 4
        rows = {round(ax.get_position().y0, 3) for ax in visible}
        cols = {round(ax.get_position().x0, 3) for ax in visible}
        assert (len(rows), len(cols)) == (6, 4)
        w, h = fig.get_size_inches()
        assert w < 12 and h < 12 and 0.5 < h / w < 2
        renderer = fig.canvas.get_renderer()  # type: ignore[attr-defined]
        title = _box(_title(fig), renderer)
        panels = [_box(ax, renderer) for ax in visible]  # with their titles and labels
        assert all(not figure_layout.overlapping([title, p]) for p in panels)


def test_05_error_curves_with_an_axis_draw_facets_as_line_styles(
    cli: CliRunner, write_experiment: Callable[..., Path], results: Path
) -> None:
    exp = write_experiment(sweep={"params.s_L": [0.15, 0.6], "render.portal_weight": ["area", "distance"]})
    status, out, err = cli("sweep", str(exp), "--no-progress")
    assert status == 0, out + err
    with _built(results, exp, build_error_curves, True) as fig:
        visible = [ax for ax in fig.axes if ax.get_visible()]
        assert len(visible) == 4 * 2  # regions x axis values
        styles = {line.get_linestyle() for ax in visible for line in ax.get_lines() if line.get_color() != "k"}
        assert {"-", "--"} <= styles


def test_06_efficiency_fits_a_page_with_the_legend_clear_of_the_panels(weights_sweep: Path, results: Path) -> None:
    with _built(results, weights_sweep, build_efficiency) as fig:
        w, h = fig.get_size_inches()
        assert w == pytest.approx(figure_layout.PAGE_WIDTH_IN) and h < 10
        renderer = fig.canvas.get_renderer()  # type: ignore[attr-defined]
        # what is saved (bbox_inches="tight"): nothing, the legend included, sticks out of the page
        assert fig.get_tightbbox(renderer).width <= figure_layout.PAGE_WIDTH_IN * 1.02
        legend = _box(fig.legends[0], renderer)
        title = _box(_title(fig), renderer)
        for ax in fig.axes:
            if ax.get_visible():
                panel = _box(ax, renderer)
                assert not figure_layout.overlapping([legend, panel]) and not figure_layout.overlapping([title, panel])
