"""Figure layout helpers: grid shapes, text that fits its column, and the
sizes figures are drawn at (a paper's page width).

Kept apart from the figures themselves so that the rules (how facets and
regions become rows and columns, how a header wraps) are tested without
rendering anything.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from matplotlib.font_manager import FontProperties
from matplotlib.textpath import TextToPath

# A paper's text width (two-column layouts: ~7 in; one column ~3.4 in).
PAGE_WIDTH_IN = 7.0
# The most panels side by side at page width before they are too small to read.
MAX_COLUMNS = 4
SMALLEST_FONT_PT = 5.0

_TEXT_TO_PATH = TextToPath()


def text_width_pt(text: str, fontsize: float) -> float:
    """Width in points of the widest line of `text` in matplotlib's default font."""
    prop = FontProperties(size=fontsize)
    return max(
        (_TEXT_TO_PATH.get_text_width_height_descent(line, prop, ismath=False)[0] for line in text.split("\n")),
        default=0.0,
    )


def fit_text(text: str, width_pt: float, fontsize: float, max_lines: int = 3) -> tuple[str, float]:
    """`text` broken at spaces into lines no wider than `width_pt`, at
    `fontsize` or the largest smaller size (down to SMALLEST_FONT_PT) at
    which it fits in `max_lines`; returns (text, fontsize)."""
    size = fontsize
    while True:
        lines = _wrap(text.split(), width_pt, size)
        if (
            len(lines) <= max_lines and all(text_width_pt(x, size) <= width_pt for x in lines)
        ) or size <= SMALLEST_FONT_PT:
            return "\n".join(lines), size
        size = max(SMALLEST_FONT_PT, size - 0.5)


def _wrap(words: list[str], width_pt: float, size: float) -> list[str]:
    lines: list[str] = []
    for word in words:
        if lines and text_width_pt(f"{lines[-1]} {word}", size) <= width_pt:
            lines[-1] = f"{lines[-1]} {word}"
        else:
            lines.append(word)
    return lines or [""]


@dataclass(frozen=True)
class Grid:
    """rows x columns of panels; `cells[i]` is the (row, column) of panel i."""

    rows: int
    columns: int
    cells: tuple[tuple[int, int], ...]


def wrapped(n: int, max_columns: int = MAX_COLUMNS) -> Grid:
    """n panels in reading order, at most `max_columns` to a row, the rows as even as can be."""
    n_rows = max(1, math.ceil(n / max_columns))
    columns = max(1, math.ceil(n / n_rows))
    return Grid(n_rows, columns, tuple(divmod(i, columns) for i in range(n)))


def blocks(n_blocks: int, per_block: int, max_columns: int = MAX_COLUMNS) -> Grid:
    """`n_blocks` groups of `per_block` panels, each group starting a new row
    and wrapped at `max_columns`: panel (b, j) is cells[b * per_block + j]."""
    inner = wrapped(per_block, max_columns)
    cells = tuple((b * inner.rows + r, c) for b in range(n_blocks) for r, c in inner.cells)
    return Grid(n_blocks * inner.rows, inner.columns, cells)


def panel_size(columns: int, width_in: float = PAGE_WIDTH_IN, aspect: float = 0.8) -> tuple[float, float]:
    """(width, height) in inches of one panel when `columns` share `width_in`."""
    w = width_in / max(columns, 1)
    return w, w * aspect


def overlapping(boxes: Sequence[tuple[float, float, float, float]]) -> list[tuple[int, int]]:
    """Pairs of (x0, y0, x1, y1) boxes that overlap (touching edges do not)."""
    out = []
    for i, a in enumerate(boxes):
        for j in range(i + 1, len(boxes)):
            b = boxes[j]
            if a[0] < b[2] and b[0] < a[2] and a[1] < b[3] and b[1] < a[3]:
                out.append((i, j))
    return out


def legend_columns(labels: Sequence[str], width_in: float, fontsize: float, most: int = 4) -> int:
    """How many legend entries fit side by side in `width_in` (each takes its
    label's width plus a handle and spacing, ~4 font sizes)."""
    widest = max((text_width_pt(label, fontsize) for label in labels), default=0.0) + 4 * fontsize
    return max(1, min(most, len(labels), int(width_in * 72 // widest)))
