"""The `precision:` section of an experiment: the relative standard error
its headline values are to reach (the sweep's rounds of replicates:
analysis/precision.py).

    precision: {rel_se: 0.05, of: [lit, insets], max_replicates: 40, max_time_s: 5400}

`of` names the headline regions: `image`, `lit`, `insets` (every inset), an
inset's name or a region class of the renderer's region AOV.
"""

from __future__ import annotations

from typing import Any

from portal_harness.core.metrics import WHOLE_IMAGE, Region
from portal_harness.core.regions import LIT
from portal_harness.experiment.model import Budget, Precision
from portal_harness.experiment.schema import SEED_MAX, Reader

KEYS = {"rel_se", "of", "max_replicates", "max_time_s"}
INSETS = "insets"
# A standard error from fewer replicates says too little to allocate more by.
MIN_REPLICATES = 3
DEFAULT_MAX_REPLICATES = 40


def read_precision(
    r: Reader,
    node: Any,
    budget: Budget | None,
    insets: tuple[Region, ...],
    region_classes: tuple[str, ...],
    n_strategies: int,
) -> Precision:
    m = r.mapping(node, "precision", KEYS, {"rel_se"})
    rel_se = r.number(m["rel_se"], "precision.rel_se", positive=True, maximum=1.0)
    if budget is None:
        raise r.fail("precision", "needs a budget (the replicates it adds are runs of the budget)")
    if budget.replicates < MIN_REPLICATES:
        raise r.fail(
            "budget.replicates",
            f"expected at least {MIN_REPLICATES} with precision (the first standard errors decide "
            f"where replicates are added), got {budget.replicates}",
        )
    names = (WHOLE_IMAGE, LIT, INSETS, *(i.name for i in insets), *region_classes)
    regions: list[str] = []
    for i, item in enumerate(r.sequence(m.get("of", [LIT, INSETS]), "precision.of")):
        name = r.choice(item, f"precision.of.{i}", names, "region")
        if name == INSETS and not insets:
            raise r.fail(f"precision.of.{i}", "the experiment has no insets")
        for region in [x.name for x in insets] if name == INSETS else [name]:
            if region not in regions:
                regions.append(region)
    max_replicates = r.integer(
        m.get("max_replicates", max(DEFAULT_MAX_REPLICATES, budget.replicates)),
        "precision.max_replicates",
        minimum=budget.replicates,
        maximum=SEED_MAX,
    )
    if budget.seed + max_replicates * n_strategies > SEED_MAX:
        raise r.fail("precision.max_replicates", f"the replicates' seeds pass {SEED_MAX}")
    max_time_s = r.number(m.get("max_time_s", 0), "precision.max_time_s")
    return Precision(rel_se=rel_se, regions=tuple(regions), max_replicates=max_replicates, max_time_s=max_time_s)
