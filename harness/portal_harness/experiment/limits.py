"""Bounds on the work one experiment creates, checked while it is loaded
(loader.py), before any point is asked of the renderer and before any run
is planned: so a submission of a billion replicates is refused in
microseconds, with the limit it breaks and its value.

- points: the sweep's cross product;
- runs: points x strategies x replicates (with `precision:`, its
  max_replicates: the most the sweep may run; the time and bytes too);
- total_time_s: the budgeted render time of the runs, the references
  (their extension included) and the pilots;
- snapshots: per run, counted from the snapshot schedule over the run's
  time and samples (samples reached in a time-limited run are bounded by a
  fast render, the time of a sample-limited run by a slow one);
- bytes: the images written, film width x height x channels x 4 bytes per
  snapshot and final image, of every run and reference;
- pixels: of the film (a render holds several float images of it in memory).

`portal-harness serve` and `portal-harness sweep` check them (their
--max-* options; `sweep --no-limits` lifts them). The defaults let every
experiment of configs/experiments/ through, the `_full` ones included.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from portal_harness.core.errors import ConfigError
from portal_harness.experiment import contract, facets
from portal_harness.experiment.model import Budget, Precision, ReferenceSettings
from portal_harness.experiment.schema import Reader

# Pixel samples per second of one render: above what any render here reaches
# (to bound the samples of a time-limited run) and below (to bound the time
# of a sample-limited one).
FAST_PIXEL_SAMPLES_PER_S = 1e8
SLOW_PIXEL_SAMPLES_PER_S = 2e5
BYTES_PER_CHANNEL = 4  # float32 EXR channels, at worst uncompressed
HUGE = 1e18  # counts past this are all "too many" (and are not rounded)
GIB = 2**30


@dataclass(frozen=True)
class Limits:
    max_points: int = 100
    max_runs: int = 2000
    max_total_time_s: float = 48 * 3600.0
    max_snapshots: int = 200  # per run
    max_bytes: int = 128 * GIB
    max_pixels: int = 4096 * 4096  # of the film (each render holds several float images of it)

    @staticmethod
    def option_names() -> dict[str, str]:
        """The limit's field -> the command line's option that sets it."""
        return {
            "max_points": "--max-points",
            "max_runs": "--max-runs",
            "max_total_time_s": "--max-total-time",
            "max_snapshots": "--max-snapshots",
            "max_bytes": "--max-bytes",
            "max_pixels": "--max-pixels",
        }


class LimitError(ConfigError):
    """An experiment over a limit: names the limit, the value and the bound."""

    def __init__(
        self,
        file: str,
        key: str,
        limit: str,
        value: float,
        maximum: float,
        what: str,
        line: int | None = None,
        column: int | None = None,
    ) -> None:
        self.limit, self.value, self.maximum = limit, value, maximum
        option = Limits.option_names()[limit]
        message = (
            f"over the limit {limit} ({option}): {what} {_fmt(value)}, at most {_fmt(maximum)} "
            "(portal-harness sweep --no-limits lifts the limits)"
        )
        super().__init__(file, key, message, line, column)


def _fmt(value: float) -> str:
    return f"{int(value)}" if float(value).is_integer() and abs(value) < 1e15 else f"{value:.4g}"


def capped_product(sizes: list[int], cap: int) -> int:
    """The product of `sizes`, or cap + 1 once it exceeds cap (no huge integers)."""
    out = 1
    for s in sizes:
        out *= s
        if out > cap:
            return cap + 1
    return out


def run_time_bound_s(time_s: float, spp: int, pixels: int) -> float:
    """The longest a run of these limits renders."""
    slow = spp * pixels / SLOW_PIXEL_SAMPLES_PER_S
    return min(time_s, slow) if time_s > 0 and spp > 0 else (time_s if time_s > 0 else slow)


def run_spp_bound(time_s: float, spp: int, pixels: int) -> float:
    """The most samples per pixel a run of these limits reaches."""
    fast = time_s * FAST_PIXEL_SAMPLES_PER_S / pixels
    return min(float(spp), fast) if time_s > 0 and spp > 0 else (float(spp) if spp > 0 else fast)


def snapshot_count(
    schedule: tuple[tuple[str, str], ...], units: dict[str, str], time_s: float, spp: int, pixels: int
) -> float:
    """At most how many snapshots a run writes: each schedule's count over the
    run's time (`s` keys) or samples (`spp` keys); `every` keys count T/period,
    `doubling` keys log2(T/first) + 1."""
    t = run_time_bound_s(time_s, spp, pixels)
    n = run_spp_bound(time_s, spp, pixels)
    total = 0.0
    for key, text in schedule:
        period = float(text)
        if period <= 0:
            continue
        span = n if units.get(key) == "spp" else t
        ratio = span / period  # may be inf (a period of 5e-324)
        if not math.isfinite(ratio) or ratio > HUGE:
            return math.inf if math.isnan(ratio) else max(ratio, HUGE)
        if key.startswith("doubling"):
            total += math.floor(math.log2(ratio)) + 1 if ratio >= 1 else 0
        else:
            total += math.floor(ratio)
    return total


@dataclass(frozen=True)
class Work:
    """What an experiment asks for, counted before anything is planned."""

    points: int
    reference_points: int
    strategies: int
    replicates: int
    run_time_s: float  # at most, per run
    snapshots: float  # at most, per run
    reference_time_s: float  # at most, per reference point: its parts and pilots
    reference_images: int  # per reference point (each part's final image and film state)
    pixels: int
    channels: int

    @property
    def runs(self) -> int:
        return self.points * self.strategies * self.replicates

    @property
    def total_time_s(self) -> float:
        return self.runs * self.run_time_s + self.reference_points * self.reference_time_s

    @property
    def bytes(self) -> float:
        image = float(self.pixels) * self.channels * BYTES_PER_CHANNEL
        return image * (self.runs * (self.snapshots + 1) + self.reference_points * self.reference_images)


# Each limit: the key of the experiment file that sets it, and what is counted.
_WHERE = {
    "max_points": ("sweep", "points in the sweep's cross product"),
    "max_runs": ("budget.replicates", "runs (points x strategies x replicates)"),
    "max_snapshots": ("budget.snapshots", "snapshots per run"),
    "max_total_time_s": ("budget.time_s", "seconds of budgeted render time"),
    "max_bytes": ("budget", "bytes of images (width x height x channels x 4 x images)"),
    "max_pixels": ("fixed", "pixels of the film (width x height)"),
}


def check(work: Work, limits: Limits, r: Reader, where: dict[str, tuple[str, str]] | None = None) -> None:
    """LimitError for the first limit the work breaks (points first: the
    other counts multiply them); `where` replaces some limits' keys."""
    for limit, value in (
        ("max_pixels", float(work.pixels)),
        ("max_points", float(work.points)),
        ("max_runs", float(work.runs)),
        ("max_total_time_s", work.total_time_s),
        ("max_snapshots", work.snapshots),
        ("max_bytes", work.bytes),
    ):
        maximum = float(getattr(limits, limit))
        if value > maximum:
            key, what = {**_WHERE, **(where or {})}[limit]
            line = r.line_of(key)
            raise LimitError(r.file, key, limit, value, maximum, what, *(line if line else (None, None)))


