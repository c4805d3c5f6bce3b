"""The measurement's pieces, each against a closed form or a seeded Monte
Carlo check with a tolerance from its own variance: region masks, the
pilot's choice, the two-reference bias test and combination, the noise
check's extension, the equal-error speed-up, and the tidy summary's
replicate statistics."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from portal_harness.analysis import speedup, summary
from portal_harness.core import exr, regions
from portal_harness.core.exr import REGION_CLASSES, Snapshot, SnapshotHeader
from portal_harness.core.metrics import Region
from portal_harness.reference import noise_check, pilot, reference_pair

H, W = 24, 32


def _header(spp: int = 100, time_s: float = 1.0, strategy: str = "light") -> SnapshotHeader:
    return SnapshotHeader(
        width=W,
        height=H,
        render_time_s=time_s,
        spp=spp,
        strategy=strategy,
        integrator="direct",
        seed=1,
        config_hash="0" * 16,
        renderer_version="test",
        rays=0.0,
        nonfinite_samples=0.0,
    )


def _snap(
    rgb: np.ndarray,
    var: np.ndarray,
    fractions: np.ndarray | None = None,
    spp: int = 100,
    time_s: float = 1.0,
    strategy: str = "light",
) -> Snapshot:
    return Snapshot(
        path=Path("x.exr"),
        header=_header(spp, time_s, strategy),
        rgb=rgb,
        variance=var,
        regions=fractions,
    )


def _fractions(classes: np.ndarray) -> np.ndarray:
    f = np.zeros((*classes.shape, len(REGION_CLASSES)))
    for i in range(len(REGION_CLASSES)):
        f[..., i] = classes == i
    return f


def _classes() -> np.ndarray:
    """Left half anti_umbra, right half anti_penumbra, top 3 rows emitter."""
    c = np.where(np.arange(W)[None, :] < W // 2, 1, 2) * np.ones((H, 1), dtype=int)
    c[:3] = REGION_CLASSES.index("emitter")
    return c


# ---- regions -------------------------------------------------------------


def test_01_class_map_takes_the_majority_only() -> None:
    f = np.zeros((1, 3, len(REGION_CLASSES)))
    f[0, 0, 1] = 1.0  # all anti_umbra
    f[0, 1, 1], f[0, 1, 2] = 0.6, 0.4  # majority anti_umbra
    f[0, 2, 1], f[0, 2, 2], f[0, 2, 3] = 0.5, 0.25, 0.25  # no class above half
    assert regions.class_map(f).tolist() == [[1, 1, -1]]


def test_02_regions_image_lit_insets_classes() -> None:
    rgb = np.full((H, W, 3), 0.5)
    rgb[:, -2:] = 0.0  # two dark columns: not lit
    snap = _snap(rgb, np.zeros_like(rgb))
    found = regions.regions_of(snap, (Region("box", 0, 5, 4, 4),), fractions=_fractions(_classes()))
    by = {r.name: r for r in found}
    assert [r.name for r in found] == ["image", "lit", "box", "anti_umbra", "anti_penumbra", "emitter"]
    assert by["image"].pixels == H * W
    # lit: not dark and not the emitter rows
    assert by["lit"].pixels == (H - 3) * (W - 2)
    assert by["box"].pixels == 16 and by["emitter"].pixels == 3 * W
    # a class with fewer than CLASS_MIN_PIXELS pixels is left out
    c = _classes()
    c[10, 10] = REGION_CLASSES.index("inside")
    names = [r.name for r in regions.regions_of(snap, (), fractions=_fractions(c))]
    assert "inside" not in names and regions.fingerprint(found) != regions.fingerprint(found[:2])


# ---- pilot ---------------------------------------------------------------


def test_03_pilot_minimises_the_worst_region_and_predicts_the_first_time() -> None:
    mean = np.full((H, W, 3), 0.5)
    fr = _fractions(_classes())
    left = _classes() == 1
    # portal: the best on average, but 50x worse than antishadow in the anti_umbra half;
    # antishadow: never more than 2x the best anywhere
    var_portal = np.full_like(mean, 1e-5)
    var_portal[left] = 5e-4
    var_anti = np.full_like(mean, 2e-5)
    var_anti[left] = 1e-5
    pilots = {
        "light": _snap(mean, np.full_like(mean, 1e-3), time_s=0.5),
        "portal": _snap(mean, var_portal, time_s=0.5),
        "antishadow": _snap(mean, var_anti, time_s=0.5),
    }
    found = regions.regions_of(pilots["light"], (Region("corner", 0, 5, 4, 4),), fractions=fr)
    ranked = pilot.score(pilots, found)
    assert [r.strategy for r in ranked] == ["antishadow", "portal", "light"]
    best = ranked[0]
    assert best.needs["anti_umbra"] == pytest.approx(1.0) and best.needs["anti_penumbra"] == pytest.approx(2.0)
    assert best.worst_need == pytest.approx(2.0)
    assert ranked[1].needs["anti_umbra"] == pytest.approx(50.0)
    assert pilot.choose(ranked) == ("antishadow", "light")
    # T = t_run x worst need x (1 - q) / q x margin
    assert pilot.first_time(ranked, 4.0, 0.1, 1.25) == pytest.approx(4.0 * 2.0 * 9 * 1.25)
    # light the best: the runner-up is the second part
    only = [pilot.PilotResult("light", 1, 1.0, {}), pilot.PilotResult("portal", 1, 2.0, {})]
    assert pilot.choose(only) == ("light", "portal")


# ---- the two references ----------------------------------------------------


def _noisy_pair(
    rng: np.random.Generator, mean: np.ndarray, sd_a: float, sd_b: float, bias_b: float = 1.0
) -> tuple[Snapshot, Snapshot]:
    """Two renders whose channels share each pixel's noise, as the renderer's
    do (a sample's R, G, B come from one path)."""
    shape = (*mean.shape[:2], 1)
    a = mean + sd_a * rng.standard_normal(shape)
    b = bias_b * mean + sd_b * rng.standard_normal(shape)
    fr = _fractions(_classes())
    return (
        _snap(a, np.full_like(mean, sd_a**2), fr, strategy="antishadow_exact"),
        _snap(b, np.full_like(mean, sd_b**2), fr),
    )


def test_04_bias_test_is_standard_normal_for_unbiased_parts_and_catches_a_bias(rng: np.random.Generator) -> None:
    mean = np.full((H, W, 3), 0.4)
    zs = []
    for _ in range(200):
        a, b = _noisy_pair(rng, mean, 0.01, 0.05)
        found = reference_pair.disagreement(a, b, regions.regions_of(a, (), fractions=a.regions))
        zs += [d.z for d in found]
    z = np.array(zs)
    # mean 0 and variance 1 within 5 standard errors of the sample's own moments
    assert abs(z.mean()) < 5 / math.sqrt(z.size)
    assert abs(z.var() - 1) < 5 * math.sqrt(2 / z.size)
    # the channels' variances alone would ignore their correlation: z with sd sqrt(3)
    a, b = _noisy_pair(rng, mean, 0.01, 0.05)
    naive = [
        float(np.sum(a.rgb - b.rgb)) / math.sqrt(float(np.sum(a.variance + b.variance)))
        for a, b in (_noisy_pair(rng, mean, 0.01, 0.05) for _ in range(200))
    ]
    assert abs(np.var(naive) - 3) < 5 * 3 * math.sqrt(2 / 200)
    # a 5% bias of one part in every pixel: about 11 sigma over the image, 7 over each half
    a, b = _noisy_pair(rng, mean, 0.01, 0.05, bias_b=1.05)
    found = reference_pair.failures(
        reference_pair.disagreement(a, b, regions.regions_of(a, (), fractions=a.regions)), 4.0
    )
    assert {d.region for d in found} >= {"image", "anti_umbra", "anti_penumbra"}
    assert all(d.mean_difference < 0 for d in found)


def test_05_combination_weights_by_region_and_stays_unbiased(rng: np.random.Generator) -> None:
    mean = np.full((H, W, 3), 0.4)
    a, b = _noisy_pair(rng, mean, 0.01, 0.03)
    # part B four times less noisy in the anti_penumbra half
    right = _classes() == 2
    b.variance[right] = 0.0025**2
    b.rgb[right] = mean[right] + 0.0025 * rng.standard_normal(mean[right].shape)
    w = reference_pair.weights(a, b, a.regions)
    assert w[~right & (_classes() == 1)] == pytest.approx(0.9)  # 1/0.01^2 vs 1/0.03^2
    assert w[right] == pytest.approx(0.0025**2 / (0.0025**2 + 0.01**2))
    c = reference_pair.combine(a, b, "antishadow_exact+light", "f" * 16, a.regions)
    assert c.header.spp == 200 and c.header.strategy == "antishadow_exact+light"
    # the combined variance is below either part's, and the combined mean is unbiased
    assert np.all(c.variance <= np.minimum(a.variance, b.variance) + 1e-15)
    err = (c.rgb - mean)[right]
    assert abs(err.mean()) < 5 * math.sqrt(float(c.variance[right].mean()) / err.size)


# ---- noise check and extension ------------------------------------------


def test_06_noise_check_and_the_extension_that_fixes_it() -> None:
    checks = noise_check.check(
        {"image": 0.02, "lit": 0.001, "outside": 0.0}, {"image": 0.1, "lit": 0.1, "outside": 0.0}, 0.1
    )
    by = {c.region: c for c in checks}
    assert not by["image"].ok and by["image"].ratio == pytest.approx(0.2)
    assert by["lit"].ok and by["outside"].ok and math.isnan(by["outside"].ratio)
    # one part (relative variance v everywhere): f = margin x floor / (q e / (1 - q))
    mean = np.full((H, W, 3), 0.5)
    v = 0.02 * (0.25 + 0.01)
    part = _snap(mean, np.full_like(mean, v))
    image = regions.regions_of(part, ())[:1]
    plan = noise_check.plan_extension([by["image"]], [part], mean, image, 0.1)
    assert plan is not None and plan.part == 0
    expected = noise_check.EXTENSION_MARGIN * 0.02 / (0.1 * 0.08 / 0.9)
    assert plan.factor == pytest.approx(expected)
    # two parts: the less noisy one is extended, by g = V_A (f / V - 1 / V_B)
    other = _snap(mean, np.full_like(mean, 3 * v))
    plan = noise_check.plan_extension([by["image"]], [other, part], mean, image, 0.1)
    assert plan is not None and plan.part == 1
    va, vb = 0.02, 0.06
    combined = 1 / (1 / va + 1 / vb)
    f = expected
    assert plan.factor == pytest.approx(min(va * (f / combined - 1 / vb), noise_check.MAX_FACTOR_PER_ROUND))


# ---- equal-error speed-up ------------------------------------------------


def test_07_time_to_error_is_exact_on_a_power_law_and_marks_bounds() -> None:
    curve = [(t, 0.3 / t) for t in (0.125, 0.25, 0.5, 1, 2, 4)]
    found = speedup.time_to_error(curve, 0.3 / 1.7)
    assert found is not None and found.bound == "" and found.time_s == pytest.approx(1.7)
    below = speedup.time_to_error(curve, 10.0)
    assert below is not None and below.bound == speedup.LOWER and below.time_s == 0.125
    above = speedup.time_to_error(curve, 1e-3)
    assert above is not None and above.bound == speedup.UPPER and above.time_s == 4
    assert speedup.combined_bound(["", speedup.LOWER]) == speedup.LOWER
    assert speedup.combined_bound([speedup.LOWER, speedup.UPPER]) == "mixed"


# ---- the tidy summary ------------------------------------------------------


def _replicates(error: float, times: list[float], noise: list[float], floor: float) -> list[summary.Replicate]:
    """Replicates with relMSE (error / t) x (1 + noise_j) + floor at t_j, curves c / t."""
    out = []
    for t, n in zip(times, noise, strict=True):
        e = error / t * (1 + n) + floor
        curve = tuple((s, error / s * (1 + n) + floor) for s in (t / 8, t / 4, t / 2, t))
        out.append(summary.Replicate(rel_mse=e, time_s=t, spp=100, curve=curve))
    return out


def test_08_summary_rows_efficiency_standard_errors_speedup_and_bounds() -> None:
    floor = 1e-4
    reps = {
        "light": {"lit": _replicates(0.4, [4, 4, 4], [0.1, -0.1, 0.0], floor)},
        "portal": {"lit": _replicates(0.02, [4, 4, 4], [0.2, -0.2, 0.0], floor)},
    }
    info = {"lit": summary.RegionInfo("lit", 100, floor)}
    rows = summary.rows_for_point("p", 1.0, ("light", "portal"), reps, info, 0.1, {"light": "done", "portal": "done"})
    by = {r["strategy"]: r for r in rows}
    light, portal = by["light"], by["portal"]
    # floor removed: relMSE = 0.1 (light) and 0.005 (portal) on average, 20x
    assert light["rel_mse"] == pytest.approx(0.1) and portal["rel_mse"] == pytest.approx(0.005)
    assert portal["efficiency_vs_light"] == pytest.approx(20.0)
    # delta method: 20 x hypot(se_l / m_l, se_p / m_p), se = sd / sqrt(3)
    se_l = np.std([0.11, 0.09, 0.1], ddof=1) / math.sqrt(3) / 0.1
    se_p = np.std([0.006, 0.004, 0.005], ddof=1) / math.sqrt(3) / 0.005
    assert portal["efficiency_vs_light_stderr"] == pytest.approx(20 * math.hypot(se_l, se_p))
    assert portal["rel_mse_stderr"] == pytest.approx(np.std([0.006, 0.004, 0.005], ddof=1) / math.sqrt(3))
    # the portal curves reach light's final error (0.1) before their first image: a lower bound
    assert portal["speedup_bound"] == "lower" and light["speedup_equal_error"] == 1.0
    assert portal["bound"] == "" and portal["reference_noise_ratio"] == pytest.approx(floor / (0.005 + floor))
    # a reference too noisy for the portal runs: raw efficiency, marked as a lower bound
    info = {"lit": summary.RegionInfo("lit", 100, 0.004)}
    reps["portal"] = {"lit": _replicates(0.02, [4, 4, 4], [0.2, -0.2, 0.0], 0.004)}
    reps["light"] = {"lit": _replicates(0.4, [4, 4, 4], [0.1, -0.1, 0.0], 0.004)}
    rows = summary.rows_for_point("p", 1.0, ("light", "portal"), reps, info, 0.1, {"light": "done", "portal": "done"})
    portal = {r["strategy"]: r for r in rows}["portal"]
    assert portal["bound"] == "lower"
    assert portal["efficiency_vs_light"] == pytest.approx((0.1 * 4) / ((0.005 + 0.004) * 4))
    # its error is the measured one (an upper bound), never the floor taken from it
    assert portal["rel_mse"] == pytest.approx(0.005 + 0.004) == portal["rel_mse_measured"]
    # a floor larger than the measured error (the runs outsampled the reference) stays positive
    info = {"lit": summary.RegionInfo("lit", 100, 0.02)}
    rows = summary.rows_for_point("p", 1.0, ("light", "portal"), reps, info, 0.1, {"light": "done", "portal": "done"})
    assert all(r["bound"] == "lower" and r["rel_mse"] > 0 for r in rows)


def test_09_speedup_is_read_off_the_curves() -> None:
    # light: relMSE 0.4 / t; portal: 0.1 / t, so it reaches light's final 0.1 at t = 1: speed-up 4
    reps = {
        "light": {"image": _replicates(0.4, [4, 4], [0.0, 0.0], 0.0)},
        "portal": {"image": _replicates(0.1, [4, 4], [0.0, 0.0], 0.0)},
    }
    rows = summary.rows_for_point(
        "p", 1.0, ("light", "portal"), reps, {"image": summary.RegionInfo("image", 10, 0.0)}, 0.1, {}
    )
    portal = {r["strategy"]: r for r in rows}["portal"]
    assert portal["speedup_equal_error"] == pytest.approx(4.0) and portal["speedup_bound"] == ""
    assert portal["time_to_light_error_s"] == pytest.approx(1.0)


def test_10_combined_reference_round_trips_through_exr(tmp_path: Path, rng: np.random.Generator) -> None:
    mean = np.full((H, W, 3), 0.4)
    a, b = _noisy_pair(rng, mean, 0.01, 0.03)
    c = reference_pair.combine(a, b, "antishadow_exact+light", "a" * 16, a.regions)
    path = tmp_path / "final.exr"
    exr.write_snapshot(path, c)
    back = exr.read_snapshot(path)
    assert back.header.spp == 200 and back.header.strategy == "antishadow_exact+light"
    assert np.allclose(back.rgb, c.rgb, rtol=1e-6) and np.allclose(back.variance, c.variance, rtol=1e-6)
    assert back.regions is not None and c.regions is not None and np.array_equal(back.regions, c.regions)
    assert not list(tmp_path.glob(".*tmp*"))


def test_11_an_extension_may_take_as_long_as_its_samples_need() -> None:
    from portal_harness.reference.extend import extension_timeout

    # 1000 spp in 15 s, extended to 16000: 225 s expected, so more than 3 x that before it counts as hung
    manifest = {"final": {"spp": 1000, "time_s": 15.0}}
    assert extension_timeout(manifest, 16000) == pytest.approx(3 * 225 + 60)


def test_12_a_firefly_reference_is_refused_however_small_its_noise_looks(rng: np.random.Generator) -> None:
    # A smooth reference at N = 4000 spp: every pixel's value carried by all its samples.
    n = 4000
    mean = np.full((H, W, 3), 0.5)
    var = np.full_like(mean, 0.5 * 0.5 * 0.2 / n)  # relative sample variance 0.2
    image = np.ones((H, W), dtype=bool)
    clean = noise_check.firefly_share(mean, var, image)
    assert clean == 0.0
    # The same with a rare large sample X = 2000 drawn once in 12 pixels: there the mean
    # rises by X / n = 0.5 and the variance of the mean is about X^2 / n^2 (one sample
    # carries the pixel: relative standard error ~ 1).
    hit = rng.choice(H * W, size=12, replace=False)
    ff_mean, ff_var = mean.copy(), var.copy()
    ys, xs = np.unravel_index(hit, (H, W))
    ff_mean[ys, xs] += 2000 / n
    ff_var[ys, xs] += (2000 / n) ** 2
    share = noise_check.firefly_share(ff_mean, ff_var, image)
    assert share > noise_check.FIREFLY_SHARE_MAX
    floor = float(np.mean(ff_var / (ff_mean**2 + 0.01)))
    # its noise is 1/20 of the smallest error: resolved by the ratio alone, refused for its fireflies
    (c,) = noise_check.check({"image": floor}, {"image": 20 * floor}, 0.1, {"image": share})
    assert c.ratio == pytest.approx(0.05) and c.fireflies and not c.ok
    (clean_check,) = noise_check.check({"image": floor}, {"image": 20 * floor}, 0.1, {"image": clean})
    assert clean_check.ok
    # the extension asked for is FIREFLY_EXTENSION times the samples
    part = _snap(ff_mean, ff_var)
    plan = noise_check.plan_extension([c], [part], ff_mean, regions.regions_of(part, ())[:1], 0.1)
    assert plan is not None and plan.factor == noise_check.FIREFLY_EXTENSION
    # and where it stays, every efficiency measured against it is reported as a lower bound
    reps = {s: {"lit": _replicates(0.4, [4, 4, 4], [0.1, -0.1, 0.0], 1e-4)} for s in ("light", "portal")}
    info = {"lit": summary.RegionInfo("lit", 100, 1e-4, fireflies=True)}
    rows = summary.rows_for_point("p", 1.0, ("light", "portal"), reps, info, 0.1, {"light": "done", "portal": "done"})
    assert all(r["bound"] == "lower" for r in rows)


def test_13_the_pilot_passes_over_a_candidate_with_fireflies(rng: np.random.Generator) -> None:
    mean = np.full((H, W, 3), 0.5)
    smooth = np.full_like(mean, 1e-4)
    # projection looks ten times cheaper, but a tenth of its noise is where a pixel rests
    # on one sample: most of its image noise is in those fireflies
    ff_mean, ff_var = mean.copy(), np.full_like(mean, 1e-6)
    hit = rng.choice(H * W, size=8, replace=False)
    ys, xs = np.unravel_index(hit, (H, W))
    ff_mean[ys, xs] = 2.0
    ff_var[ys, xs] = 4.0
    pilots = {
        "light": _snap(mean, 2 * smooth, time_s=0.5),
        "antishadow": _snap(mean, smooth, time_s=0.5),
        "projection": _snap(ff_mean, ff_var, time_s=0.5),
    }
    found = regions.regions_of(pilots["light"], ())
    ranked = pilot.score(pilots, found)
    by = {r.strategy: r for r in ranked}
    assert by["projection"].firefly_share > noise_check.FIREFLY_SHARE_MAX and not by["projection"].trusted
    assert by["antishadow"].trusted and by["light"].trusted
    assert pilot.choose(ranked) == ("antishadow", "light")
    # with nothing else left it is still a reference strategy (the noise check then judges it)
    assert pilot.choose([by["projection"]])[0] == "projection"


def _pixel_means(samples: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per pixel-channel, the mean of the samples (last axis) and its variance, as the renderer's layers give them."""
    n = samples.shape[-1]
    return samples.mean(axis=-1), samples.var(axis=-1, ddof=1) / n


@pytest.mark.parametrize("n", [9, pilot.MIN_SPP])
def test_14_a_few_samples_make_edges_look_like_fireflies(rng: np.random.Generator, n: int) -> None:
    # a nearly noise-free estimator over most pixels, and edge pixels whose samples are 0 or 4
    # (coverage p): what the 512x512 multi_lamp pilots of antishadow_exact look like
    shape = (H, W, 3)
    samples = 0.5 + 0.001 * rng.standard_normal((*shape, n))
    edge = rng.random((H, W)) < 0.08
    p = rng.uniform(0.02, 1.0, size=(H, W))
    hits = rng.random((*shape, n)) < p[..., None, None]
    samples[edge] = 4.0 * hits[edge]
    mean, var = _pixel_means(samples)
    share = noise_check.firefly_share(mean, var, np.ones((H, W), dtype=bool))
    if n < pilot.MIN_SPP:
        assert share > noise_check.FIREFLY_SHARE_MAX  # what made the pilot pass over the best strategy
    else:
        assert share < noise_check.FIREFLY_SHARE_MAX


def test_15_real_fireflies_stay_fireflies_at_the_pilots_sample_floor(rng: np.random.Generator) -> None:
    # rare large samples (one in 200, 200 times the pixel's value): the projection pilots'
    # caustic-like noise; at pilot.MIN_SPP they still hold most of the image's noise
    n = pilot.MIN_SPP
    shape = (H, W, 3)
    samples = 0.5 + 0.05 * rng.standard_normal((*shape, n))
    spikes = rng.random((H, W, 1, n)) < 1 / 200
    samples = samples + 100.0 * spikes
    mean, var = _pixel_means(samples)
    assert noise_check.firefly_share(mean, var, np.ones((H, W), dtype=bool)) > noise_check.FIREFLY_SHARE_MAX
