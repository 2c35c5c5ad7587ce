"""What a write body asks for, in the domain's terms: the treatments of an experiment body
(``POST /experiments``, ``POST /plan`` and ``softevo plan SPEC.json`` read them alike)."""

from __future__ import annotations

from softevo.evolution.treatments import Treatment, preset_grid
from softevo.service.api.schemas import ExperimentIn, PresetIn
from softevo.service.runs.limits import check_workspace


def request_treatments(body: ExperimentIn | PresetIn) -> list[Treatment]:
    """The treatments an experiment body asks for: a preset's grid, or its own treatments
    (``Treatment``'s own checks apply, and the workspace limit)."""
    if isinstance(body, PresetIn):
        return preset_grid(body.preset, body.scale, repetitions=body.repetitions, seed=body.seed,
                           algorithm=body.algorithm, model=body.model)
    treatments = [Treatment.from_settings({**t.model_dump(), "name": t.name or ""}) for t in body.treatments]
    for treatment in treatments:
        check_workspace(treatment.workspace)
    return treatments
