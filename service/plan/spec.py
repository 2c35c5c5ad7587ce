"""An experiment spec as plain data, and the treatments it asks for.

A spec is what ``POST /experiments`` takes and ``softevo plan SPEC.json`` reads: explicit
treatments, ``{"name": ..., "treatments": [{settings}, ...]}``, each treatment's settings
those of ``evolution.treatments.Treatment.from_settings``; or a preset,
``{"preset": ..., "scale": ..., "repetitions", "seed", "name", "algorithm", "model"}``.

- ``spec_treatments(spec, where)``: the treatments of a spec read from a file (JSON already
  parsed), each checked by ``Treatment``'s own checks and the REST bounds
  (``service.runs.limits.check_treatment``); UserError, in one line naming ``where`` and the
  field, for anything else.
- ``listed_treatments`` and ``preset_treatments``: the same for the parts of a body the REST
  API has already validated with its schema (``service.api.requests``).

Nothing here knows HTTP: the command line reads specs without the API's request models.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from softevo.errors import UserError
from softevo.evolution import options
from softevo.evolution.treatments import Treatment, preset_grid
from softevo.service.runs.limits import check_treatment

EXPERIMENT_FIELDS = ("name", "treatments")
PRESET_FIELDS = ("preset", "scale", "repetitions", "seed", "name", "algorithm", "model")
MAX_TREATMENTS = 200  # treatments in one spec, as ``POST /experiments`` takes them
SPEC_SHAPE = '{"name": ..., "treatments": [...]} or {"preset": ..., "scale": ...}'


def spec_treatments(spec: Any, where: str = "spec") -> list[Treatment]:
    """The treatments of ``spec`` (module doc); UserError ``"<where>: <field>: <problem>"``."""
    if not isinstance(spec, Mapping):
        raise UserError(f"{where}: not an experiment spec: a JSON object {SPEC_SHAPE}")
    try:
        if "preset" in spec:
            return preset_treatments(checked_preset(spec))
        return checked_treatments(spec)
    except UserError as exc:
        raise UserError(f"{where}: {exc}") from None


def preset_treatments(spec: Mapping[str, Any]) -> list[Treatment]:
    """The treatments of a preset spec (``PRESET_FIELDS``; ``name`` names the experiment)."""
    return preset_grid(spec["preset"], spec.get("scale") or "tiny", repetitions=spec.get("repetitions"),
                       seed=spec.get("seed") or 0, algorithm=spec.get("algorithm"), model=spec.get("model"))


def listed_treatments(treatments: Sequence[Mapping[str, Any]]) -> list[Treatment]:
    """Each of ``treatments``' settings as a ``Treatment`` within the REST bounds."""
    return [treatment_of(settings) for settings in treatments]


def treatment_of(settings: Mapping[str, Any]) -> Treatment:
    """One treatment's settings as a ``Treatment`` (no name: its default name), checked."""
    treatment = Treatment.from_settings({**settings, "name": settings.get("name") or ""})
    check_treatment(treatment)
    return treatment


def checked_preset(spec: Mapping[str, Any]) -> Mapping[str, Any]:
    """``spec`` once its fields are known and its counts whole numbers (the choices are
    ``preset_grid``'s to check)."""
    unknown_fields(spec, PRESET_FIELDS)
    for name, least in (("repetitions", 1), ("seed", 0)):
        value = spec.get(name)
        if value is not None and (isinstance(value, bool) or not isinstance(value, int) or value < least):
            raise UserError(f"{name}: must be an integer >= {least} (got {value!r})")
    for name in ("preset", "scale", "name", "algorithm", "model"):
        if spec.get(name) is not None and not isinstance(spec[name], str):
            raise UserError(f"{name}: must be a string (got {spec[name]!r})")
    return spec


def checked_treatments(spec: Mapping[str, Any]) -> list[Treatment]:
    """The treatments of an explicit spec; a treatment's problem names it (``treatments.0:``),
    and a value given wrongly is said before a field left out."""
    unknown_fields(spec, EXPERIMENT_FIELDS)
    listed = spec.get("treatments")
    if not isinstance(listed, list) or not 1 <= len(listed) <= MAX_TREATMENTS:
        raise UserError(f"treatments: must be a list of 1..{MAX_TREATMENTS} treatments")
    treatments = []
    for index, settings in enumerate(listed):
        try:
            treatments.append(treatment_of(required(settings)))
        except UserError as exc:
            raise UserError(f"treatments.{index}: {exc}") from None
        except (TypeError, ValueError) as exc:  # a value of the wrong kind (a workspace of words)
            raise UserError(f"treatments.{index}: not a treatment ({exc})") from None
    name = spec.get("name")
    if not isinstance(name, str) or not name.strip():
        raise UserError("name: required, the experiment's name (a string)")
    return treatments


def required(settings: Any) -> Mapping[str, Any]:
    """``settings`` once it is an object holding every declared option without a default
    (``evolution.options``)."""
    if not isinstance(settings, Mapping):
        raise UserError("must be an object of treatment settings")
    needed = [option.name for option in options.declared() if option.required]
    missing = [name for name in needed if name not in settings]
    if missing:
        raise UserError(f"{', '.join(missing)}: required")
    return settings


def unknown_fields(spec: Mapping[str, Any], known: Sequence[str]) -> None:
    unknown = sorted(set(spec) - set(known))
    if unknown:
        raise UserError(f"unknown field(s) {', '.join(map(str, unknown))}; a spec has {', '.join(known)}")
