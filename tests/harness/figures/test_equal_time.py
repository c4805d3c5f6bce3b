"""Images compared at equal time (figures/data.py: pick_time, times_agree):
the inset figure and the viewer show every strategy's image at the same
render time, up to EQUAL_TIME_TOLERANCE, never one run at its previous
snapshot because it overshot the shortest run's budget by a millisecond."""

from __future__ import annotations

import pytest

from portal_harness.figures.data import EQUAL_TIME_TOLERANCE, common_time, pick_time, times_agree

# The runs of one point of lampshade_ratio (s_L = 0.075) in a fresh
# `make figures`: snapshots every 0.5 s, finals a pass past the 2 s budget.
SCHEDULE = [0.5, 1.0, 1.5]
FINALS = {"light": 2.0001, "portal": 2.0010, "antishadow": 1.9989, "antishadow_exact": 2.0004}


def test_01_runs_that_overshoot_by_a_pass_are_shown_at_their_final_image() -> None:
    t_eq = min(FINALS.values())
    chosen = {s: pick_time([*SCHEDULE, final], t_eq) for s, final in FINALS.items()}
    assert chosen == FINALS
    assert times_agree([t for t in chosen.values() if t is not None])


def test_02_the_previous_snapshot_is_never_taken_for_equal_time() -> None:
    # the fault this replaces: the last image at or before the shortest final
    picked = [pick_time([*SCHEDULE, final], min(FINALS.values()), tolerance=1e-6) for final in FINALS.values()]
    chosen = [t for t in picked if t is not None]
    assert sorted(chosen) == [1.5, 1.5, 1.5, 1.9989]
    assert not times_agree(chosen)


def test_03_a_later_image_beyond_the_tolerance_is_not_taken() -> None:
    assert pick_time([1.0, 1.5, 2.1], 2.0) == 1.5
    assert pick_time([1.0, 1.5, 2.0 * (1 + EQUAL_TIME_TOLERANCE)], 2.0) == pytest.approx(2.04)
    assert pick_time([3.0, 4.0], 2.0) == 3.0  # none within: the earliest
    assert pick_time([], 2.0) is None


@pytest.mark.parametrize(
    ("times", "agree"),
    [([2.0, 2.001, 1.9989], True), ([1.5, 2.0], False), ([7.5, 8.0], False), ([8.0], True), ([], True)],
)
def test_04_times_agree_within_the_tolerance(times: list[float], agree: bool) -> None:
    assert times_agree(times) is agree


def test_05_a_run_that_overshot_by_more_than_the_tolerance_moves_the_comparison_to_a_shared_snapshot() -> None:
    # white_room_night_full, path tracing: passes of ~0.05 s, light's last one ended at 2.05 s; compared at
    # the shortest final (1.98 s) light would show its 1.51 s snapshot beside the others' finals.
    runs = [[0.5, 1.01, 1.51, 2.05], [0.52, 1.02, 1.503, 1.98], [0.5, 1.0, 1.52, 2.0]]
    t = common_time(runs, 1.98)
    assert t == pytest.approx(1.52)
    picked = [pick_time(r, t) for r in runs]
    assert picked == [1.51, 1.503, 1.52] and times_agree([p for p in picked if p is not None])
    # runs that all end within the tolerance keep the shortest final
    finals = [[*SCHEDULE, f] for f in FINALS.values()]
    assert common_time(finals, min(FINALS.values())) == min(FINALS.values())
    # nothing agrees (path tracing's passes are longer than the tolerance): the images closest in time,
    # here the finals (white_room_night_full, path: 1.98, 2.00 and 2.02 s, not light's 1.51 s snapshot)
    runs = [[0.51, 1.04, 1.555, 1.876, 1.981], [0.54, 1.03, 1.517, 1.731, 2.000], [0.51, 1.009, 1.513, 2.022]]
    t = common_time(runs, 1.981)
    assert [pick_time(r, t) for r in runs] == [1.981, 2.000, 2.022]
