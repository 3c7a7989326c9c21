"""Guards on the real outline: the repair sees everything, never far above the exact reference."""

from __future__ import annotations

import numpy as np
import pytest

from typed_config import ConfigError
from uav_swarm.missions.monitoring.outline import Outline
from uav_swarm.missions.monitoring.outline_guards import (
    SightConfig,
    judge,
    reference_guards,
    repair_on_outline,
)
from uav_swarm.missions.monitoring.setcover import InfeasibleCoverError

SLOTS = np.array([[0, 0], [150, 0], [150, 60], [130, 60], [130, 20], [110, 20], [110, 60], [85, 60],
                  [85, 20], [65, 20], [65, 60], [50, 60], [50, 20], [30, 20], [30, 60], [0, 60]], dtype=float)
JOGS = np.array([[0, 0], [40, 0], [40, 0.6], [80, 0.6], [80, 30], [41, 30], [41, 29.4], [0, 29.4]],
                dtype=float)
NEAR_COLLINEAR = np.array([[0, 0], [30, 0], [60, 0.05], [90, 0], [90, 20], [45, 20.08], [0, 20]], dtype=float)
COURTYARD = (np.array([[0.0, 0.0], [60.0, 0.0], [60.0, 50.0], [0.0, 50.0]]),
             [np.array([[20.0, 15.0], [20.0, 35.0], [40.0, 35.0], [40.0, 15.0]])])
OUTLINES = {"slots": (SLOTS, []), "jogs": (JOGS, []), "near-collinear": (NEAR_COLLINEAR, []),
            "courtyard": COURTYARD}
SIGHT = SightConfig(witness_spacing_m=1.0)  # coarser than the default to keep the tests short


@pytest.mark.parametrize("region", ["interior", "exterior"], ids=["agp", "fp"])
@pytest.mark.parametrize("name", list(OUTLINES))
def test_repair_from_noisy_or_no_proposals_sees_every_witness_with_few_guards(name, region):
    outline = Outline.from_rings(*OUTLINES[name], name=name)
    reference = reference_guards(outline, region, SIGHT)
    assert reference.seen_fraction == 1.0
    rng = np.random.default_rng(3)
    x0, y0, x1, y1 = outline.polygon.bounds
    tries = {"near the reference": reference.guards_m + rng.normal(0.0, 2.0, reference.guards_m.shape),
             "random": rng.uniform((x0, y0), (x1, y1), size=(5, 2)), "none": np.zeros((0, 2))}
    for proposals in tries.values():
        repaired = repair_on_outline(outline, region, proposals, SIGHT)
        assert judge(outline, region, repaired.guards_m, SIGHT).seen_fraction == 1.0  # judged anew
        assert len(repaired.guards_m) <= len(reference.guards_m) + 1


def test_the_reference_is_optimal_on_shapes_with_a_known_answer():
    ell = Outline.from_rings(np.array([[0, 0], [30, 0], [30, 10], [10, 10], [10, 30], [0, 30.0]]))
    assert len(reference_guards(ell, "interior", SIGHT).guards_m) == 1  # the corner square sees both arms
    square = Outline.from_rings(np.array([[0, 0], [20, 0], [20, 20], [0, 20.0]]))
    assert len(reference_guards(square, "exterior", SIGHT).guards_m) == 2  # two opposite corners, no fewer


def test_a_slot_too_narrow_to_see_into_with_the_margin_is_refused_in_metres():
    slot = Outline.from_rings(np.array([[0, 0], [40, 0], [40, 20], [21, 20], [21, 35], [19.8, 35], [19.8, 20],
                                        [0, 20.0]]), name="hall with a 1.2 m slot")
    strict = SightConfig(witness_spacing_m=1.0, min_clearance_m=0.7)
    refusal = r"hall with a 1.2 m slot: \d+ witness point\(s\) .*\(20\.\d+, "  # named in metres
    with pytest.raises(InfeasibleCoverError, match=refusal):
        repair_on_outline(slot, "interior", np.zeros((0, 2)), strict)
    relaxed = SightConfig(witness_spacing_m=1.0, min_clearance_m=0.0, standoff_m=0.5)
    assert repair_on_outline(slot, "interior", np.zeros((0, 2)), relaxed).seen_fraction == 1.0


def test_a_guard_outside_its_region_or_at_a_wall_sees_nothing():
    square = Outline.from_rings(np.array([[0, 0], [20, 0], [20, 20], [0, 20.0]]))
    placement = judge(square, "interior", np.array([[10.0, 10.0], [30.0, 10.0], [10.0, 0.4]]), SIGHT)
    assert placement.seen_by[0].all() and not placement.seen_by[1:].any()


def test_a_margin_wider_than_the_standoff_is_refused_by_name():
    with pytest.raises(ConfigError, match="standoff_m = 0.5 must be >= min_clearance_m = 1.0"):
        SightConfig(standoff_m=0.5, min_clearance_m=1.0)
    with pytest.raises(ConfigError, match="witness_spacing_m"):
        SightConfig(witness_spacing_m=0.0)


def test_a_building_too_narrow_for_any_guard_is_refused_at_once():
    corridor = Outline.from_rings(np.array([[0, 0], [30, 0], [30, 1.5], [0, 1.5]]), name="corridor")
    with pytest.raises(InfeasibleCoverError, match="corridor: .* no guard position inside the building"):
        reference_guards(corridor, "interior", SIGHT)  # 1.5 m wide: nowhere 1 m from both walls
    with pytest.raises(InfeasibleCoverError, match="corridor: .* no guard position inside the building"):
        repair_on_outline(corridor, "interior", np.array([[15.0, 0.75]]), SIGHT)
