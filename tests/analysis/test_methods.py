"""The methods paragraph from each treatment's stored settings (analysis.methods)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from softevo.analysis.methods import (
    cap_cuts,
    evaluation_methods,
    frequency_shares,
    mapping_text,
    methods_text,
    settling_text,
)
from softevo.evolution import environments, genotype
from softevo.evolution.genotype import Phenotype
from softevo.evolution.treatments import Treatment

LAND, WATER = environments.PAPER
ROBOT = Phenotype(body=np.full((2, 2, 2), 2, np.int8), phase=np.zeros((2, 2, 2)), frequency=2.0)


def _row(treatment: Treatment) -> pd.Series:
    return pd.Series(treatment.to_settings() | {"name": treatment.name})


def test_mappings_are_described_from_the_genotype_module():
    assert mapping_text("linear") == "one evolved frequency mapped linearly onto 1-5 Hz"
    assert "unbounded; a negative f runs at |f|" in mapping_text("evosoro")
    for name, (logistic, bounded, positive_only) in genotype.EVOSORO_MAPPINGS.items():
        text = mapping_text(name)
        assert ("at most 4 Hz" in text) == bounded and ("invalid" in text) == positive_only, name
        assert ("logistic" in text) == logistic and ("below 4 Hz" in text) == logistic, name
    assert mapping_text("made-up") == "control mapping 'made-up' (unknown to this version)"


@pytest.mark.parametrize("model", ["voxelyze-2", "voxcad-land-water"])
def test_settling_is_read_from_the_scene_the_treatment_builds(model):
    transition = Treatment(f"{LAND}-{WATER}", 0.1, model=model)
    expected = [
        ROBOT.to_scene(world, 1e5, transition.cycles, model=model)["settle_seconds"]
        for world in environments.PAPER
    ]
    text = settling_text(_row(transition), ROBOT)
    assert text == ", ".join(
        f"{s:g} s {environments.get(w).label}" for s, w in zip(expected, environments.PAPER, strict=True)
    )


def test_the_cap_counts_stored_flags_or_else_the_frequency():
    treatment = _row(Treatment(LAND, 0.1, name="t", cycles=50, max_seconds=20.0))
    evaluations = pd.DataFrame({"treatment": ["t"] * 4 + ["u"], "frequency": [1.0, 2.0, 3.0, -2.6, 0.1]})
    assert cap_cuts(treatment, evaluations) == (2, 4)  # 50 cycles: over 20 s at 1, 2 Hz; 19.2 s at |-2.6|
    flagged = evaluations.assign(capped=[False, False, True, False, True])
    assert cap_cuts(treatment, flagged) == (1, 4)
    uncapped = _row(Treatment(LAND, 0.1, name="t", cycles=50))
    assert cap_cuts(uncapped, evaluations) == (0, 4)


def test_treatments_with_the_same_evaluation_share_a_sentence():
    treatments = pd.DataFrame(
        [
            _row(Treatment(LAND, 0.001, name="a", cycles=50, max_seconds=60.0)),
            _row(Treatment(LAND, 10.0, name="b", cycles=50, max_seconds=60.0)),
            _row(Treatment(WATER, 0.1, name="c", cycles=8)),
        ]
    )
    evaluations = pd.DataFrame({"treatment": ["a", "b", "c"], "frequency": [0.5, 2.0, 3.0]})
    methods = evaluation_methods(treatments, evaluations, ROBOT)
    text = methods_text(methods)
    assert text.startswith("a, b: physics model voxelyze-2")
    assert "50 actuation cycles per evaluation, at most 60 s after settling (the cap cut 1 of the 2" in text
    assert "c: physics model" in text and "8 actuation cycles per evaluation, no cap on seconds." in text


def test_frequency_shares_count_the_clip_the_cap_and_slow_robots():
    clipped = _row(
        Treatment(LAND, 0.1, name="t", cycles=50, max_seconds=100.0, control_mapping="evosoro-bounded")
    )
    logistic = _row(
        Treatment(LAND, 0.1, name="t", cycles=50, max_seconds=100.0, control_mapping="evosoro-logistic")
    )
    evaluations = pd.DataFrame({"treatment": ["t"] * 5, "frequency": [4.0, 4.0, 0.4, 2.0, None]})
    # the clip holds the two at 4 Hz; 50 cycles at 0.4 Hz last 125 s > 100: the cap cuts it
    assert frequency_shares(clipped, evaluations) == (3, 1)
    assert frequency_shares(logistic, evaluations) == (1, 1)  # no clip under the logistic reading
    text = methods_text(evaluation_methods(pd.DataFrame([clipped]), evaluations, ROBOT))
    assert "75.0% sit at a bound of the frequency" in text and "25.0% run below 0.5 Hz" in text
