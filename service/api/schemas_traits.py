"""The trait fields of the REST response bodies, generated from the trait registry
(``evolution.traits``), never written out by hand.

A body that shows traits as fields (an evaluation, a lineage entry, a phylogeny node, a
surviving line's traits) has one field per trait with a column of its own, typed (a count
an integer), nullable and described by its record (``trait_fields``), the JSON shape the
dashboard and clients read; every other registered trait arrives under its own name as an
extra key of the same body (``RegisteredTraits``): the schema says so with
``additionalProperties``, so a trait registered by a deployment's plugin is served without a
schema of its own.
"""

from __future__ import annotations

from typing import Any

from pydantic import BaseModel, ConfigDict, Field, create_model

from softevo.evolution import traits


class RegisteredTraits(BaseModel):
    """A body that also holds every registered trait without a column of its own, by name:
    a number, or null where the evaluation has none."""

    model_config = ConfigDict(extra="allow")
    __pydantic_extra__: dict[str, float | None] = Field(init=False)


def trait_fields(
    name: str,
    base: type[BaseModel] = BaseModel,
    value: Any = None,
    nullable: bool = False,
    along_lines: bool = False,
) -> type[BaseModel]:
    """A model ``name`` on ``base`` with a field per trait with a column of its own
    (``evolution.traits.column_traits()``; ``along_lines``: only those the exaptation analysis
    follows), described by the trait's label. Each field's type is ``value`` if given, else
    a number (an integer for a count), null allowed unless the trait is ``required`` and not
    ``nullable`` (a body read through an outer join)."""
    fields: dict[str, Any] = {}
    for trait in traits.column_traits():
        if along_lines and not trait.along_lines:
            continue
        kind = value if value is not None else int if trait.integer else float
        if value is None and (nullable or not trait.required):
            kind = kind | None
        fields[trait.name] = (kind, Field(description=trait.label))
    return create_model(name, __base__=base, __module__=__name__, **fields)
