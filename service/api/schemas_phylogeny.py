"""Response bodies of the phylogeny endpoints (``GET /runs/{id}/phylogeny`` and
``GET /runs/{id}/exaptation``); ``service.storage.run_tree`` and ``service.storage.exaptation`` say
what each field means. Their trait fields are generated from the trait registry
(``service.api.schemas_traits``): a field per trait with a column of its own, and every other
registered trait as an extra key."""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, Field

from softevo.service.api.schemas_traits import RegisteredTraits, trait_fields

NodeTraits = trait_fields("NodeTraits", RegisteredTraits, nullable=True)


class PhylogenyNode(NodeTraits):
    """An individual with its birth evaluation's environment and every trait."""

    id: int
    parent_id: int | None = Field(description="null: a random newcomer, the root of a lineage")
    generation_born: int
    last_generation: int | None = Field(description="last generation whose kept population held it")
    environment: str | None = Field(description="of its first evaluation (the world it was born into)")


class PhylogenyPage(BaseModel):
    run_id: int
    total: int = Field(description="individuals in the run (born at or before generation, if given)")
    limit: int
    offset: int
    individuals: list[PhylogenyNode] = Field(description="in id order")


class TraitAlongLine(BaseModel):
    founder: float | None
    switch: float | None = Field(description="of the line's member kept at the arrival generation")
    end: float | None
    first_changed: int | None = Field(description="birth generation of the first change after the founder")


class RegisteredLineTraits(BaseModel):
    """Every registered trait followed along lines without a column of its own, by name."""

    model_config = ConfigDict(extra="allow")
    __pydantic_extra__: dict[str, TraitAlongLine] = Field(init=False)


LineTraits = trait_fields("LineTraits", RegisteredLineTraits, value=TraitAlongLine, along_lines=True)


class SurvivingLine(BaseModel):
    founder_id: int
    individual_id: int = Field(description="the final member the line reaches")
    root_id: int = Field(description="the newcomer the line started from")
    switch_id: int | None = Field(description="the line's member kept at the arrival generation")
    traits: LineTraits


class FounderLines(BaseModel):
    founder_id: int
    lines: int = Field(description="final members descending from it")
    front_lines: int = Field(description="of those, on the final Pareto front")
    traits: dict[str, float | None] = Field(description="the founder's traits at its birth")


class ExaptationOut(BaseModel):
    run_id: int
    switch_at: int = Field(description="first generation out of the first world")
    switch_over: int = Field(description="generations of compound worlds (0: abrupt)")
    arrival: int = Field(description="first generation wholly in the second world")
    generation: int = Field(description="last stored generation")
    environments: list[str]
    founders: int = Field(description="population kept at switch_at - 1")
    founders_surviving: int = Field(description="founders with a line into the final population")
    final_population: int
    from_founders: int = Field(description="final members with a founder among their ancestors")
    roots: list[int] = Field(description="root newcomers of the final population")
    every_line_rooted: bool
    founder_lines: list[FounderLines]
    lines_total: int
    limit: int
    offset: int
    lines: list[SurvivingLine] = Field(description="ordered by founder, then final member")
