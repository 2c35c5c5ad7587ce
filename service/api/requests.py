"""What a write body asks for, in the domain's terms: the treatments of an experiment body
(``POST /experiments`` and ``POST /plan``), read by ``service.plan.spec`` as ``softevo plan
SPEC.json`` reads a spec file."""

from __future__ import annotations

from softevo.evolution.treatments import Treatment
from softevo.service.api.schemas import ExperimentIn, PresetIn
from softevo.service.plan.spec import PRESET_FIELDS, listed_treatments, preset_treatments


def request_treatments(body: ExperimentIn | PresetIn) -> list[Treatment]:
    """The treatments an experiment body asks for (``service.plan.spec``, as the command line
    reads a spec): a preset's grid, or its own treatments (``Treatment``'s own checks apply,
    and the limits)."""
    if isinstance(body, PresetIn):
        return preset_treatments(body.model_dump(include=set(PRESET_FIELDS)))
    return listed_treatments([t.model_dump() for t in body.treatments])