def check_points(r: Reader, limits: Limits, sweep: tuple[tuple[str, tuple[object, ...]], ...]) -> int:
    """The sweep's points, checked against max_points (each is asked of the renderer)."""
    points = capped_product([len(values) for _, values in sweep], max(limits.max_points, 1))
    if points > limits.max_points:
        key, what = _WHERE["max_points"]
        line = r.line_of(key)
        raise LimitError(r.file, key, "max_points", points, limits.max_points, what, *(line or (None, None)))
    return points


def limit_work(
    r: Reader,
    limits: Limits,
    names: contract.Contract,
    sweep: tuple[tuple[str, tuple[object, ...]], ...],
    strategies: tuple[str, ...],
    budget: Budget,
    reference: ReferenceSettings,
    pixels: int,
    precision: Precision | None = None,
) -> None:
    """Counts an experiment's work from its parsed sections (no point asked
    of the renderer, no run planned) and checks it against the limits. With
    `precision`, every (point, strategy) is counted at the replicates the
    sweep may reach, precision.max_replicates, not the first stage's."""
    points = check_points(r, limits, sweep)
    cap = max(limits.max_points, 1)
    ref_points = capped_product([len(v) for k, v in sweep if not facets.shares_reference(k)], cap)
    parts = 1 if len(reference.strategies) == 1 else 2
    ref_time = max(run_time_bound_s(reference.time_s, reference.spp, pixels), reference.max_time_s)
    pilots = reference.pilot_time_s * len(names.strategies) if not reference.strategies else 0.0
    units = dict(names.snapshot_units)
    work = Work(
        points=points,
        reference_points=ref_points,
        strategies=len(strategies),
        replicates=precision.max_replicates if precision is not None else budget.replicates,
        run_time_s=run_time_bound_s(budget.time_s, budget.spp, pixels),
        snapshots=snapshot_count(budget.snapshots, units, budget.time_s, budget.spp, pixels),
        reference_time_s=parts * ref_time + pilots,
        reference_images=2 * parts,
        pixels=pixels,
        channels=len(names.exr_channels),
    )
    runs_key = ("precision.max_replicates", "runs (points x strategies x precision.max_replicates)")
    check(work, limits, r, {"max_runs": runs_key} if precision is not None else None)
