"""`portal-harness figures`: the tables of the summary (tables.py, to
results/experiments/<experiment>/summary.tex), then every figure, as PNG and PDF
in results/figures/<experiment>_<figure>.{png,pdf}."""

from __future__ import annotations

from pathlib import Path

from portal_harness.analysis import tables
from portal_harness.core.paths import ResultsLayout
from portal_harness.execution import index
from portal_harness.experiment.model import Experiment
from portal_harness.figures.data import load
from portal_harness.figures.efficiency import figure_efficiency
from portal_harness.figures.error_curves import figure_error_curves
from portal_harness.figures.gain import figure as figure_gain
from portal_harness.figures.insets import figure_insets
from portal_harness.figures.regions import figure_regions


def make_all(experiment: Experiment, layout: ResultsLayout) -> list[Path]:
    conn = index.connect(layout.index_path)
    try:
        data = load(experiment, conn, layout)
        # The tables first: they need no image and are the cheapest output.
        paths = [
            tables.write(
                layout.summary_csv(experiment.name).with_name("summary.tex"),
                experiment.name,
                data.summary,
                experiment.facets,
                experiment.axis.label if experiment.axis is not None else None,
            )
        ]
        paths += figure_error_curves(experiment, data, conn, layout)
        paths += figure_insets(experiment, data, conn, layout)
        paths += figure_efficiency(experiment, data, conn, layout)
        paths += figure_regions(experiment, data, conn, layout)
        paths += figure_gain(experiment, layout)
    finally:
        conn.close()
    return paths
